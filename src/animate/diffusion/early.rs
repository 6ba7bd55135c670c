//! The early shape of categories I and II and how it turns into the fitted one: the blobs at
//! their ellipsoids' extent, their `B` on the way to the fitted value, and the volume pace of
//! category II's arrival.

use super::lerp;
use crate::animate::blob_bounds;
use crate::animate::stats::{Lattice, visible_volume};
use crate::blobby::Blob;

/// `B` part way (`fitted` ∈ [0, 1]) from the early `early` to the fitted `b`: geometric, so
/// the field changes at an even relative rate (the early `B²` is often tens of times the
/// fitted one, and a linear blend would do most of its shrinking in its last few percent);
/// linear in `B²` when either is 0.
pub(super) fn blend_b(early: f64, b: f64, fitted: f64) -> f64 {
    if early > 0.0 && b > 0.0 {
        early * (b / early).powf(fitted)
    } else {
        lerp(early * early, b * b, fitted).sqrt()
    }
}

/// The blobs with `B = γ·(1+A)/A` (`γ` = `strength`; 1 shows an isolated blob at its
/// ellipsoid), or the fitted `B` when `strength` is 0. Dead blobs stay dead.
pub(super) fn early_shape(target: &[Blob], strength: f64) -> Vec<Blob> {
    target
        .iter()
        .map(|b| {
            if strength > 0.0 && b.is_live() {
                Blob {
                    b: strength * (1.0 + b.a) / b.a,
                    ..*b
                }
            } else {
                *b
            }
        })
        .collect()
}

/// For the first blobs of `order` (category I then II, as displayed at full size), the
/// fraction in `(0, 1]` of the early shape's growth done once blob `k` is in: 90 % the visible
/// volume of blobs `order[..=k]` on a 2 % lattice over that of all of them, 10 % the count
/// (evenly spaced when nothing is visible); and the cells of all of them.
pub(super) fn volume_paced_finish(
    early: &[Blob],
    threshold: f64,
    order: &[usize],
) -> (Vec<f64>, usize) {
    let n = order.len();
    if n == 0 {
        return (Vec::new(), 0);
    }
    let lattice = Lattice::for_target(&blob_bounds(early), 0.02);
    let mut shown: Vec<Blob> = early.iter().map(|b| Blob { b: 0.0, ..*b }).collect();
    let mut volume = Vec::with_capacity(n);
    for &i in order {
        shown[i] = early[i];
        volume.push(visible_volume(&shown, threshold, lattice).voxels as f64);
    }
    // Blobs hidden inside others add nothing; keep the curve non-decreasing.
    for k in 1..n {
        volume[k] = volume[k].max(volume[k - 1]);
    }
    let v1 = volume[n - 1];
    let finish = (0..n)
        .map(|k| {
            let even = (k + 1) as f64 / n as f64;
            if v1 > 0.0 {
                // Mostly by volume, a little by count, so no two blobs land on one instant.
                0.9 * volume[k] / v1 + 0.1 * even
            } else {
                even
            }
        })
        .collect();
    (finish, v1 as usize)
}
