//! Blob optimisation after decomposition; [`optimise`] is the one entry a fit calls (see
//! docs/ARCHITECTURE.md, "Optimisation").
//!
//! Full optimisation (beyond the paper): every blob parameter — centre, rotation,
//! influence radii and `B` — on a geometric residual `F/|∇F|` at surface samples, plus one-sided
//! sign constraints just inside (`F > 0`) and outside (`F < 0`) the surface so that no spurious
//! surface appears away from the mesh.
//!
//! Solver: block-coordinate Levenberg–Marquardt. One blob's 10 parameters against the points
//! inside its support form a 10×10 normal system; blobs whose support boxes do not overlap are
//! updated in parallel (greedy colouring, so the result does not depend on the thread count);
//! `|∇F|` is held fixed within a sweep. A sweep may be restricted to some blobs (the
//! adaptive budget re-fits only around the blobs it adds).
//!
//! Files: `steps` is the entry (faithful pass, full problem, dead-blob drop, adaptive budget,
//! final sweeps, swap rounds, negligible drop, in that order), `points` builds what is fitted,
//! `params` is one blob's parametrisation and Jacobian, `sparsity` says which points each blob
//! touches and which blobs can move together, `budget` adds blobs where the model falls short,
//! `swap` moves the least useful blobs of a small model there, `config` holds the settings.
//!
//! Parametrisation: the field of a blob depends only on its influence radii `r = s·√(1+A)`:
//! `f = B²(1 − |diag(1/r)·Rᵀ(x−c)|²)²`, so `A` is kept fixed and `s` is moved with `r`.

mod budget;
mod config;
mod params;
mod points;
mod sparsity;
mod steps;
mod swap;

pub use budget::{Budget, NEGLIGIBLE, Placement, drop_negligible};
pub use config::FullConfig;
pub use points::far_field_points;
pub use steps::{Optimisation, Optimised, Start, Target, optimise};

use glam::DVec3;
use rayon::prelude::*;

use super::{Blob, BlobField};
use crate::mesh::sample::SurfaceSamples;
use crate::mesh::winding::WindingNumber;
use params::{Eval, Params};
use points::{Kind, Points, constraint_points};
use sparsity::{colour, incidence, points_within};

/// What happened during a full optimisation.
#[derive(Clone, Debug, Default)]
pub struct FullReport {
    /// RMS of `F/|∇F|` at the surface samples before, as a fraction of `D`.
    pub rms_before: f64,
    /// The same after.
    pub rms_after: f64,
}

/// Residual of one point given its field value `F`, and its derivative `dr/dF`.
#[inline]
fn residual(kind: Kind, big_f: f64, inv_g: f64, cfg: &FullConfig) -> (f64, f64) {
    let w = cfg.constraint_weight * inv_g;
    match kind {
        Kind::Surface => (big_f * inv_g, inv_g),
        Kind::Inside if big_f < cfg.margin => ((big_f - cfg.margin) * w, w),
        Kind::Outside if big_f > -cfg.margin => ((big_f + cfg.margin) * w, w),
        _ => (0.0, 0.0),
    }
}

