//! The local refit of a carried blob's `A` and `B` where the deforming surface leaves it
//! (issue 51, item 3: "refitted only where the shape leaves the blobs").
//!
//! **Where.** A blob is refitted on a frame of the sequence when its anchors leave their
//! affine map ([`Deformation::residual`], the weighted RMS distance) by more than
//! [`RefitConfig::from`] of the blob's smallest rest semi-axis, fully from [`RefitConfig::full`]
//! on, with a smoothstep weight between: a blob the surface carries affinely keeps its fitted
//! `A`, `B` bit for bit, and one the surface starts to leave eases into its refit.
//!
//! **How.** The paper's per-blob solve, the one the fit itself runs
//! ([`crate::blobby::fit::solve_blob`]: Nelder–Mead on `(A, B)` over a sum of squares of the
//! field at surface samples), over the blob's surface samples — the rest vertices inside its
//! widest support (`A = a_max`), at most [`MAX_SAMPLES`], the nearest kept; at least
//! [`MIN_SAMPLES`] of them inside it in the frame — at their positions in the frame, the other
//! blobs carried to the frame and held (each refitted blob is solved against the others as
//! carried, so the result does not depend on an order), from the blob's fitted `A`, `B`. What
//! it fits is the field each sample had at rest, `F_t(p'_k) = F_rest(p_k)`, not `F = 0`: the
//! fit's own residual at a sample (the full optimisation's choice, not the faithful solve's) is
//! kept, so a blob is changed only by how the surface moved around it — a rigid or affine
//! motion, which leaves every sample's `ρ²` and field as at rest, changes nothing. The result
//! is kept as factors of the fitted `A`, `B` (so a blob still flying in or growing is scaled
//! alike), per frame of the sequence, read linear between frames, so nothing pops.
//!
//! **Cost.** Once per frame of the sequence when the deformation is made (in parallel over
//! frames, each frame's solves in blob order: deterministic at any thread count); a frame then
//! only reads two factors per blob.
//!
//! **Measured, not used by shots**: it lost silhouette IoU on the builtin waving tube and on a
//! bend that stretches (docs/MEASUREMENTS.md, "Bending"), so `scene::shot` carries the blobs
//! only; kept for the measurement (`tests/it/deform.rs`) and as the start of a shape refit.

use glam::DVec3;
use rayon::prelude::*;

use super::{Deformation, VertexGrid};
use crate::blobby::fit::{FaithfulConfig, solve_blob};
use crate::blobby::{Blob, BlobField};

/// Most surface samples of a blob's refit (the nearest rest vertices are kept).
pub const MAX_SAMPLES: usize = 256;
/// The most a refit changes a blob's `A` or `B`: by this factor either way.
pub const MAX_CHANGE: f64 = 1.5;
/// Fewest surface samples inside a blob's support for its refit (fewer do not hold the
/// solve's two parameters: the blob is carried only).
pub const MIN_SAMPLES: usize = 12;

/// Where and how blobs are refitted.
#[derive(Clone, Debug)]
pub struct RefitConfig {
    /// The anchors' distance from their affine map, over the blob's smallest rest semi-axis,
    /// at which the refit starts.
    pub from: f64,
    /// …and from which it applies in full.
    pub full: f64,
    /// The per-blob solve's settings (the fit's faithful ones).
    pub faithful: FaithfulConfig,
    /// The field's iso-level `t`.
    pub threshold: f64,
}

impl Default for RefitConfig {
    fn default() -> Self {
        RefitConfig {
            from: 0.1,
            full: 0.2,
            faithful: FaithfulConfig::default(),
            threshold: crate::blobby::THRESHOLD,
        }
    }
}

/// What the refit did over the sequence (for the shot's report and the measurements).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefitSummary {
    /// (blob, frame) pairs refitted (weight > 0).
    pub refitted: usize,
    /// (blob, frame) pairs looked at (live blobs × frames).
    pub considered: usize,
    /// The smallest and largest factor of `A`.
    pub a_range: [f64; 2],
    /// The smallest and largest factor of `B`.
    pub b_range: [f64; 2],
}

