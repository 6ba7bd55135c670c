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
    let per_point: Vec<Vec<u32>> = pts
        .x
        .par_iter()
        .map(|&x| {
            index
                .blobs_near(x)
                .iter()
                .copied()
                .filter(|&i| {
                    let (m, c) = frames[i as usize];
                    widened[i as usize].b > 0.0 && (m * (x - c)).length_squared() < 1.0
                })
                .collect()
        })
        .collect();
    let mut start = vec![0usize; blobs.len() + 1];
    for list in &per_point {
        for &i in list {
            start[i as usize + 1] += 1;
        }
    }
    for i in 0..blobs.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut entries = vec![0u32; start[blobs.len()]];
    for (p, list) in per_point.iter().enumerate() {
        for &i in list {
            entries[fill[i as usize]] = p as u32;
            fill[i as usize] += 1;
        }
    }
    (start, entries)
}

/// Greedy colouring of the graph "blobs share a point": blobs of one colour can be updated
/// in parallel. Deterministic (blobs in index order, smallest free colour).
pub(super) fn colour(
    n_blobs: usize,
    start: &[usize],
    entries: &[u32],
    n_points: usize,
) -> Vec<Vec<usize>> {
    // The transpose of the incidence (point → blobs), as CSR.
    let mut p_start = vec![0usize; n_points + 1];
    for &p in entries {
        p_start[p as usize + 1] += 1;
    }
    for p in 0..n_points {
        p_start[p + 1] += p_start[p];
    }
    let mut fill = p_start.clone();
    let mut p_blobs = vec![0u32; entries.len()];
    for i in 0..n_blobs {
        for &p in &entries[start[i]..start[i + 1]] {
            p_blobs[fill[p as usize]] = i as u32;
            fill[p as usize] += 1;
        }
    }
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
