//! Where a steered category-II blob emerges: part way from its parent's centre toward its own,
//! so that it grows out of the side of the cloud it belongs on instead of crossing the body.
//!
//! Unsteered, a new blob starts at its parent's centre at zero size and moves out as it grows
//! (the paper's "grows out of"). From a steered start the parents are often the large body
//! blobs, and a II blob then crosses the body while mid-sized: on the duck from the tail
//! (−0.75, 0.1, 0) blob 3 crossed blob 0, whose long axis pokes out of the early cloud in a
//! thin tip that the billows nearly cut off; with blob 3's field passing through it, the
//! rendered neck fell below the coverage's alpha and the tip split off on screen (largest
//! piece 0.939 of the coverage, frame 65). Emerging nearer its place, blob 3 covers the tip
//! while it grows (docs/MEASUREMENTS.md, "Steered starts on the duck").

use glam::DVec3;

use crate::blobby::{Blob, BlobField};

/// How far toward the cloud's surface a steered II blob emerges: this share of the way from
/// its parent's centre to where the segment toward its own centre leaves the cloud shown
/// before it (to its own centre when that is inside). Half: it starts well inside (a blob
/// born on the surface shows as a small bump of its own while it is tiny: on the duck from the
/// tail at 1, the coverage's largest piece fell to 0.961 at frame 50, against 0.974 at ½).
pub(super) const EMERGE_DEPTH: f64 = 0.5;

/// Samples along the way from the parent's centre to the blob's.
const SAMPLES: usize = 64;

/// Per blob (by index): where each category-II blob of `placed` (`placed[0]` is blob I, the
/// rest II in display order) emerges, as a share of the way from its parent's centre to its
/// own (0 for every other blob). `early`: the blobs as shown before the blend (full size).
pub(super) fn emergence(
    early: &[Blob],
    threshold: f64,
    placed: &[usize],
    parent: &[Option<usize>],
) -> Vec<f64> {
    let mut emerge = vec![0.0; early.len()];
    let mut shown: Vec<Blob> = Vec::with_capacity(placed.len());
    for (pos, &i) in placed.iter().enumerate() {
        if pos > 0
            && let Some(p) = parent[i]
        {
            let field = BlobField::new(&shown, threshold);
            let exit = exit_share(&field, early[p].center, early[i].center);
            emerge[i] = EMERGE_DEPTH * exit;
        }
        shown.push(early[i]);
    }
    emerge
}

/// The share of the segment `a → b` (`a` inside the cloud of `field`) before it first leaves
/// the cloud, on [`SAMPLES`] steps (1 when it stays inside).
fn exit_share(field: &BlobField, a: DVec3, b: DVec3) -> f64 {
    (1..=SAMPLES)
        .find(|&k| field.value(a.lerp(b, k as f64 / SAMPLES as f64)) < 0.0)
        .map_or(1.0, |k| (k - 1) as f64 / SAMPLES as f64)
}

/// A blob's size progress `e` mapped to its progress along the way out from its parent's
/// centre when it emerges at share `k` of the way: `k` at size 0, exactly 1 at full size; `e`
/// itself (bit for bit) when `k` is 0, the unsteered rule.
#[inline]
pub(super) fn way_out(k: f64, e: f64) -> f64 {
    if k > 0.0 {
        1.0 - (1.0 - k) * (1.0 - e)
    } else {
        e
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn sphere(center: DVec3, r: f64) -> Blob {
        let a = 1.0;
        Blob {
            center,
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
            a,
            b: (1.0 + a) / a,
        }
    }

    /// A II blob beyond its parent's surface emerges half way to where the way out leaves the
    /// parent's cloud (a unit sphere: at 1 of the 2 to its centre), inside the cloud; blob I
    /// and a blob without a parent stay at 0; one whose centre is inside emerges half way to it.
    #[test]
    fn a_steered_blob_emerges_half_way_to_the_surface() {
        let early = [
            sphere(DVec3::ZERO, 1.0),
            sphere(DVec3::new(2.0, 0.0, 0.0), 0.6),
            sphere(DVec3::new(0.0, 0.5, 0.0), 0.3),
        ];
        let parent = [None, Some(0), Some(0)];
        let k = emergence(&early, 1.0, &[0, 1, 2], &parent);
        assert_eq!(k[0], 0.0);
        // The unit sphere's surface is at 1 on the way of length 2: the exit share is 0.5
        // within a step (1/64), the emergence half of it.
        assert!((k[1] - 0.25).abs() <= 0.5 / SAMPLES as f64, "{}", k[1]);
        let field = BlobField::new(&early[..1], 1.0);
        assert!(field.value(DVec3::ZERO.lerp(early[1].center, k[1])) > 0.0);
        assert_eq!(k[2], EMERGE_DEPTH, "a centre inside: half way to it");
        assert_eq!(emergence(&early, 1.0, &[0, 1], &[None, None, None])[1], 0.0);
    }

    /// The way out is exactly the blob's own centre at full size, starts at `k`, and is the
    /// unsteered `e` bit for bit when `k` is 0.
    #[test]
    fn the_way_out_ends_at_the_blobs_centre() {
        for k in [0.1, 0.25, 0.3, 0.7] {
            assert_eq!(way_out(k, 1.0), 1.0);
            assert!((way_out(k, 0.0) - k).abs() < 1e-15);
            assert!(way_out(k, 0.5) > way_out(k, 0.4));
        }
        for e in [0.0, 0.123, 0.5, 1.0] {
            assert_eq!(way_out(0.0, e).to_bits(), e.to_bits());
        }
    }
}