/// The per-frame, per-blob factors of `A` and `B` of `d`'s blobs (`formed` at rest, anchored
/// in `d`) on the mesh `frames` (the ones `d` was made from), and a summary. Empty when no blob
/// is refitted on any frame.
pub(super) fn factors(
    d: &Deformation,
    formed: &[Blob],
    frames: &[Vec<DVec3>],
    cfg: &RefitConfig,
) -> (Vec<Vec<[f64; 2]>>, RefitSummary) {
    let rest = &frames[0];
    let mut summary = RefitSummary {
        a_range: [1.0, 1.0],
        b_range: [1.0, 1.0],
        ..RefitSummary::default()
    };
    if formed.is_empty() || rest.is_empty() {
        return (Vec::new(), summary);
    }
    let grid = VertexGrid::new(rest);
    let reach = (1.0 + cfg.faithful.a_max).sqrt();
    let mut near = Vec::new();
    let samples: Vec<Vec<u32>> = formed
        .iter()
        .map(|b| {
            if !b.is_live() {
                return Vec::new();
            }
            let r = reach * b.semi_axes.max_element();
            grid.nearest(rest, b.center, r, MAX_SAMPLES, &mut near);
            near.iter().map(|&(_, v)| v).collect()
        })
        .collect();
    // The field each sample has at rest (the fitted model's residual there).
    let field = BlobField::new(formed, cfg.threshold);
    let targets: Vec<Vec<f64>> = samples
        .iter()
        .map(|list| {
            list.iter()
                .map(|&v| field.value(rest[v as usize]))
                .collect()
        })
        .collect();
    let live: Vec<bool> = formed
        .iter()
        .zip(&samples)
        .map(|(b, list)| b.is_live() && b.a > 0.0 && list.len() >= MIN_SAMPLES)
        .collect();
    let per_frame: Vec<Option<Vec<[f64; 2]>>> = (0..frames.len())
        .into_par_iter()
        .map(|f| {
            let weights: Vec<f64> = formed
                .iter()
                .enumerate()
                .map(|(i, b)| {
                    if !live[i] {
                        return 0.0;
                    }
                    let leave = d.residual_between(i, f, f, 0.0) / b.semi_axes.min_element();
                    weight(leave, cfg)
                })
                .collect();
            let chosen: Vec<usize> = (0..formed.len()).filter(|&i| weights[i] > 0.0).collect();
            if chosen.is_empty() {
                return None;
            }
            let mut carried = formed.to_vec();
            for (i, b) in carried.iter_mut().enumerate() {
                d.map_between(i, f, f, 0.0).carry(b);
            }
            let solver = Solver {
                index: widest_index(&carried, cfg),
                blobs: &carried,
                cfg,
            };
            let mut out = vec![[1.0, 1.0]; formed.len()];
            for &i in &chosen {
                if let Some([a, b]) = solver.solve(i, &frames[f], &samples[i], &targets[i]) {
                    let (w, fitted) = (weights[i], &formed[i]);
                    out[i] = [
                        1.0 + w * (a / fitted.a - 1.0),
                        1.0 + w * (b / fitted.b - 1.0),
                    ];
                }
            }
            Some(out)
        })
        .collect();
    summary.considered = frames.len() * live.iter().filter(|&&l| l).count();
    if per_frame.iter().all(Option::is_none) {
        return (Vec::new(), summary);
    }
    let mut out = Vec::with_capacity(frames.len());
    for frame in per_frame {
        let frame = frame.unwrap_or_else(|| vec![[1.0, 1.0]; formed.len()]);
        for k in &frame {
            if *k != [1.0, 1.0] {
                summary.refitted += 1;
            }
            summary.a_range = [summary.a_range[0].min(k[0]), summary.a_range[1].max(k[0])];
            summary.b_range = [summary.b_range[0].min(k[1]), summary.b_range[1].max(k[1])];
        }
        out.push(frame);
    }
    (out, summary)
}

/// The refit's weight of a blob whose anchors leave their affine map by `leave` (a fraction
/// of its smallest semi-axis): 0 up to `from`, 1 from `full` on, smoothstep between.
pub(super) fn weight(leave: f64, cfg: &RefitConfig) -> f64 {
    if !(leave > cfg.from) {
        return 0.0;
    }
    let span = (cfg.full - cfg.from).max(f64::MIN_POSITIVE);
    crate::animate::smoothstep(((leave - cfg.from) / span).min(1.0))
}

/// The blobs' widest supports (`A = a_max`), indexed: which blobs can reach a point.
fn widest_index(blobs: &[Blob], cfg: &RefitConfig) -> BlobField {
    let widest: Vec<Blob> = blobs
        .iter()
        .map(|b| Blob {
            a: cfg.faithful.a_max.max(b.a),
            b: 1.0,
            ..*b
        })
        .collect();
    BlobField::new(&widest, 1.0)
}

/// The faithful solve of a blob of one pose against the others held.
struct Solver<'a> {
    blobs: &'a [Blob],
    /// [`widest_index`] of the blobs.
    index: BlobField,
    cfg: &'a RefitConfig,
}

