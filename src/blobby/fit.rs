//! Paper-faithful blob optimisation (paper §4.2): centres and shapes fixed; for each blob in
//! turn, Nelder–Mead (downhill simplex) on `(A_i, B_i)` minimising `(1/m) Σ_p F(p)²` over the
//! surface samples; a few sweeps.
//!
//! Only samples inside a blob's largest allowed support (`A = a_max`) can change with that blob,
//! and in its local frame each sample reduces to its squared ellipsoidal radius `q = ρ²`. With
//! the pairs `(q, rest)` sorted by `q`, the blob's cost is a polynomial in `B²` and `1/(1+A)`
//! whose coefficients are prefix sums of `rest·qʲ` and `qʲ` up to `q < 1 + A`: one objective
//! evaluation is a binary search ([`SortedCost`]), not a loop over thousands of samples.

use glam::DVec3;
use rayon::prelude::*;

use super::{Blob, BlobField};

/// Settings of the faithful optimisation.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FaithfulConfig {
    /// Gauss–Seidel sweeps over all blobs (paper: 3).
    pub sweeps: usize,
    /// Lower bound of `A`.
    pub a_min: f64,
    /// Upper bound of `A` (bounds the support, and so the samples a blob can touch).
    pub a_max: f64,
    /// Objective evaluations per blob per sweep.
    pub max_evals: usize,
}

impl Default for FaithfulConfig {
    fn default() -> Self {
        FaithfulConfig {
            sweeps: 3,
            a_min: 0.05,
            a_max: 4.0,
            max_evals: 150,
        }
    }
}

/// `(1/m) Σ F(p)²` over `samples`.
pub fn objective(field: &BlobField, samples: &[DVec3]) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    let s: f64 = samples
        .par_iter()
        .map(|&p| {
            let f = field.value(p);
            f * f
        })
        .sum();
    s / samples.len() as f64
}

/// For each blob, the samples inside its largest allowed support with their `ρ²`, as CSR.
struct Neighbourhoods {
    start: Vec<usize>,
    sample: Vec<u32>,
    rho2: Vec<f64>,
}

fn neighbourhoods(blobs: &[Blob], samples: &[DVec3], a_max: f64) -> Neighbourhoods {
    let widest: Vec<Blob> = blobs
        .iter()
        .map(|b| Blob {
            a: a_max,
            b: 1.0,
            ..*b
        })
        .collect();
    let index = BlobField::new(&widest, 1.0);
    // Per sample: the blobs whose widest support contains it, with ρ².
    let per_sample: Vec<Vec<(u32, f64)>> = samples
        .par_iter()
        .map(|&p| {
            index
                .blobs_near(p)
                .iter()
                .filter_map(|&i| {
                    let q = blobs[i as usize].ellipsoid().radius_squared(p);
                    (q < 1.0 + a_max).then_some((i, q))
                })
                .collect()
        })
        .collect();
    let mut counts = vec![0usize; blobs.len() + 1];
    for list in &per_sample {
        for &(i, _) in list {
            counts[i as usize + 1] += 1;
        }
    }
    for i in 0..blobs.len() {
        counts[i + 1] += counts[i];
    }
    let mut fill = counts.clone();
    let total = counts[blobs.len()];
    let mut pairs = vec![(0.0f64, 0u32); total];
    for (p, list) in per_sample.iter().enumerate() {
        for &(i, q) in list {
            let k = &mut fill[i as usize];
            pairs[*k] = (q, p as u32);
            *k += 1;
        }
    }
    // Each blob's samples by increasing ρ² (ties by sample index: a total order).
    let mut segments = Vec::with_capacity(blobs.len());
    let mut rest = pairs.as_mut_slice();
    for i in 0..blobs.len() {
        let (head, tail) = rest.split_at_mut(counts[i + 1] - counts[i]);
        segments.push(head);
        rest = tail;
    }
    segments
        .into_par_iter()
        .for_each(|seg| seg.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1))));
    Neighbourhoods {
        start: counts,
        sample: pairs.iter().map(|p| p.1).collect(),
        rho2: pairs.iter().map(|p| p.0).collect(),
    }
}

/// `Σ_k (r_k + B²·(1 − q_k/(1+A))₊²)²` over pairs sorted by `q`, in O(log n) per evaluation.
///
/// For `s = 1 + A` only the prefix `q < s` has a blob term; expanding `u = 1 − q/s`,
/// `Σ (r + B²u²)² = Σ r² + 2B²(R₀ − 2R₁/s + R₂/s²) + B⁴(P₀ − 4P₁/s + 6P₂/s² − 4P₃/s³ + P₄/s⁴)`
/// with prefix sums `Rⱼ = Σ r qʲ`, `Pⱼ = Σ qʲ`, plus `Σ r²` over all pairs.
pub struct SortedCost<'a> {
    q: &'a [f64],
    /// Prefix sums, entry `k` over the first `k` pairs: `[R0, R1, R2, P0, P1, P2, P3, P4]`.
    prefix: Vec<[f64; 8]>,
    r2: f64,
}