/// Solve the 10×10 symmetric system `(H + λ·diag(H) + ε) d = −g` by Cholesky; `None` if singular.
fn solve_damped(h: &[[f64; 10]; 10], g: &[f64; 10], lambda: f64) -> Option<[f64; 10]> {
    let mut a = *h;
    for (k, row) in a.iter_mut().enumerate() {
        row[k] += lambda * h[k][k] + 1e-9;
    }
    // In-place Cholesky: a = L Lᵀ.
    for j in 0..10 {
        let mut d = a[j][j];
        for k in 0..j {
            d -= a[j][k] * a[j][k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..10 {
            let mut s = a[i][j];
            for k in 0..j {
                s -= a[i][k] * a[j][k];
            }
            a[i][j] = s / d;
        }
    }
    let mut y = [0.0; 10];
    for i in 0..10 {
        let mut s = -g[i];
        for k in 0..i {
            s -= a[i][k] * y[k];
        }
        y[i] = s / a[i][i];
    }
    let mut x = [0.0; 10];
    for i in (0..10).rev() {
        let mut s = y[i];
        for k in i + 1..10 {
            s -= a[k][i] * x[k];
        }
        x[i] = s / a[i][i];
    }
    Some(x)
}

/// Points per chunk of a blob's sums. The chunks of one blob run in parallel (a big blob alone
/// in its colour still uses every core) and their partial sums are added in order, so results do
/// not depend on the thread count.
const CHUNK: usize = 1024;

/// `part` of each chunk of `0..n`, in order.
fn chunked<T: Send>(n: usize, part: impl Fn(std::ops::Range<usize>) -> T + Sync) -> Vec<T> {
    (0..n.div_ceil(CHUNK))
        .into_par_iter()
        .map(|c| part(c * CHUNK..((c + 1) * CHUNK).min(n)))
        .collect()
}

/// Shared, read-only state of one sweep.
struct Sweep<'a> {
    cfg: &'a FullConfig,
    pts: &'a Points,
    sums: &'a [f64],
    inv_g: &'a [f64],
    threshold: f64,
    scale: f64,
    shape_prior: f64,
}

impl Sweep<'_> {
    /// LM on one blob against the points `idx`; returns the improved parameters.
    fn improve(&self, p0: Params, anchor: &Params, idx: &[u32]) -> Params {
        let e0 = Eval::new(&p0);
        // Shape prior: a blob's radii and centre stay near where the decomposition put them
        // (in units of its mean radius), weighted like `idx.len()` points `shape_prior·D` off.
        // Without it, weak blobs stretch into long tails that add up to spurious surface.
        let w = self.shape_prior * self.scale * (idx.len() as f64).sqrt();
        let r0 = anchor.log_r.exp().element_sum() / 3.0;
        let prior = |p: &Params| -> [f64; 6] {
            let dc = (p.c - anchor.c) / r0;
            let dr = p.log_r - anchor.log_r;
            [dc.x, dc.y, dc.z, dr.x, dr.y, dr.z].map(|v| v * w)
        };
        // F without this blob, per incident point, and the starting cost's chunk sums in the
        // same pass (the same chunks and order as `cost`, so the same bits).
        let start: Vec<(Vec<f64>, f64)> = chunked(idx.len(), |range| {
            let mut sum = 0.0;
            let rest = idx[range]
                .iter()
                .map(|&k| {
                    let k = k as usize;
                    let own = e0.value(self.pts.x[k]);
                    let r = self.sums[k] - self.threshold - own;
                    let (res, _) = residual(self.pts.kind[k], r + own, self.inv_g[k], self.cfg);
                    sum += res * res;
                    r
                })
                .collect();
            (rest, sum)
        });
        let rest: Vec<f64> = start.iter().flat_map(|c| c.0.iter().copied()).collect();
        let cost = |p: &Params| -> f64 {
            let e = Eval::new(p);
            let parts = chunked(idx.len(), |range| {
                let mut sum = 0.0;
                for (&k, &r) in idx[range.clone()].iter().zip(&rest[range]) {
                    let k = k as usize;
                    let big_f = r + e.value(self.pts.x[k]);
                    let (res, _) = residual(self.pts.kind[k], big_f, self.inv_g[k], self.cfg);
                    sum += res * res;
                }
                sum
            });
            parts.iter().sum::<f64>() + prior(p).iter().map(|v| v * v).sum::<f64>()
        };
        let mut p = p0;
        let mut c =
            start.iter().map(|c| c.1).sum::<f64>() + prior(&p).iter().map(|v| v * v).sum::<f64>();
        let mut lambda = 1e-3;
        for _ in 0..self.cfg.iterations {
            let e = Eval::new(&p);
            let parts = chunked(idx.len(), |range| {
                let (mut h, mut g) = ([[0.0; 10]; 10], [0.0; 10]);
                for (&k, &r) in idx[range.clone()].iter().zip(&rest[range]) {
                    let k = k as usize;
                    let (f, jf) = e.value_and_jacobian(self.pts.x[k], self.scale);
                    let (res, dres) = residual(self.pts.kind[k], r + f, self.inv_g[k], self.cfg);
                    if dres == 0.0 {
                        continue;
                    }
                    let j: [f64; 10] = std::array::from_fn(|a| jf[a] * dres);
                    for a in 0..10 {
                        g[a] += j[a] * res;
                        for b in 0..=a {
                            h[a][b] += j[a] * j[b];
                        }
                    }
                }
                (h, g)
            });
            let (mut h, mut g) = ([[0.0; 10]; 10], [0.0; 10]);
            for (ph, pg) in &parts {
                for a in 0..10 {
                    g[a] += pg[a];
                    for b in 0..=a {
                        h[a][b] += ph[a][b];
                    }
                }
            }
            // Prior residuals: d(centre)/d(step) = scale, d(log r)/d(step) = 1.
            let pr = prior(&p);
            for k in 0..3 {
                let jc = w * self.scale / r0;
                g[k] += jc * pr[k];
                h[k][k] += jc * jc;
                g[6 + k] += w * pr[3 + k];
                h[6 + k][6 + k] += w * w;
            }
            for a in 0..10 {
                for b in 0..a {
                    h[b][a] = h[a][b];
                }
            }
            let mut accepted = false;
            for _ in 0..4 {
                let Some(mut d) = solve_damped(&h, &g, lambda) else {
                    lambda *= 10.0;
                    continue;
                };
                // Trust region: bounded moves per iteration.
                for (a, v) in d.iter_mut().enumerate() {
                    let cap = if a < 3 { 0.05 } else { 0.3 };
                    *v = v.clamp(-cap, cap);
                }
                let trial = p.stepped(&d, self.scale);
                let ct = cost(&trial);
                if ct < c {
                    (p, c) = (trial, ct);
                    lambda = (lambda * 0.3).max(1e-7);
                    accepted = true;
                    break;
                }
                lambda *= 8.0;
            }
            if !accepted {
                break;
            }
        }
        p
    }
}

