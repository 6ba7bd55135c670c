//! Which points each blob touches (CSR incidence) and which blobs can be updated together
//! (greedy colouring of the overlap graph).

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::points::Points;
use crate::blobby::{Blob, BlobField};

/// Per blob, the indices of the points inside its (slightly enlarged) support, as CSR.
pub(super) fn incidence(blobs: &[Blob], pts: &Points) -> (Vec<usize>, Vec<u32>) {
    let widened: Vec<Blob> = blobs
        .iter()
        .map(|b| Blob {
            semi_axes: b.semi_axes * 1.15,
            b: if b.is_live() { 1.0 } else { 0.0 },
            ..*b
        })
        .collect();
    let index = BlobField::new(&widened, 1.0);
    // Support tests as a matrix product: `x` is inside when |M(x − c)|² < 1.
    let frames: Vec<(DMat3, DVec3)> = widened
        .iter()
        .map(|b| {
            let r = b.semi_axes * (1.0 + b.a).sqrt();
            let m = DMat3::from_diagonal(1.0 / r) * DMat3::from_quat(b.rotation.inverse());
            (m, b.center)
        })
        .collect();
    // Point → blobs as CSR, built per chunk of points (one allocation a chunk, not a point).
    let inside = |x: DVec3, i: u32| {
        let (m, c) = frames[i as usize];
        widened[i as usize].b > 0.0 && (m * (x - c)).length_squared() < 1.0
    };
    let chunks: Vec<(Vec<u32>, Vec<u32>)> = pts
        .x
        .par_chunks(1024)
        .map(|xs| {
            let (mut counts, mut list) = (Vec::with_capacity(xs.len()), Vec::new());
            for &x in xs {
                let before = list.len();
                list.extend(
                    index
                        .blobs_near(x)
                        .iter()
                        .copied()
                        .filter(|&i| inside(x, i)),
                );
                counts.push((list.len() - before) as u32);
            }
            (counts, list)
        })
        .collect();
    let mut p_start = Vec::with_capacity(pts.x.len() + 1);
    p_start.push(0usize);
    let mut p_blobs = Vec::new();
    for (counts, list) in chunks {
        for c in counts {
            p_start.push(p_start[p_start.len() - 1] + c as usize);
        }
        p_blobs.extend(list);
    }
    transpose(&p_start, &p_blobs, blobs.len())
}

/// The transpose of a CSR relation (`start`, `entries`) from rows to `n_columns` columns: for
/// each column, the rows that list it, in increasing order.
fn transpose(start: &[usize], entries: &[u32], n_columns: usize) -> (Vec<usize>, Vec<u32>) {
    let mut t_start = vec![0usize; n_columns + 1];
    for &c in entries {
        t_start[c as usize + 1] += 1;
    }
    for c in 0..n_columns {
        t_start[c + 1] += t_start[c];
    }
    let mut fill = t_start.clone();
    let mut t_entries = vec![0u32; entries.len()];
    for row in 0..start.len().saturating_sub(1) {
        for &c in &entries[start[row]..start[row + 1]] {
            t_entries[fill[c as usize]] = row as u32;
            fill[c as usize] += 1;
        }
    }
    (t_start, t_entries)
}

/// Greedy colouring of the graph "blobs share a point": blobs of one colour can be updated
/// in parallel. Deterministic (blobs in index order, smallest free colour).
pub(super) fn colour(
    n_blobs: usize,
    start: &[usize],
    entries: &[u32],
    n_points: usize,
) -> Vec<Vec<usize>> {
    let (p_start, p_blobs) = transpose(start, entries, n_points);
    let mut colour_of = vec![usize::MAX; n_blobs];
    // `taken[c] == i + 1` marks colour `c` as used by a neighbour of blob `i`.
    let mut taken: Vec<usize> = Vec::new();
    for i in 0..n_blobs {
        for &p in &entries[start[i]..start[i + 1]] {
            for &j in &p_blobs[p_start[p as usize]..p_start[p as usize + 1]] {
                let c = colour_of[j as usize];
                if c != usize::MAX {
                    if c >= taken.len() {
                        taken.resize(c + 1, 0);
                    }
                    taken[c] = i + 1;
                }
            }
        }
        colour_of[i] = (0..).find(|&c| taken.get(c) != Some(&(i + 1))).unwrap_or(0);
    }
    let n_colours = colour_of.iter().copied().max().map_or(0, |c| c + 1);
    let mut groups = vec![Vec::new(); n_colours];
    for (i, &c) in colour_of.iter().enumerate() {
        groups[c].push(i);
    }
    groups
}