impl<'a> SortedCost<'a> {
    /// From `q` sorted ascending and the matching `rest` values.
    pub fn new(q: &'a [f64], rest: &[f64]) -> SortedCost<'a> {
        let mut prefix = Vec::with_capacity(q.len() + 1);
        let mut acc = [0.0f64; 8];
        prefix.push(acc);
        for (&q, &r) in q.iter().zip(rest) {
            let q2 = q * q;
            let terms = [r, r * q, r * q2, 1.0, q, q2, q2 * q, q2 * q2];
            for (a, t) in acc.iter_mut().zip(terms) {
                *a += t;
            }
            prefix.push(acc);
        }
        SortedCost {
            q,
            prefix,
            r2: rest.iter().map(|r| r * r).sum(),
        }
    }

    /// The cost at `A = a`, `B = b` (`a > −1`).
    pub fn eval(&self, a: f64, b: f64) -> f64 {
        let s = 1.0 + a;
        let k = self.q.partition_point(|&q| q < s);
        let [r0, r1, r2, p0, p1, p2, p3, p4] = self.prefix[k];
        let t = 1.0 / s;
        let ru2 = r0 - t * (2.0 * r1 - t * r2);
        let u4 = p0 - t * (4.0 * p1 - t * (6.0 * p2 - t * (4.0 * p3 - t * p4)));
        let b2 = b * b;
        self.r2 + 2.0 * b2 * ru2 + b2 * b2 * u4.max(0.0)
    }
}

#[inline]
fn blob_term(q: f64, a: f64, b: f64) -> f64 {
    let u = q / (1.0 + a);
    if u < 1.0 {
        let k = 1.0 - u;
        b * b * k * k
    } else {
        0.0
    }
}

/// Optimise `A`, `B` of every blob in place (selection order, Gauss–Seidel); returns the
/// objective `(1/m) Σ F(p)²` before and after. Deterministic (sequential over blobs).
pub fn optimise_faithful(
    cfg: &FaithfulConfig,
    blobs: &mut [Blob],
    samples: &[DVec3],
    threshold: f64,
) -> (f64, f64) {
    let before = objective(&BlobField::new(blobs, threshold), samples);
    if samples.is_empty() || blobs.is_empty() {
        return (before, before);
    }
    let hood = neighbourhoods(blobs, samples, cfg.a_max);
    // sums[p] = Σ_i f_i(p) over every blob (all blobs touching p are in the neighbourhoods).
    let mut sums = vec![0.0; samples.len()];
    for (i, blob) in blobs.iter().enumerate() {
        for k in hood.start[i]..hood.start[i + 1] {
            sums[hood.sample[k] as usize] += blob_term(hood.rho2[k], blob.a, blob.b);
        }
    }
    let mut rest = Vec::new();
    for _ in 0..cfg.sweeps {
        for (i, blob) in blobs.iter_mut().enumerate() {
            let range = hood.start[i]..hood.start[i + 1];
            if range.is_empty() {
                continue;
            }
            let q = &hood.rho2[range.clone()];
            rest.clear();
            rest.extend(range.clone().map(|k| {
                sums[hood.sample[k] as usize] - blob_term(hood.rho2[k], blob.a, blob.b) - threshold
            }));
            let [a, b] = solve_blob(cfg, q, &rest, [blob.a, blob.b]);
            blob.a = a;
            blob.b = b;
            for (j, k) in range.enumerate() {
                sums[hood.sample[k] as usize] = rest[j] + threshold + blob_term(q[j], a, b);
            }
        }
    }
    let after = objective(&BlobField::new(blobs, threshold), samples);
    (before, after)
}

/// One blob's faithful solve (paper §4.2): the `[A, B]` minimising `Σ_k (rest_k + f(q_k))²`
/// by Nelder–Mead from `start`, where `q` are the squared ellipsoidal radii `ρ²` of the samples
/// inside the blob's widest support (ascending), `rest` the rest of the field there
/// (`Σ_{j≠i} f_j − t`), and `A` is held in `[a_min, a_max]`. The rule the fit applies to every
/// blob and a deforming target's local refit ([`crate::animate::deform`]) to the blobs the
/// surface leaves.
pub fn solve_blob(cfg: &FaithfulConfig, q: &[f64], rest: &[f64], start: [f64; 2]) -> [f64; 2] {
    let clamp = |x: [f64; 2]| [x[0].clamp(cfg.a_min, cfg.a_max), x[1].abs()];
    let sorted = SortedCost::new(q, rest);
    let cost = |x: [f64; 2]| {
        let [a, b] = clamp(x);
        sorted.eval(a, b)
    };
    clamp(nelder_mead(
        cost,
        start,
        [0.25, 0.25 * start[1].abs().max(0.1)],
        cfg.max_evals,
    ))
}

/// Downhill simplex in two dimensions (Nelder & Mead 1965; standard coefficients 1, 2, ½, ½),
/// from `x0` with initial steps `step`, for at most `max_evals` evaluations. Returns the best point.
pub fn nelder_mead(
    f: impl Fn([f64; 2]) -> f64,
    x0: [f64; 2],
    step: [f64; 2],
    max_evals: usize,
) -> [f64; 2] {
    let add =
        |a: [f64; 2], b: [f64; 2], t: f64| [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
    let mut s = [x0, [x0[0] + step[0], x0[1]], [x0[0], x0[1] + step[1]]];
    let mut v = [f(s[0]), f(s[1]), f(s[2])];
    let mut evals = 3;
    while evals < max_evals {
        // Order: s[0] best, s[2] worst.
        let mut idx = [0, 1, 2];
        idx.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
        s = [s[idx[0]], s[idx[1]], s[idx[2]]];
        v = [v[idx[0]], v[idx[1]], v[idx[2]]];
        if (v[2] - v[0]).abs() <= 1e-12 * (v[0].abs() + 1e-30) {
            break;
        }
        let centroid = [(s[0][0] + s[1][0]) * 0.5, (s[0][1] + s[1][1]) * 0.5];
        let reflected = add(centroid, s[2], -1.0);
        let fr = f(reflected);
        evals += 1;
        if fr < v[0] {
            let expanded = add(centroid, s[2], -2.0);
            let fe = f(expanded);
            evals += 1;
            if fe < fr {
                (s[2], v[2]) = (expanded, fe);
            } else {
                (s[2], v[2]) = (reflected, fr);
            }
        } else if fr < v[1] {
            (s[2], v[2]) = (reflected, fr);
        } else {
            let contracted = if fr < v[2] {
                add(centroid, reflected, 0.5)
            } else {
                add(centroid, s[2], 0.5)
            };
            let fc = f(contracted);
            evals += 1;
            if fc < v[2].min(fr) {
                (s[2], v[2]) = (contracted, fc);
            } else {
                // Shrink toward the best vertex.
                for k in 1..3 {
                    s[k] = add(s[0], s[k], 0.5);
                    v[k] = f(s[k]);
                }
                evals += 2;
            }
        }
    }
    let best = (0..3).min_by(|&a, &b| v[a].total_cmp(&v[b])).unwrap_or(0);
    s[best]
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    #[test]
    fn sorted_cost_matches_the_direct_sum() {
        let mut q: Vec<f64> = (0..3000)
            .map(|i| (i as f64 * 0.618_034).fract() * 5.0)
            .collect();
        q.sort_by(f64::total_cmp);
        let rest: Vec<f64> = (0..3000).map(|i| (i as f64 * 0.37).sin() - 1.0).collect();
        let cost = SortedCost::new(&q, &rest);
        for (a, b) in [(0.05, 0.3), (1.0, 2.0), (2.7, 1.1), (4.0, 0.0), (0.5, 3.5)] {
            let direct: f64 = q
                .iter()
                .zip(&rest)
                .map(|(&q, &r)| (r + blob_term(q, a, b)).powi(2))
                .sum();
            let fast = cost.eval(a, b);
            assert!(
                (fast - direct).abs() < 1e-9 * direct.abs().max(1.0),
                "{a} {b}: {fast} vs {direct}"
            );
        }
    }

    #[test]
    fn nelder_mead_finds_a_quadratic_minimum() {
        let x = nelder_mead(
            |[a, b]| (a - 1.5).powi(2) + 3.0 * (b + 0.5).powi(2) + 0.5 * a * b,
            [0.0, 0.0],
            [0.3, 0.3],
            400,
        );
        // The gradient of the quadratic vanishes at its minimum.
        let g = [
            2.0 * (x[0] - 1.5) + 0.5 * x[1],
            6.0 * (x[1] + 0.5) + 0.5 * x[0],
        ];
        assert!(
            g[0].abs() < 1e-4 && g[1].abs() < 1e-4,
            "{x:?} gradient {g:?}"
        );
    }

    #[test]
    fn overlapping_blobs_are_improved() {
        // Two overlapping spheres: the starting B inflates the overlap; optimisation must
        // bring the objective on the union's surface down.
        let e = |x: f64| crate::geometry::Ellipsoid {
            center: DVec3::new(x, 0.0, 0.0),
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(1.0),
        };
        let mut blobs = vec![
            Blob::from_ellipsoid(&e(-0.3), 1.0),
            Blob::from_ellipsoid(&e(0.3), 1.0),
        ];
        let samples: Vec<DVec3> = (0..400)
            .map(|i| {
                let t = i as f64 * 2.399963;
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / 400.0;
                let r = (1.0 - z * z).sqrt();
                let p = DVec3::new(r * t.cos(), r * t.sin(), z);
                p + DVec3::X * if p.x >= 0.0 { 0.3 } else { -0.3 }
            })
            .collect();
        let (before, after) =
            optimise_faithful(&FaithfulConfig::default(), &mut blobs, &samples, 1.0);
        assert!(after < 0.5 * before, "before {before}, after {after}");
    }
}
