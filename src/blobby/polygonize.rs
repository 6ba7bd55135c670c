//! `nephele mesh`: the blob surface `F = 0` as a triangle mesh, by marching cubes over the
//! bounds of all blob supports, with the field evaluated through its spatial index.
//!
//! In: a [`BlobField`] and a resolution. Out: a closed, outward-oriented [`Mesh`] (empty when no
//! blob is live or the field never exceeds the threshold).

use super::BlobField;
use crate::mesh::Mesh;
use crate::mesh::marching_cubes::marching_cubes;

/// Margin added around the support bounds, as a fraction of their diagonal, so the surface never
/// runs along the grid's border.
const MARGIN: f64 = 0.01;

/// Polygonize a blob field with `resolution` cells along the longest side of its bounds.
///
/// Outside every support `F = −t`, and [`BlobField::value`] returns that after one bounds test,
/// so grid points far from any blob cost almost nothing.
pub fn polygonize(field: &BlobField, resolution: usize) -> Mesh {
    let bounds = field.bounds();
    if bounds.is_empty() {
        return Mesh::default();
    }
    let bounds = bounds.expanded(MARGIN * bounds.diagonal());
    marching_cubes(&bounds, resolution, |x| field.value(x))
}