impl Solver<'_> {
    /// `[A, B]` of blob `i` from its fitted ones, fitting the field at its `samples` (vertex
    /// indices into `positions`) to `targets` (each sample's field at rest); `None` when fewer
    /// than [`MIN_SAMPLES`] are inside its widest support or the solve switches it off.
    fn solve(
        &self,
        i: usize,
        positions: &[DVec3],
        samples: &[u32],
        targets: &[f64],
    ) -> Option<[f64; 2]> {
        let blob = &self.blobs[i];
        let e = blob.ellipsoid();
        let support = 1.0 + self.cfg.faithful.a_max;
        let mut pairs: Vec<(f64, f64, u32)> = Vec::with_capacity(samples.len());
        for (&v, &target) in samples.iter().zip(targets) {
            let p = positions[v as usize];
            let rho2 = e.radius_squared(p);
            if !(rho2 < support) {
                continue;
            }
            let others: f64 = self
                .index
                .blobs_near(p)
                .iter()
                .filter(|&&j| j as usize != i)
                .map(|&j| self.blobs[j as usize].value(p))
                .sum();
            pairs.push((rho2, others - self.cfg.threshold - target, v));
        }
        if pairs.len() < MIN_SAMPLES {
            return None;
        }
        pairs.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.2.cmp(&y.2)));
        let q: Vec<f64> = pairs.iter().map(|p| p.0).collect();
        let rest: Vec<f64> = pairs.iter().map(|p| p.1).collect();
        // A refit corrects a fitted blob, it does not replace it: `A` within a factor
        // [`MAX_CHANGE`] of the fitted one, `B` likewise (the samples are surface points only,
        // with no inside/outside constraint to hold a blob that the rest of the field covers).
        let bounded = FaithfulConfig {
            a_min: (blob.a / MAX_CHANGE).max(self.cfg.faithful.a_min),
            a_max: (blob.a * MAX_CHANGE).min(self.cfg.faithful.a_max.max(blob.a)),
            ..self.cfg.faithful.clone()
        };
        let [a, b] = solve_blob(&bounded, &q, &rest, [blob.a, blob.b]);
        let b = b.clamp(blob.b / MAX_CHANGE, blob.b * MAX_CHANGE);
        (a > 0.0 && b > 0.0).then_some([a, b])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    #[test]
    fn a_rigid_motion_is_not_refitted_and_a_bend_is() {
        let (blobs, rest) = super::super::tests::capsule();
        let turn = DMat3::from_axis_angle(DVec3::new(0.3, 1.0, -0.2).normalize(), 0.9);
        let rigid: Vec<DVec3> = rest.iter().map(|&p| turn * p + DVec3::X).collect();
        // A kink: the upper half folds over by 100° about the middle (x = 0, y = 0 line).
        let fold = DMat3::from_rotation_z(100f64.to_radians());
        let bent = folded(&rest, &fold);
        let times = [0.0, 1.0, 2.0];
        let d = Deformation::with_refit(
            &blobs,
            &[rest.clone(), rigid, bent.clone()],
            &times,
            &RefitConfig::default(),
        );
        let summary = d.refit_summary();
        // Rigid: every factor exactly 1 (no blob leaves its map).
        for i in 0..blobs.len() {
            assert_eq!(d.refit_factors(i, 1.0), [1.0, 1.0], "blob {i}");
        }
        // The kink leaves the middle blob's map: it is refitted, and the result is
        // deterministic.
        assert!(d.is_refitted() && summary.refitted > 0, "{summary:?}");
        assert_ne!(d.refit_factors(2, 2.0), [1.0, 1.0]);
        let again = Deformation::with_refit(
            &blobs,
            &[rest.clone(), rest.clone(), bent],
            &times,
            &RefitConfig::default(),
        );
        assert_eq!(again.refit_factors(2, 2.0), d.refit_factors(2, 2.0));
        // Between frames the factors run linearly (no pop).
        let [k1, k2] = [d.refit_factors(2, 1.5), d.refit_factors(2, 2.0)];
        assert!(((k1[0] - 1.0) - 0.5 * (k2[0] - 1.0)).abs() < 1e-12);
        // The carried-only deformation applies none.
        let mut with = blobs.clone();
        let mut without = blobs.clone();
        d.apply(&mut with, 2.0);
        d.carried_only().apply(&mut without, 2.0);
        assert_eq!(with[2].center, without[2].center);
        assert_ne!([with[2].a, with[2].b], [without[2].a, without[2].b]);
    }

    /// `rest` with its upper half (y > 0) turned by `fold` about the origin.
    fn folded(rest: &[DVec3], fold: &DMat3) -> Vec<DVec3> {
        rest.iter()
            .map(|&p| if p.y > 0.0 { *fold * p } else { p })
            .collect()
    }

    #[test]
    fn the_weight_runs_smoothly_from_zero_to_one() {
        let cfg = RefitConfig::default();
        assert_eq!(weight(0.05, &cfg), 0.0);
        assert_eq!(weight(cfg.from, &cfg), 0.0);
        assert_eq!(weight(cfg.full, &cfg), 1.0);
        assert_eq!(weight(5.0, &cfg), 1.0);
        assert_eq!(weight(f64::NAN, &cfg), 0.0);
        let mid = weight(0.5 * (cfg.from + cfg.full), &cfg);
        assert!((mid - 0.5).abs() < 1e-12, "{mid}");
    }
}
