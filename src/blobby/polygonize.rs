//! `nephele mesh`: the blob surface `F = 0` as a triangle mesh, by marching cubes over the
//! bounds of all blob supports, with the field evaluated through its spatial index.

use super::BlobField;
use crate::mesh::Mesh;

/// Polygonize a blob field with `resolution` cells along the longest side of its bounds.
pub fn polygonize(field: &BlobField, resolution: usize) -> Mesh {
    let _ = (field, resolution);
    todo!("polygonize helper")
}
