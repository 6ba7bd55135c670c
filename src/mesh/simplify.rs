//! Quadric-error-metric simplification (Garland–Heckbert, via `meshopt`) to pick decomposition
//! seeds (docs/ARCHITECTURE.md, Decomposition).
//!
//! In: a [`Mesh`] and a target vertex count. Out: the sorted indices of the original vertices
//! that the simplified mesh keeps.

use meshopt::SimplifyOptions;

use super::Mesh;

/// Indices of original vertices kept by simplifying `mesh` to about `target` vertices
/// (all vertices when the mesh has fewer). Sorted ascending, no duplicates.
///
/// Edge collapses (`meshopt::simplify`, borders locked on open meshes) aim at `target` referenced
/// vertices, with a few proportional corrections of the index-count target. When collapse gets
/// stuck above the target, `simplify_sloppy` (vertex clustering) takes over; when the result
/// still has too few vertices, evenly strided unused vertices fill it up to `target`.
pub fn simplified_vertex_indices(mesh: &Mesh, target: usize) -> Vec<u32> {
    let nv = mesh.positions.len();
    if nv <= target {
        return (0..nv as u32).collect();
    }
    if target == 0 {
        return Vec::new();
    }
    // f32 positions relative to the box centre keep precision for far-off models.
    let centre = mesh.bounds().center();
    let positions: Vec<[f32; 3]> = mesh
        .positions
        .iter()
        .map(|p| (*p - centre).as_vec3().to_array())
        .collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let options = if mesh.boundary_edge_count() > 0 {
        SimplifyOptions::LockBorder
    } else {
        SimplifyOptions::None
    };
    // A closed triangle mesh has about two triangles, six indices, per vertex.
    let mut index_target = 6 * target;
    let mut kept = Vec::new();
    for _ in 0..4 {
        let out = meshopt::simplify_decoder(
            &indices,
            &positions,
            index_target.min(indices.len()),
            1.0,
            options,
            None,
        );
        kept = unique_vertices(&out, nv);
        let err = kept.len() as f64 / target as f64;
        if (0.97..=1.03).contains(&err) || kept.is_empty() {
            break;
        }
        let next = (index_target as f64 / err).round() as usize;
        if next == index_target {
            break;
        }
        index_target = next.max(3);
    }
    if kept.len() as f64 > 1.2 * target as f64 {
        // Stuck (locked borders, non-manifold input): clustering always reaches a target.
        let out =
            meshopt::simplify_sloppy_decoder(&indices, &positions, 6 * target, f32::MAX, None);
        let sloppy = unique_vertices(&out, nv);
        if !sloppy.is_empty() && sloppy.len() <= kept.len() {
            kept = sloppy;
        }
    }
    if kept.len() > target + target / 5 {
        kept = strided(&kept, target);
    }
    fill_strided(&mut kept, &mesh.triangles, nv, target);
    kept
}

/// Sorted unique vertices referenced by an index buffer.
fn unique_vertices(indices: &[u32], nv: usize) -> Vec<u32> {
    let mut used = vec![false; nv];
    for &i in indices {
        used[i as usize] = true;
    }
    (0..nv as u32).filter(|&i| used[i as usize]).collect()
}

/// `count` evenly strided entries of `from` (sorted input gives sorted output).
fn strided(from: &[u32], count: usize) -> Vec<u32> {
    (0..count).map(|k| from[k * from.len() / count]).collect()
}

/// Add evenly strided vertices not yet in `kept` until it holds about `target`; keeps it sorted.
fn fill_strided(kept: &mut Vec<u32>, triangles: &[[u32; 3]], nv: usize, target: usize) {
    if kept.len() >= target * 97 / 100 {
        return;
    }
    // Only vertices used by some triangle are candidates (isolated ones have no normal).
    let mut used = vec![true; nv];
    for &i in triangles.iter().flatten() {
        used[i as usize] = false;
    }
    for &i in kept.iter() {
        used[i as usize] = true;
    }
    let free: Vec<u32> = (0..nv as u32).filter(|&i| !used[i as usize]).collect();
    let missing = (target - kept.len()).min(free.len());
    if missing > 0 {
        kept.extend(strided(&free, missing));
        kept.sort_unstable();
        kept.dedup();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::sample::tests::sphere;

    #[test]
    fn small_meshes_keep_every_vertex() {
        let m = sphere(1.0, 2);
        let v = simplified_vertex_indices(&m, 10_000);
        assert_eq!(v, (0..m.positions.len() as u32).collect::<Vec<_>>());
    }

    #[test]
    fn simplification_hits_the_target_and_spreads_seeds() {
        let m = sphere(1.0, 5); // 4,098 vertices
        let v = simplified_vertex_indices(&m, 500);
        assert!((450..=550).contains(&v.len()), "{} seeds", v.len());
        assert!(v.windows(2).all(|w| w[0] < w[1]));
        // Every point of the sphere has a seed nearby (seeds spread, not clustered).
        let seeds: Vec<_> = v.iter().map(|&i| m.positions[i as usize]).collect();
        for p in m.positions.iter().step_by(37) {
            let d = seeds
                .iter()
                .map(|s| s.distance(*p))
                .fold(f64::MAX, f64::min);
            assert!(d < 0.25, "{p} is {d} from its nearest seed");
        }
    }

    #[test]
    fn open_meshes_still_reach_the_target() {
        let mut m = sphere(1.0, 5);
        // Cut away the upper cap: a large open border.
        let keep: Vec<[u32; 3]> = m
            .triangles
            .iter()
            .copied()
            .filter(|t| t.iter().all(|&i| m.positions[i as usize].y < 0.5))
            .collect();
        m.triangles = keep;
        let v = simplified_vertex_indices(&m, 300);
        assert!((280..=380).contains(&v.len()), "{} seeds", v.len());
    }
}
