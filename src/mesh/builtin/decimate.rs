//! Edge-collapse decimation of the polygonized figures with meshoptimizer, then compaction.
//!
//! Marching tetrahedra gives many thin triangles; simplifying a finer polygonization down to a
//! triangle budget gives a lighter mesh with better-shaped faces and a smaller error than
//! polygonizing coarsely. meshoptimizer is single-threaded and deterministic.

use glam::DVec3;

use crate::mesh::Mesh;

/// Simplify `mesh` to about `target` triangles (fewer is never forced beyond `max_error`, a
/// fraction of the mesh extent), keeping the original f64 positions of surviving vertices.
/// Returns the input unchanged if meshoptimizer cannot read the vertex buffer.
pub fn decimate(mesh: &Mesh, target: usize, max_error: f32) -> Mesh {
    let xyz: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|p| p.as_vec3().to_array())
        .collect();
    let Ok(adapter) =
        meshopt::VertexDataAdapter::new(meshopt::typed_to_bytes(&xyz), size_of::<[f32; 3]>(), 0)
    else {
        return mesh.clone();
    };
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let kept = meshopt::simplify(
        &indices,
        &adapter,
        3 * target,
        max_error,
        meshopt::SimplifyOptions::RegularizeLight,
        None,
    );
    compact(&mesh.positions, &kept)
}

/// Keep only the vertices `indices` uses, in first-use order.
fn compact(positions: &[DVec3], indices: &[u32]) -> Mesh {
    let mut remap = vec![u32::MAX; positions.len()];
    let mut out = Mesh::default();
    let mut id = |v: u32| {
        let r = &mut remap[v as usize];
        if *r == u32::MAX {
            *r = out.positions.len() as u32;
            out.positions.push(positions[v as usize]);
        }
        *r
    };
    let triangles: Vec<[u32; 3]> = indices
        .chunks_exact(3)
        .map(|t| [id(t[0]), id(t[1]), id(t[2])])
        .collect();
    out.triangles = triangles;
    out
}
