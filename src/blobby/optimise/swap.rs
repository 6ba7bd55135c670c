//! Swap rounds: move the least useful blobs of a small model to where it falls shortest.
//!
//! The greedy selection picks blobs for the volume they cover and the adaptive budget adds
//! blobs at the surface's worst shortfalls; neither revisits a blob once placed. After the
//! final sweeps some blobs do little (a neighbour covers the same surface) while elsewhere the
//! model still stops short of the mesh. A swap round drops the blobs whose removal raises the
//! residual least, adds as many from the unused candidates at the worst shortfalls, re-fits
//! around both and then every blob, and keeps the result only if the total residual fell.

use rayon::prelude::*;

use super::budget::{Budget, Placement, overlapping};
use super::params::{Eval, Params};
use super::sparsity::incidence;
use super::{FullProblem, chunked, residual, sums_and_inverse_gradients};
use crate::blobby::{Blob, BlobField};

impl FullProblem<'_> {
    /// Σ of every point's squared residual (surface and sign constraints, no shape prior),
    /// in units of `D²`. Deterministic at any thread count (fixed chunks, summed in order).
    pub(super) fn cost(&self, blobs: &[Blob]) -> f64 {
        let field = BlobField::new(blobs, self.threshold);
        let (sums, inv_g) = sums_and_inverse_gradients(&field, &self.pts, self.diag);
        let parts = chunked(self.pts.x.len(), |range| {
            range
                .map(|k| {
                    let big_f = sums[k] - self.threshold;
                    let (r, _) = residual(self.pts.kind[k], big_f, inv_g[k], self.cfg);
                    r * r
                })
                .sum::<f64>()
        });
        parts.iter().sum::<f64>() / (self.diag * self.diag)
    }

    /// Per blob, how much [`FullProblem::cost`] rises when that blob alone is removed (the
    /// others and every point's `|∇F|` held): a blob whose neighbours cover its surface costs
    /// little to lose.
    pub(super) fn usefulness(&self, blobs: &[Blob]) -> Vec<f64> {
        let field = BlobField::new(blobs, self.threshold);
        let (sums, inv_g) = sums_and_inverse_gradients(&field, &self.pts, self.diag);
        let (start, entries) = incidence(blobs, None, &self.pts);
        (0..blobs.len())
            .into_par_iter()
            .map(|i| {
                let e = Eval::new(&Params::from_blob(&blobs[i]));
                let mut rise = 0.0;
                for &k in &entries[start[i]..start[i + 1]] {
                    let k = k as usize;
                    let (kind, big_f) = (self.pts.kind[k], sums[k] - self.threshold);
                    let (with, _) = residual(kind, big_f, inv_g[k], self.cfg);
                    let without = big_f - e.value(self.pts.x[k]);
                    let (without, _) = residual(kind, without, inv_g[k], self.cfg);
                    rise += without * without - with * with;
                }
                rise
            })
            .collect()
    }
}

impl Budget<'_> {
    /// Run up to `cfg.swap_rounds` swap rounds of `cfg.swap_blobs` blobs each (see the module
    /// docs). A dropped blob's candidate stays used, so that a round never undoes the last.
    /// Stops at the first round that does not lower the problem's cost (`FullProblem::cost`),
    /// restoring the blobs from before it.
    pub fn swap(&self, problem: &FullProblem, placed: &mut Placement) {
        let cfg = problem.cfg;
        if cfg.swap_blobs == 0 || placed.blobs.len() <= cfg.swap_blobs {
            return;
        }
        let mut cost = problem.cost(&placed.blobs);
        for _ in 0..cfg.swap_rounds {
            let before = (placed.blobs.clone(), placed.anchors.clone());
            let dropped = drop_least_useful(problem, placed, cfg.swap_blobs);
            let kept = placed.blobs.len();
            self.add_at_shortfalls(problem, placed, cfg.swap_blobs);
            // Re-fit the new blobs and every blob around them or around a dropped one.
            let mut around = placed.blobs.clone();
            around.extend_from_slice(&dropped);
            let active = &overlapping(&around, kept)[..placed.blobs.len()];
            let (blobs, anchors) = (&mut placed.blobs, &placed.anchors);
            let prior = cfg.final_shape_prior;
            problem.optimise(blobs, anchors, cfg.swap_sweeps, Some(active), prior);
            problem.optimise(blobs, anchors, cfg.swap_sweeps, None, prior);
            let after = problem.cost(blobs);
            if !(after < cost) {
                (placed.blobs, placed.anchors) = before;
                return;
            }
            cost = after;
        }
    }
}

/// Remove the `count` blobs of least [`FullProblem::usefulness`] (ties by index) and their
/// anchors, keeping the order of the rest; returns the removed blobs.
fn drop_least_useful(problem: &FullProblem, placed: &mut Placement, count: usize) -> Vec<Blob> {
    let useful = problem.usefulness(&placed.blobs);
    let mut order: Vec<usize> = (0..useful.len()).collect();
    order.sort_by(|&a, &b| useful[a].total_cmp(&useful[b]).then(a.cmp(&b)));
    let mut keep = vec![true; useful.len()];
    for &i in order.iter().take(count) {
        keep[i] = false;
    }
    let dropped = placed
        .blobs
        .iter()
        .zip(&keep)
        .filter(|(_, k)| !**k)
        .map(|(b, _)| *b)
        .collect();
    placed.retain(&keep);
    dropped
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blobby::optimise::FullConfig;
    use crate::blobby::optimise::tests::unit_sphere_samples;
    use crate::geometry::Ellipsoid;
    use glam::{DQuat, DVec3};

    fn sphere_blob(c: DVec3, r: f64) -> Blob {
        let e = Ellipsoid {
            center: c,
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
        };
        Blob::from_ellipsoid(&e, 1.0)
    }

    #[test]
    fn the_blob_no_point_needs_is_the_least_useful_and_goes_first() {
        let samples = unit_sphere_samples(2000);
        let cfg = FullConfig::default();
        let problem = FullProblem::new(&cfg, &samples, None, &[], 2.0 * 3f64.sqrt(), 1.0);
        // The sphere's own blob, a small one deep inside it (no point in its support) and one
        // bulging out of its side.
        let blobs = vec![
            sphere_blob(DVec3::ZERO, 1.0),
            sphere_blob(DVec3::ZERO, 0.05),
            sphere_blob(DVec3::new(0.9, 0.0, 0.0), 0.3),
        ];
        let blobs_before = blobs.clone();
        let useful = problem.usefulness(&blobs);
        assert_eq!(useful[1], 0.0, "{useful:?}");
        assert!(useful[0] > 0.0, "losing the sphere costs: {useful:?}");
        assert!(useful[2] < 0.0, "losing the bulge gains: {useful:?}");
        let sphere = blobs[0];
        let mut placed = Placement {
            anchors: blobs.clone(),
            blobs,
            used: Vec::new(),
        };
        let dropped = drop_least_useful(&problem, &mut placed, 2);
        assert_eq!(dropped, blobs_before[1..], "in model order");
        assert_eq!(placed.blobs, [sphere]);
        assert_eq!(placed.anchors, [sphere]);
    }
}
