//! Quadric-error-metric simplification (Garland–Heckbert) to pick decomposition seeds.

use super::Mesh;

/// Indices of original vertices kept by simplifying `mesh` to about `target` vertices
/// (all vertices when the mesh has fewer). Sorted ascending, no duplicates.
pub fn simplified_vertex_indices(mesh: &Mesh, target: usize) -> Vec<u32> {
    let _ = (mesh, target);
    todo!("decompose helper")
}