/// `1/|∇F|` for the geometric residual `F/|∇F|`, the gradient floored so the residual never
/// explodes where the field is flat: typical `|∇F|` on the surface of a blob of radius ~D/20 is
/// ~2·B·…; the floor bounds the residual by about 10 % of D per unit of `F`.
#[inline]
fn inverse_gradient(g: DVec3, diag: f64) -> f64 {
    1.0 / g.length().max(10.0 / diag)
}

/// The blobs' summed field (before the threshold) and [`inverse_gradient`] at every point.
fn sums_and_inverse_gradients(field: &BlobField, pts: &Points, diag: f64) -> (Vec<f64>, Vec<f64>) {
    pts.x
        .par_iter()
        .map(|&x| {
            let (f, g) = field.value_and_gradient(x);
            (f + field.threshold(), inverse_gradient(g, diag))
        })
        .unzip()
}

/// RMS of `F/|∇F|` over the surface points, as a fraction of `diag`.
fn surface_rms(field: &BlobField, pts: &Points, diag: f64) -> f64 {
    let (s, n) = pts
        .x
        .par_iter()
        .zip(&pts.kind)
        .filter(|(_, k)| **k == Kind::Surface)
        .map(|(&x, _)| {
            let (f, g) = field.value_and_gradient(x);
            let d = f * inverse_gradient(g, diag);
            (d * d, 1usize)
        })
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    (s / n.max(1) as f64).sqrt() / diag
}

/// The full optimisation's problem: the constraint points of one mesh, built once and reused by
/// every pass over the blobs.
pub struct FullProblem<'a> {
    cfg: &'a FullConfig,
    pts: Points,
    diag: f64,
    threshold: f64,
}

