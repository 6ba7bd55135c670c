//! The display order of the diffusion scheme: which blob appears next (paper §5.2.2: the next
//! category-II blob is the one whose centre has the smallest signed distance to the current
//! surface; category III follows by nearness), optionally steered by the artist ([`Steering`]:
//! where it starts, which blobs come first).

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

/// How the artist steers the display order (the diffusion's `start` and `order`; nothing by
/// default, the paper's order).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Steering {
    /// Where the diffusion starts: blob I is the live blob nearest this point (in its own
    /// ellipsoidal radius, so the blob the point is in, or the one it is nearest to).
    pub start: Option<DVec3>,
    /// Blobs shown first, in this order (checked: live, each once). Blob I is the first of
    /// them unless `start` picks it; the others open category II in the written order.
    pub order: Vec<usize>,
}

impl Steering {
    /// True when nothing is steered (the paper's order, bit for bit).
    pub fn is_none(&self) -> bool {
        self.start.is_none() && self.order.is_empty()
    }
}

/// Display order of the live blobs: the first, then the next `n_ii` (category II) greedily by
/// signed distance to the visible surface, then the rest (category III) in selection order.
/// Returns the order and the number of category-II blobs placed: with `connected`, a II blob
/// is placed only if it joins the visible cloud (the segment from its centre to the centre of
/// its nearest visible blob lies inside the cloud with it added); the nearest connecting one
/// goes next, and those that never connect are deferred to the front of category III.
///
/// Steered ([`Steering`]): blob I is the one nearest `start` (else the first of `order`), the
/// listed blobs open category II in their order (placed whether they join or not: the artist's
/// choice), and the paper's rule places the rest of II around them. When no II blob joins the
/// cloud (a start far from the large blobs), the joining live blob of smallest signed distance
/// is placed as a bridge toward them, so the early cloud still grows in one piece.
pub fn display_order(
    blobs: &[Blob],
    threshold: f64,
    n_ii: usize,
    connected: bool,
    steering: &Steering,
) -> (Vec<usize>, usize) {
    let live: Vec<usize> = (0..blobs.len()).filter(|&i| blobs[i].is_live()).collect();
    if live.is_empty() {
        return (Vec::new(), 0);
    }
    let first = match (steering.start, steering.order.first()) {
        (Some(p), _) => nearest_blob(blobs, &live, p).expect("live blobs"),
        (None, Some(&i)) => i,
        (None, None) => live[0],
    };
    // The artist's blobs after the first, then the rest in selection order.
    let listed: Vec<usize> = steering
        .order
        .iter()
        .copied()
        .filter(|&i| i != first)
        .collect();
    let rest: Vec<usize> = live
        .iter()
        .copied()
        .filter(|&i| i != first && !listed.contains(&i))
        .collect();
    let n_ii = n_ii.saturating_sub(listed.len()).min(rest.len());
    let diag = blob_bounds(blobs).diagonal().max(f64::MIN_POSITIVE);
    let mut order = vec![first];
    order.extend_from_slice(&listed);
    let mut remaining: Vec<usize> = rest[..n_ii].to_vec();
    let mut others: Vec<usize> = rest[n_ii..].to_vec();
    let mut visible_idx: Vec<usize> = order.clone();
    let mut visible: Vec<Blob> = order.iter().map(|&i| blobs[i]).collect();
    let steered = !steering.is_none();
    while !remaining.is_empty() {
        let field = BlobField::new(&visible, threshold);
        let pick = next_joining(
            &field,
            blobs,
            &visible,
            &visible_idx,
            &remaining,
            connected,
            diag,
        );
        let i = match pick {
            Some(r) => remaining.remove(r),
            None if steered && connected => {
                // A bridge from the steered start toward the category-II blobs.
                match next_joining(&field, blobs, &visible, &visible_idx, &others, true, diag) {
                    Some(r) => others.remove(r),
                    None => break,
                }
            }
            None => break,
        };
        order.push(i);
        visible_idx.push(i);
        visible.push(blobs[i]);
    }
    let placed = order.len() - 1;
    order.extend_from_slice(&remaining);
    order.extend_from_slice(&others);
    (order, placed)
}

/// The position in `candidates` of the next blob by the paper's rule: smallest signed distance
/// to the cloud of `field` (ties to the earlier one), among those that join it when
/// `connected`.
fn next_joining(
    field: &BlobField,
    blobs: &[Blob],
    visible: &[Blob],
    visible_idx: &[usize],
    candidates: &[usize],
    connected: bool,
    diag: f64,
) -> Option<usize> {
    let mut ranked: Vec<(usize, f64)> = candidates
        .iter()
        .enumerate()
        .map(|(r, &i)| (r, signed_distance(field, visible, blobs[i].center, diag)))
        .collect();
    // Stable: ties keep the lower index.
    ranked.sort_by(|a, b| a.1.total_cmp(&b.1));
    ranked
        .iter()
        .map(|&(r, _)| r)
        .find(|&r| !connected || joins(field, blobs, visible_idx, &blobs[candidates[r]]))
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
