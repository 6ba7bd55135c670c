//! The display order of the diffusion scheme: which blob appears next (paper §5.2.2: the next
//! category-II blob is the one whose centre has the smallest signed distance to the current
//! surface; category III follows by nearness).

use glam::DVec3;

use crate::animate::blob_bounds;
use crate::animate::pieces::{nearest_blob, segment_inside};
use crate::blobby::{Blob, BlobField};

/// Reorder `order[fixed..]` greedily: next is the blob whose centre is nearest (Euclidean) to
/// the centre of any blob already placed (ties to the earlier one).
pub(super) fn order_by_nearest(blobs: &[Blob], order: &mut [usize], fixed: usize) {
    if fixed == 0 || fixed >= order.len() {
        return;
    }
    // Distance of each remaining blob to the nearest placed centre, updated as blobs are placed.
    let mut dist: Vec<f64> = order[fixed..]
        .iter()
        .map(|&i| {
            order[..fixed]
                .iter()
                .map(|&j| blobs[j].center.distance_squared(blobs[i].center))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    for pos in fixed..order.len() {
        let r = pos - fixed;
        let pick = (r..dist.len())
            .min_by(|&a, &b| dist[a].total_cmp(&dist[b]).then(a.cmp(&b)))
            .expect("non-empty");
        order.swap(pos, fixed + pick);
        dist.swap(r, pick);
        let placed = blobs[order[pos]].center;
        for q in r + 1..dist.len() {
            let d = placed.distance_squared(blobs[order[fixed + q]].center);
            dist[q] = dist[q].min(d);
        }
    }
}

/// Number of category-II blobs among `n`: `round(fraction · n)`, at least 1 when `n ≥ 2` and the
/// fraction is positive, at most `n − 1`.
pub fn category_ii_count(n: usize, fraction: f64) -> usize {
    if n < 2 {
        return 0;
    }
    let k = (fraction * n as f64).round() as usize;
    let k = if fraction > 0.0 { k.max(1) } else { k };
    k.min(n - 1)
}

/// Display order of the live blobs: the first, then the next `n_ii` (category II) greedily by
/// signed distance to the visible surface, then the rest (category III) in selection order.
/// Returns the order and the number of category-II blobs placed: with `connected`, a II blob
/// is placed only if it joins the visible cloud (the segment from its centre to the centre of
/// its nearest visible blob lies inside the cloud with it added); the nearest connecting one
/// goes next, and those that never connect are deferred to the front of category III.
pub fn display_order(
    blobs: &[Blob],
    threshold: f64,
    n_ii: usize,
    connected: bool,
) -> (Vec<usize>, usize) {
    let live: Vec<usize> = (0..blobs.len()).filter(|&i| blobs[i].is_live()).collect();
    let Some((&first, rest)) = live.split_first() else {
        return (Vec::new(), 0);
    };
    let n_ii = n_ii.min(rest.len());
    let diag = blob_bounds(blobs).diagonal().max(f64::MIN_POSITIVE);
    let mut order = vec![first];
    let mut remaining: Vec<usize> = rest[..n_ii].to_vec();
    let mut visible_idx: Vec<usize> = vec![first];
    let mut visible: Vec<Blob> = vec![blobs[first]];
    while !remaining.is_empty() {
        let field = BlobField::new(&visible, threshold);
        let mut ranked: Vec<(usize, f64)> = remaining
            .iter()
            .enumerate()
            .map(|(r, &i)| (r, signed_distance(&field, &visible, blobs[i].center, diag)))
            .collect();
        // Stable: ties keep the lower index.
        ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
        let pick = ranked
            .iter()
            .map(|&(r, _)| r)
            .find(|&r| !connected || joins(&field, blobs, &visible_idx, &blobs[remaining[r]]));
        let Some(pick) = pick else {
            break;
        };
        let i = remaining.remove(pick);
        order.push(i);
        visible_idx.push(i);
        visible.push(blobs[i]);
    }
    let placed = order.len() - 1;
    order.extend_from_slice(&remaining);
    order.extend_from_slice(&rest[n_ii..]);
    (order, placed)
}

/// True when `blob`, added to the cloud of `field` (blobs `visible`), lies in one piece with
/// it: the field is at or above the iso-level along the segment from `blob`'s centre to the
/// centre of its nearest visible blob.
fn joins(field: &BlobField, blobs: &[Blob], visible: &[usize], blob: &Blob) -> bool {
    let Some(j) = nearest_blob(blobs, visible, blob.center) else {
        return true;
    };
    segment_inside(
        |x| field.value(x) + blob.value(x),
        blob.center,
        blobs[j].center,
    )
}

/// Signed distance estimate from `x` to the surface of `field` (negative inside), see the
/// module doc.
fn signed_distance(field: &BlobField, visible: &[Blob], x: DVec3, diag: f64) -> f64 {
    let (f, g) = field.value_and_gradient(x);
    if f + field.threshold() <= 0.0 {
        let nearest = visible
            .iter()
            .map(|b| b.center.distance(x))
            .fold(f64::INFINITY, f64::min);
        return diag + nearest;
    }
    let slope = g.length();
    if slope <= 0.0 {
        return if f > 0.0 { -diag } else { diag };
    }
    (-f / slope).clamp(-diag, diag)
}