impl<'a> FullProblem<'a> {
    /// Surface samples, their offset sign constraints (kept on their side of the winding
    /// number `solid` when given) and the far-field points `far` (see [`far_field_points`]) of
    /// a mesh with bounding-box diagonal `diag`.
    pub fn new(
        cfg: &'a FullConfig,
        samples: &SurfaceSamples,
        solid: Option<&WindingNumber>,
        far: &[(DVec3, bool)],
        diag: f64,
        threshold: f64,
    ) -> FullProblem<'a> {
        FullProblem {
            cfg,
            pts: constraint_points(cfg, samples, solid, far, diag),
            diag,
            threshold,
        }
    }

    /// Run `sweeps` sweeps over the blobs flagged in `active` (every blob when `None`), in
    /// place. `anchors[i]` is where blob `i`'s shape prior, of strength `shape_prior` (see
    /// [`FullConfig::shape_prior`]), holds it (its decomposition ellipsoid). Deterministic at
    /// any thread count.
    pub fn optimise(
        &self,
        blobs: &mut [Blob],
        anchors: &[Blob],
        sweeps: usize,
        active: Option<&[bool]>,
        shape_prior: f64,
    ) {
        let (cfg, threshold, diag) = (self.cfg, self.threshold, self.diag);
        // Only the points some active blob reaches take part.
        let pts = active.map(|mask| points_within(&self.pts, &supports_of(blobs, mask)));
        let pts = pts.as_ref().unwrap_or(&self.pts);
        let anchors: Vec<Params> = anchors.iter().map(Params::from_blob).collect();
        for _ in 0..sweeps {
            let field = BlobField::new(blobs, threshold);
            let (mut sums, inv_g) = sums_and_inverse_gradients(&field, pts, diag);
            let (start, entries) = incidence(blobs, active, pts);
            let groups = colour(blobs, &start);
            for group in groups {
                let updated: Vec<(usize, Params)> = {
                    let sweep_state = Sweep {
                        cfg,
                        pts,
                        sums: &sums,
                        inv_g: &inv_g,
                        threshold,
                        scale: diag,
                        shape_prior,
                    };
                    group
                        .par_iter()
                        .filter(|&&i| blobs[i].is_live() && start[i + 1] > start[i])
                        .map(|&i| {
                            (
                                i,
                                sweep_state.improve(
                                    Params::from_blob(&blobs[i]),
                                    &anchors[i],
                                    &entries[start[i]..start[i + 1]],
                                ),
                            )
                        })
                        .collect()
                };
                for (i, p) in updated {
                    let old = Eval::new(&Params::from_blob(&blobs[i]));
                    let new = Eval::new(&p);
                    for &k in &entries[start[i]..start[i + 1]] {
                        let x = pts.x[k as usize];
                        sums[k as usize] += new.value(x) - old.value(x);
                    }
                    blobs[i] = p.to_blob(blobs[i].a);
                }
            }
        }
    }
}

/// The live blobs flagged in `mask` (the others switched off), for support queries.
fn supports_of(blobs: &[Blob], mask: &[bool]) -> Vec<Blob> {
    blobs
        .iter()
        .zip(mask)
        .map(|(b, &on)| Blob {
            b: if on { b.b } else { 0.0 },
            ..*b
        })
        .collect()
}

/// Optimise every parameter of every blob in place for `cfg.sweeps` sweeps, the prior holding
/// each blob near where it starts, against samples without a mesh (no winding-number check of
/// the offset points). Deterministic at any thread count.
pub fn optimise_full(
    cfg: &FullConfig,
    blobs: &mut [Blob],
    samples: &SurfaceSamples,
    far: &[(DVec3, bool)],
    diag: f64,
    threshold: f64,
) -> FullReport {
    let anchors = blobs.to_vec();
    let problem = FullProblem::new(cfg, samples, None, far, diag, threshold);
    let rms_before = surface_rms(&BlobField::new(blobs, threshold), &problem.pts, diag);
    problem.optimise(blobs, &anchors, cfg.sweeps, None, cfg.shape_prior);
    FullReport {
        rms_before,
        rms_after: surface_rms(&BlobField::new(blobs, threshold), &problem.pts, diag),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    /// `m` samples of the unit sphere (a Fibonacci spiral) with their normals.
    pub(super) fn unit_sphere_samples(m: usize) -> SurfaceSamples {
        let mut s = SurfaceSamples::default();
        for i in 0..m {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / m as f64;
            let t = i as f64 * 2.399963;
            let r = (1.0 - z * z).sqrt();
            let n = DVec3::new(r * t.cos(), r * t.sin(), z);
            s.positions.push(n);
            s.normals.push(n);
            s.mean_curvature.push(1.0);
        }
        s
    }

    #[test]
    fn fits_a_sphere_from_a_poor_start() {
        // Samples of the unit sphere; one blob started off-centre, squashed and too weak.
        let s = unit_sphere_samples(2000);
        let mut blobs = vec![Blob {
            center: DVec3::new(0.1, -0.05, 0.0),
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::new(1.0, 0.8, 1.1),
            a: 1.0,
            b: 2.0,
        }];
        let cfg = FullConfig {
            sweeps: 8,
            iterations: 4,
            max_points: 10_000,
            ..FullConfig::default()
        };
        let report = optimise_full(&cfg, &mut blobs, &s, &[], 2.0 * 3f64.sqrt(), 1.0);
        assert!(report.rms_after < 0.2 * report.rms_before, "{report:?}");
        assert!(report.rms_after < 1e-3, "{report:?}");
    }
}
