//! The shape refit of a carried blob where its anchors leave their affine map (issue 51,
//! item 3; built and measured against carrying, docs/MEASUREMENTS.md, "Bending": it gains
//! 0.001–0.002 of silhouette IoU and loses none; what deforming shots use).
//!
//! The carry's map `M = (Q + λR)(P + λI)⁻¹` is the least-squares affine map of the anchors;
//! where the surface bends across a blob no affine map fits, and the least-squares one shrinks
//! toward the anchors' correlation (an arc's points correlate less with their rest line than
//! the line with itself), so the blob thins. The shape refit compares, along each of the
//! blob's carried axes `u = M r / |M r|`, the deformed anchors' spread (their covariance `Cₜ`,
//! the least-squares ellipsoid of the anchors) with the spread `M` predicts (`M P Mᵀ`), and
//! stretches that axis by the ratio of their square roots, within a factor [`MAX_GAIN`]:
//!
//! ```text
//! gain_r = √(uᵀ Cₜ u / uᵀ M P Mᵀ u),   S = M + Σ_r (gain_r − 1) (M r) rᵀ
//! ```
//!
//! only for axes the anchors span at rest (variance along `r` at least [`SPANNED`] of their
//! widest: a flat patch that bends gains spread across itself that says nothing of the blob's
//! thickness). For an affine motion `Cₜ = M P Mᵀ` up to the regularisation, so a blob the
//! surface carries affinely is all but unchanged; only blobs past the refit's `from`
//! ([`super::refit::RefitConfig`]) are touched, with its weight, per frame of the sequence,
//! read linear between frames. The centre is the carry's.
//!
//! Tried first: mapping the anchors' whole covariance (`S = Cₜ^½ U C₀^-½`, `U` the rotation
//! nearest `Cₜ^-½ Q C₀^-½`, so `S C₀ Sᵀ = Cₜ`): its measurement was lost to a bug (a default
//! correction of glam's identity matrix, not zero) and, with the reason above, not repeated.

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::refit::{RefitConfig, weight};
use super::{Deformation, outer};

use crate::blobby::Blob;
use crate::decompose::eigen::symmetric_eigen;

/// An axis of a blob is re-stretched only where the anchors' rest variance along it is at least
/// this share of their widest.
const SPANNED: f64 = 0.25;

/// The most the shape refit changes a semi-axis from the carry's: by this factor either way.
const MAX_GAIN: f64 = 1.5;

/// A blob's shape correction on one frame: added to the carry's `M` (the centre stays the
/// carry's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeCorrection {
    /// `w (S − M)`.
    pub linear: DMat3,
}

impl Default for ShapeCorrection {
    /// No correction (not glam's default matrix, the identity).
    fn default() -> Self {
        ShapeCorrection {
            linear: DMat3::ZERO,
        }
    }
}

/// Per frame of the sequence, per blob of `formed` (anchored in `d`), its shape correction;
/// and how many (blob, frame) pairs are corrected. Empty when none is.
pub(super) fn corrections(
    d: &Deformation,
    formed: &[Blob],
    frames: usize,
    cfg: &RefitConfig,
) -> (Vec<Vec<ShapeCorrection>>, usize) {
    let per_frame: Vec<Vec<ShapeCorrection>> = (0..frames)
        .into_par_iter()
        .map(|f| {
            (0..formed.len())
                .map(|i| {
                    let b = &formed[i];
                    if !b.is_live() {
                        return ShapeCorrection::default();
                    }
                    let leave = d.residual_between(i, f, f, 0.0) / b.semi_axes.min_element();
                    let w = weight(leave, cfg);
                    if w <= 0.0 {
                        return ShapeCorrection::default();
                    }
                    d.shape_correction(i, b, f, w)
                })
                .collect()
        })
        .collect();
    let count = per_frame
        .iter()
        .flatten()
        .filter(|c| **c != ShapeCorrection::default())
        .count();
    if count == 0 {
        return (Vec::new(), 0);
    }
    (per_frame, count)
}

