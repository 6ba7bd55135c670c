//! Marching cubes of a scalar field's zero level (inside = positive), producing a closed,
//! outward-oriented, vertex-shared triangle mesh.

use glam::DVec3;

use super::Mesh;
use crate::geometry::Aabb;

/// Polygonize `{x : field(x) = 0}` (inside where `field > 0`) over `bounds` with `resolution`
/// cells along the longest side. The grid is padded by one cell so a field that is negative on
/// the boundary gives a closed surface. Vertices lie on the zero level by linear interpolation.
/// Parallel over slabs; deterministic.
pub fn marching_cubes(
    bounds: &Aabb,
    resolution: usize,
    field: impl Fn(DVec3) -> f64 + Sync,
) -> Mesh {
    let _ = (bounds, resolution, &field);
    todo!("polygonize helper")
}
