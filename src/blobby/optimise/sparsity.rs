//! Which points each blob touches (CSR incidence, and the points some blob touches at all) and
//! which blobs can be updated together (greedy colouring of the overlap graph).

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::points::Points;
use crate::blobby::{Blob, BlobField};
use crate::geometry::Aabb;

/// A blob's support enlarged by 15 %, with `b` 1 when it counts and 0 when not.
pub(super) fn widened(b: &Blob, counts: bool) -> Blob {
    Blob {
        semi_axes: b.semi_axes * 1.15,
        b: if counts && b.is_live() { 1.0 } else { 0.0 },
        ..*b
    }
}

/// The points of `pts` inside the (widened) support of some live blob of `blobs`.
pub(super) fn points_within(pts: &Points, blobs: &[Blob]) -> Points {
    let widened: Vec<Blob> = blobs.iter().map(|b| widened(b, true)).collect();
    let index = BlobField::new(&widened, 1.0);
    let keep: Vec<usize> = (0..pts.x.len())
        .into_par_iter()
        .filter(|&k| index.sum(pts.x[k]) > 0.0)
        .collect();
    Points {
        x: keep.iter().map(|&k| pts.x[k]).collect(),
        n: keep.iter().map(|&k| pts.n[k]).collect(),
        kind: keep.iter().map(|&k| pts.kind[k]).collect(),
    }
}

/// Per blob, the indices of the points inside its (slightly enlarged) support, as CSR. Blobs
/// not flagged in `active` (when given) touch no point.
pub(super) fn incidence(
    blobs: &[Blob],
    active: Option<&[bool]>,
    pts: &Points,
) -> (Vec<usize>, Vec<u32>) {
    let widened: Vec<Blob> = blobs
        .iter()
        .enumerate()
        .map(|(i, b)| widened(b, active.is_none_or(|m| m[i])))
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

/// Greedy colouring of the blobs that touch some point (`start[i + 1] > start[i]`) such that
/// two blobs of one colour share no point: their widened support boxes do not overlap (a cheap
/// superset of "share a point": the exact relation costs Σ over points of (blobs there)², which
/// was a fifth of the fit). Blobs of one colour can be updated in parallel. Deterministic
/// (blobs in index order, smallest free colour).
pub(super) fn colour(blobs: &[Blob], start: &[usize]) -> Vec<Vec<usize>> {
    let boxes: Vec<Aabb> = blobs
        .iter()
        .map(|b| widened(b, true).support_bounds())
        .collect();
    let touching: Vec<usize> = (0..blobs.len())
        .filter(|&i| start[i + 1] > start[i])
        .collect();
    // Sweep and prune along x: neighbours of each blob, as CSR over `touching`.
    let mut by_x = touching.clone();
    by_x.sort_by(|&a, &b| boxes[a].min.x.total_cmp(&boxes[b].min.x).then(a.cmp(&b)));
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for (k, &i) in by_x.iter().enumerate() {
        for &j in &by_x[k + 1..] {
            if boxes[j].min.x > boxes[i].max.x {
                break;
            }
            if boxes[i].overlaps(&boxes[j]) {
                pairs.push((i, j));
                pairs.push((j, i));
            }
        }
    }
    pairs.sort_unstable();
    let mut colour_of = vec![usize::MAX; blobs.len()];
    let mut taken: Vec<usize> = Vec::new();
    let mut cursor = 0;
    for &i in &touching {
        while cursor < pairs.len() && pairs[cursor].0 < i {
            cursor += 1;
        }
        // `taken[c] == i + 1` marks colour `c` as used by a neighbour of blob `i`.
        while cursor < pairs.len() && pairs[cursor].0 == i {
            let c = colour_of[pairs[cursor].1];
            if c != usize::MAX {
                if c >= taken.len() {
                    taken.resize(c + 1, 0);
                }
                taken[c] = i + 1;
            }
            cursor += 1;
        }
        colour_of[i] = (0..).find(|&c| taken.get(c) != Some(&(i + 1))).unwrap_or(0);
    }
    let n_colours = touching
        .iter()
        .map(|&i| colour_of[i] + 1)
        .max()
        .unwrap_or(0);
    let mut groups = vec![Vec::new(); n_colours];
    for &i in &touching {
        groups[colour_of[i]].push(i);
    }
    groups
}