impl Deformation {
    /// Blob `i` (`blob`, formed) its shape correction on sequence frame `f` with weight `w`
    /// (module doc).
    fn shape_correction(&self, i: usize, blob: &Blob, f: usize, w: f64) -> ShapeCorrection {
        let k = &self.blobs[i];
        let anchors = &self.anchors[k.start as usize..(k.start + k.len) as usize];
        let at = &self.tracks[f];
        let mean = anchors
            .iter()
            .fold(DVec3::ZERO, |m, x| m + at[x.vertex as usize] * x.weight);
        let (mut spread, mut rest) = (DMat3::ZERO, DMat3::ZERO);
        for x in anchors {
            let q = at[x.vertex as usize] - mean;
            spread += outer(q * x.weight, q);
            rest += outer(x.offset * x.weight, x.offset);
        }
        let map = self.map_between(i, f, f, 0.0);
        let m = map.linear;
        // What the affine map says the anchors' spread is, against what it is.
        let predicted = m * rest * m.transpose();
        let widest = symmetric_eigen(&rest).0.x.max(f64::MIN_POSITIVE);
        let axes = DMat3::from_quat(blob.rotation);
        let mut shape = m;
        for r in [axes.x_axis, axes.y_axis, axes.z_axis] {
            // Only along axes the anchors span at rest (a flat patch bent gains spread across
            // itself that says nothing of the blob's thickness).
            if r.dot(rest * r) < SPANNED * widest {
                continue;
            }
            let carried = m * r;
            let len = carried.length();
            if !(len > 0.0) {
                continue;
            }
            let u = carried / len;
            let gain = (u.dot(spread * u) / u.dot(predicted * u).max(f64::MIN_POSITIVE))
                .sqrt()
                .clamp(1.0 / MAX_GAIN, MAX_GAIN);
            shape += outer(carried * (gain - 1.0), r);
        }
        if !shape.is_finite() {
            return ShapeCorrection::default();
        }
        ShapeCorrection {
            linear: (shape - m) * w,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rigid motion corrects nothing; a bend about the middle corrects the middle blob, and
    /// the carried-only deformation is the plain carry.
    #[test]
    fn a_rigid_motion_is_left_and_a_bend_is_reshaped() {
        let (blobs, rest) = super::super::tests::capsule();
        let turn = DMat3::from_axis_angle(DVec3::new(0.3, 1.0, -0.2).normalize(), 0.9);
        let rigid: Vec<DVec3> = rest.iter().map(|&p| turn * p + DVec3::X).collect();
        // A kink: the upper half folds over by 100° about the middle (as the A, B refit's test).
        let fold = DMat3::from_rotation_z(100f64.to_radians());
        let bent: Vec<DVec3> = rest
            .iter()
            .map(|&p| if p.y > 0.0 { fold * p } else { p })
            .collect();
        let frames = [rest.clone(), rigid, bent];
        let d = Deformation::with_shape_refit(
            &blobs,
            &frames,
            &[0.0, 1.0, 2.0],
            &RefitConfig::default(),
        );
        let plain = Deformation::new(&blobs, &frames, &[0.0, 1.0, 2.0]);
        assert_eq!(d.carried_only(), plain);
        let (mut a, mut b) = (blobs.clone(), blobs.clone());
        d.apply(&mut a, 1.0);
        plain.apply(&mut b, 1.0);
        assert_eq!(a, b, "a rigid motion is carried only");
        assert!(d.shape_refitted() > 0, "the bend leaves some blob's map");
        let (mut a, mut b) = (blobs.clone(), blobs.clone());
        d.apply(&mut a, 2.0);
        plain.apply(&mut b, 2.0);
        assert_ne!(a, b, "the bend reshapes some blob");
        for (x, y) in a.iter().zip(&b) {
            assert_eq!(x.center, y.center, "the centre is the carry's");
            let ratio = x.semi_axes / y.semi_axes;
            assert!(
                ratio.min_element() >= 1.0 / MAX_GAIN - 1e-9
                    && ratio.max_element() <= MAX_GAIN + 1e-9,
                "{ratio}"
            );
        }
    }
}
