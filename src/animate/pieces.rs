//! Keeping a cluster of blobs in one piece of cloud (aggregation keyframes).
//!
//! A blob is *joined* to a set of blobs when the field of the cluster is at or above the
//! iso-level along the segment from its centre to the centre of its nearest joined blob (by
//! that blob's ellipsoidal radius). Starting from the cluster's largest blob, blobs that join
//! are added until none does; each blob left over is pulled along the segment toward its
//! nearest joined blob until it joins (bisection) and a little further, so jitter and repulsion never leave
//! a blob flying alone. Only blobs whose centre is inside the cluster's solid take part (the
//! others do not show); the partner's centre is inside, so a pulled blob joins at the latest
//! on reaching it, and the loop ends.

use glam::DVec3;

use crate::blobby::{Blob, BlobField};

/// Share of the remaining way a pulled blob moves past the point where it first joins.
const NECK_MARGIN: f64 = 0.3;

/// Samples along a joining segment.
const SEGMENT_SAMPLES: usize = 32;

/// True when the segment `a → b` lies inside the solid of the field `f` (`F(x) = f(x) ≥ 0` at
/// every sample).
pub(crate) fn segment_inside(f: impl Fn(DVec3) -> f64, a: DVec3, b: DVec3) -> bool {
    (0..=SEGMENT_SAMPLES).all(|k| f(a.lerp(b, k as f64 / SEGMENT_SAMPLES as f64)) >= 0.0)
}

/// Of `candidates`, the blob whose ellipsoid is nearest `x` (smallest ellipsoidal radius).
pub(crate) fn nearest_blob(blobs: &[Blob], candidates: &[usize], x: DVec3) -> Option<usize> {
    candidates.iter().copied().min_by(|&a, &b| {
        let ra = blobs[a].ellipsoid().radius_squared(x);
        let rb = blobs[b].ellipsoid().radius_squared(x);
        ra.total_cmp(&rb)
    })
}

/// Move members of `members` (indices into `blobs`) so that the cluster is one piece at
/// iso-level `threshold`; returns how many blobs were moved. Deterministic.
pub(crate) fn keep_in_one_piece(blobs: &mut [Blob], members: &[usize], threshold: f64) -> usize {
    // Only blobs whose centre is inside the cluster's solid show; the others (below the
    // iso-level even with their neighbours) are left alone.
    let cluster_field = |blobs: &[Blob]| {
        BlobField::new(
            &members.iter().map(|&k| blobs[k]).collect::<Vec<_>>(),
            threshold,
        )
    };
    let mut field = cluster_field(blobs);
    let shown: Vec<usize> = members
        .iter()
        .copied()
        .filter(|&i| field.is_inside(blobs[i].center))
        .collect();
    let Some(&root) = shown.iter().max_by(|&&a, &&b| {
        let (va, vb) = (
            blobs[a].semi_axes.element_product(),
            blobs[b].semi_axes.element_product(),
        );
        va.total_cmp(&vb).then(b.cmp(&a))
    }) else {
        return 0;
    };
    let mut joined = vec![root];
    let mut left: Vec<usize> = shown.iter().copied().filter(|&i| i != root).collect();
    let mut moved = 0;
    while !left.is_empty() {
        // `field` is the cluster's as it stands: rebuilt only when a blob moves.
        let before = left.len();
        left.retain(|&i| {
            let mate = nearest_blob(blobs, &joined, blobs[i].center).expect("root joined");
            if segment_inside(|x| field.value(x), blobs[i].center, blobs[mate].center) {
                joined.push(i);
                false
            } else {
                true
            }
        });
        if left.len() < before {
            continue;
        }
        // Nothing joins as it is: pull the first one left just far enough toward its mate.
        let i = left.remove(0);
        let mate = nearest_blob(blobs, &joined, blobs[i].center).expect("root joined");
        let (from, to) = (blobs[i].center, blobs[mate].center);
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..8 {
            let mid = 0.5 * (lo + hi);
            blobs[i].center = from.lerp(to, mid);
            let trial = cluster_field(blobs);
            if segment_inside(|x| trial.value(x), blobs[i].center, to) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        // A little further than just touching, so the neck is solid, not a point.
        blobs[i].center = from.lerp(to, hi + NECK_MARGIN * (1.0 - hi));
        joined.push(i);
        moved += 1;
        field = cluster_field(blobs);
    }
    moved
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::sphere_blob as sphere;

    #[test]
    fn a_blob_flying_alone_is_pulled_back_until_it_joins() {
        let mut blobs = vec![
            sphere(DVec3::ZERO, 1.0),
            sphere(DVec3::new(1.5, 0.0, 0.0), 0.6),
            sphere(DVec3::new(6.0, 0.0, 0.0), 0.5),
        ];
        let moved = keep_in_one_piece(&mut blobs, &[0, 1, 2], 1.0);
        assert_eq!(moved, 1);
        let far = blobs[2].center.x;
        assert!(far < 6.0 && far > 1.5, "{far}");
        let field = BlobField::new(&blobs, 1.0);
        assert!(segment_inside(
            |x| field.value(x),
            blobs[2].center,
            blobs[1].center
        ));
        // Not collapsed onto its neighbour: it stays more than 40 % of its radius away.
        assert!(far - 1.5 > 0.4 * 0.6, "{far}");
    }
}
