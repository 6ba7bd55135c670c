//! Mesh assembly shared by every reader: [`MeshBuilder`] (vertices, fan-triangulated polygons)
//! and [`clean_up`], which welds bit-identical positions and drops degenerate triangles and
//! unreferenced vertices, so every format yields the same indexed mesh for the same surface.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;

use crate::mesh::Mesh;

/// Accumulates vertices and polygons into a [`Mesh`]: fan triangulation, degenerate triangles
/// (a repeated index) dropped. Index range checks are the caller's job.
#[derive(Default)]
pub(crate) struct MeshBuilder {
    mesh: Mesh,
}

impl MeshBuilder {
    /// An empty builder with room for `vertices` and `triangles` (callers pass counts already
    /// checked against the file size).
    pub(crate) fn with_capacity(vertices: usize, triangles: usize) -> MeshBuilder {
        MeshBuilder {
            mesh: Mesh {
                positions: Vec::with_capacity(vertices),
                triangles: Vec::with_capacity(triangles),
            },
        }
    }

    /// Number of vertices pushed so far.
    pub(crate) fn vertex_count(&self) -> usize {
        self.mesh.positions.len()
    }

    /// Add a vertex; `Err` with a message when a coordinate is NaN or infinite.
    pub(crate) fn push_vertex(&mut self, p: [f64; 3]) -> Result<(), String> {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(format!("non-finite vertex coordinate {p:?}"));
        }
        self.mesh.positions.push(DVec3::from_array(p));
        Ok(())
    }

    /// Add a polygon of at least three vertex indices as a triangle fan around its first
    /// vertex; `Err` with a message for fewer than three.
    pub(crate) fn push_polygon(&mut self, poly: &[u32]) -> Result<(), String> {
        if poly.len() < 3 {
            return Err(format!(
                "face has {} vertices; a face needs at least 3",
                poly.len()
            ));
        }
        let a = poly[0];
        for w in poly[1..].windows(2) {
            push_if_proper(&mut self.mesh.triangles, [a, w[0], w[1]]);
        }
        Ok(())
    }

    /// The mesh as read (not yet cleaned up).
    pub(crate) fn finish(self) -> Mesh {
        self.mesh
    }
}

/// Push `t` unless it repeats an index (no area, no orientation: dropped silently).
fn push_if_proper(triangles: &mut Vec<[u32; 3]>, t: [u32; 3]) {
    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
        triangles.push(t);
    }
}

/// Weld bit-identical positions (-0 equals +0) into their first occurrence, drop triangles
/// that became degenerate, then drop vertices no triangle uses (stray scan points, the
/// duplicates just welded), keeping the rest in file order. Unreferenced vertices would only
/// distort the bounding box every tolerance is relative to.
pub(crate) fn clean_up(mut mesh: Mesh) -> Mesh {
    let first = first_occurrences(&mesh.positions);
    let triangles = std::mem::take(&mut mesh.triangles);
    for t in triangles {
        push_if_proper(&mut mesh.triangles, t.map(|v| first[v as usize]));
    }
    drop_unreferenced_vertices(&mut mesh);
    mesh
}

/// For each vertex, the index of the first vertex at the bit-identical position.
fn first_occurrences(positions: &[DVec3]) -> Vec<u32> {
    let mut seen: HashMap<[u64; 3], u32, BuildHasherDefault<KeyHasher>> =
        HashMap::with_capacity_and_hasher(positions.len(), Default::default());
    (0..positions.len() as u32)
        .map(|i| {
            // Adding +0.0 turns -0.0 into +0.0, so both weld.
            let key = (positions[i as usize] + 0.0).to_array().map(f64::to_bits);
            *seen.entry(key).or_insert(i)
        })
        .collect()
}

/// Remove vertices no triangle uses, renumbering the rest in order; returns how many went.
fn drop_unreferenced_vertices(mesh: &mut Mesh) -> usize {
    let mut new_index = vec![u32::MAX; mesh.positions.len()];
    for t in &mesh.triangles {
        for &v in t {
            new_index[v as usize] = 0;
        }
    }
    let mut kept = 0u32;
    for slot in new_index.iter_mut().filter(|s| **s == 0) {
        *slot = kept;
        kept += 1;
    }
    let removed = mesh.positions.len() - kept as usize;
    if removed > 0 {
        let mut i = 0;
        mesh.positions.retain(|_| {
            i += 1;
            new_index[i - 1] != u32::MAX
        });
        for t in &mut mesh.triangles {
            *t = t.map(|v| new_index[v as usize]);
        }
    }
    removed
}

/// FxHash-style multiplicative hasher: the keys are float bit patterns from a file, and
/// SipHash would be a visible part of the load time.
#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }
    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
    fn write_usize(&mut self, v: usize) {
        self.write_u64(v as u64);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fan_triangulation_drops_degenerates() {
        let mut b = MeshBuilder::default();
        b.push_polygon(&[0, 1, 2, 3, 4]).unwrap();
        b.push_polygon(&[5, 5, 6]).unwrap();
        assert!(b.push_polygon(&[1, 2]).is_err());
        assert_eq!(b.finish().triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    }

    #[test]
    fn unreferenced_vertices_are_dropped_in_order() {
        let mut m = Mesh {
            positions: (0..6).map(|i| DVec3::splat(i as f64)).collect(),
            triangles: vec![[5, 1, 3], [3, 1, 5]],
        };
        assert_eq!(drop_unreferenced_vertices(&mut m), 3);
        assert_eq!(
            m.positions,
            vec![DVec3::ONE, DVec3::splat(3.0), DVec3::splat(5.0)]
        );
        assert_eq!(m.triangles, vec![[2, 0, 1], [1, 0, 2]]);
    }

    #[test]
    fn welding_merges_signed_zeros_and_drops_collapsed_triangles() {
        let p = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let m = clean_up(Mesh {
            // 3 duplicates 0 (with -0.0), 4 duplicates 1.
            positions: vec![
                p(0.0, 0.0),
                p(1.0, 0.0),
                p(0.0, 1.0),
                p(-0.0, 0.0),
                p(1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [3, 2, 4], [0, 3, 2]],
        });
        assert_eq!(m.positions, vec![p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1.0)]);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 1]]);
    }
}
