//! Adaptive blob budget: spend the blobs the optimisation switched off where the model falls
//! shortest of the mesh.
//!
//! A surface sample with `F < 0` lies outside the model: the blob surface stops short of the
//! mesh there (a thin tip, a ridge). The remedy is a blob that reaches it, and the
//! decomposition already grew one inscribed ellipsoid per candidate seed; the unused candidate
//! whose surface passes nearest the sample is added, and the optimiser then fits it in.

use glam::DVec3;
use rayon::prelude::*;

use super::{FullProblem, inverse_gradient};
use crate::blobby::{Blob, BlobField};
use crate::geometry::Ellipsoid;

/// Distance from `x` to the ellipsoid's surface along the ray from its centre (exact for a
/// sphere, a close upper bound for a mildly anisotropic ellipsoid; 0 inside).
fn radial_gap(e: &Ellipsoid, x: DVec3) -> f64 {
    let rho = e.radius_squared(x).sqrt();
    if rho <= 1.0 {
        return 0.0;
    }
    x.distance(e.center) * (1.0 - 1.0 / rho)
}

/// The surface samples where the model falls short, worst first: geometric residual
/// `F/|∇F|` below `−tolerance` (lengths in units of the model), at most `count` of them and no
/// two closer than `separation`; each with its field value `F`. Deterministic: ties break by
/// sample index.
pub fn worst_shortfalls(
    field: &BlobField,
    points: &[DVec3],
    tolerance: f64,
    separation: f64,
    count: usize,
    diag: f64,
) -> Vec<(DVec3, f64)> {
    let mut short: Vec<(f64, usize, f64)> = points
        .par_iter()
        .enumerate()
        .filter_map(|(k, &x)| {
            let (f, g) = field.value_and_gradient(x);
            let d = f * inverse_gradient(g, diag);
            (d < -tolerance).then_some((d, k, f))
        })
        .collect();
    short.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut picked: Vec<(DVec3, f64)> = Vec::new();
    for (_, k, f) in short {
        if picked.len() >= count {
            break;
        }
        let x = points[k];
        if picked.iter().all(|p| p.0.distance(x) >= separation) {
            picked.push((x, f));
        }
    }
    picked
}

/// For each point, the unused candidate whose surface passes nearest it (within `reach`),
/// marking it used. Returns `(candidate, point)` index pairs, in the points' order.
pub fn nearest_unused(
    candidates: &[Ellipsoid],
    used: &mut [bool],
    points: &[DVec3],
    reach: f64,
) -> Vec<(usize, usize)> {
    let mut chosen = Vec::new();
    for (k, &x) in points.iter().enumerate() {
        let best = candidates
            .iter()
            .enumerate()
            .filter(|(i, _)| !used[*i])
            .map(|(i, e)| (radial_gap(e, x), i))
            .filter(|(gap, _)| *gap <= reach)
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        if let Some((_, i)) = best {
            used[i] = true;
            chosen.push((i, k));
        }
    }
    chosen
}

/// A blob whose peak field `B²` is below this fraction of the threshold is redundant: dropping
/// it moves `F` by less than that anywhere. The optimiser leaves many such nearly switched-off
/// blobs (7–16 % of a fit's), and each costs bytes and render time for no visible surface.
pub const NEGLIGIBLE: f64 = 0.002;

/// The blobs a full fit is placing, each with its anchor (where its shape prior holds it: its
/// decomposition ellipsoid), and which decomposition candidates a blob has come from.
pub struct Placement {
    /// The blobs, in selection order and then in the order they were added.
    pub blobs: Vec<Blob>,
    /// `anchors[i]` is the blob `blobs[i]` started as.
    pub anchors: Vec<Blob>,
    /// Per candidate: a blob came from it (the budget takes only the others).
    pub used: Vec<bool>,
}

impl Placement {
    /// Keep the blobs `i` with `keep[i]` and their anchors, in order.
    pub fn retain(&mut self, keep: &[bool]) {
        let (mut a, mut b) = (keep.iter(), keep.iter());
        self.anchors.retain(|_| *a.next().unwrap_or(&false));
        self.blobs.retain(|_| *b.next().unwrap_or(&false));
    }

    /// Drop the dead blobs (`B = 0`) and their anchors, keeping the order of the rest.
    pub fn drop_dead(&mut self) {
        let keep: Vec<bool> = self.blobs.iter().map(Blob::is_live).collect();
        self.retain(&keep);
    }
}

/// Drop the blobs whose peak field is negligible (see [`NEGLIGIBLE`]) at iso-level
/// `threshold`, keeping the order of the rest. Run it last: between optimisation passes such a
/// blob can still grow back.
pub fn drop_negligible(blobs: &mut Vec<Blob>, threshold: f64) {
    blobs.retain(|b| b.b * b.b >= NEGLIGIBLE * threshold);
}

/// The adaptive blob budget of a fit.
pub struct Budget<'a> {
    /// Blobs the model may have.
    pub blobs: usize,
    /// The decomposition's candidate ellipsoids, the pool new blobs come from.
    pub candidates: &'a [Ellipsoid],
    /// Starting `A` of a new blob.
    pub initial_a: f64,
    /// The surface samples whose shortfalls the budget closes.
    pub points: &'a [DVec3],
}

impl Budget<'_> {
    /// Fill the model up to `self.blobs` in `budget_rounds` rounds: each adds blobs from the
    /// unused candidates at the worst shortfalls of the surface samples, then re-fits the new
    /// blobs and those overlapping them for `budget_sweeps` sweeps and drops any that died.
    pub fn spend(&self, problem: &FullProblem, placed: &mut Placement) {
        let cfg = problem.cfg;
        for round in 0..cfg.budget_rounds {
            let spare = self.blobs.saturating_sub(placed.blobs.len());
            let before = placed.blobs.len();
            let count = spare.div_ceil(cfg.budget_rounds - round);
            self.add_at_shortfalls(problem, placed, count);
            if placed.blobs.len() == before {
                break;
            }
            let active = overlapping(&placed.blobs, before);
            problem.optimise(
                &mut placed.blobs,
                &placed.anchors,
                cfg.budget_sweeps,
                Some(&active),
                cfg.shape_prior,
            );
            placed.drop_dead();
        }
    }

    /// Add up to `count` blobs (with their anchors) from the unused candidates at the model's
    /// worst shortfalls, marking their candidates used.
    pub(super) fn add_at_shortfalls(
        &self,
        problem: &FullProblem,
        placed: &mut Placement,
        count: usize,
    ) {
        if count == 0 {
            return;
        }
        let diag = problem.diag;
        let field = BlobField::new(&placed.blobs, problem.threshold);
        let depth = problem.cfg.budget_shortfall * diag;
        let worst = worst_shortfalls(&field, self.points, depth, 0.03 * diag, count, diag);
        let at: Vec<DVec3> = worst.iter().map(|w| w.0).collect();
        for (i, k) in nearest_unused(self.candidates, &mut placed.used, &at, 0.05 * diag) {
            let (x, f) = worst[k];
            let blob = closing_blob(&self.candidates[i], self.initial_a, x, f);
            placed.blobs.push(blob);
            placed.anchors.push(blob);
        }
    }
}

/// The blob of ellipsoid `e` with just enough weight to bring the field `F(x) = f < 0` to the
/// threshold at `x` (and at most the weight that makes `e` its own iso-surface): the blob adds
/// to a field already near the threshold, and its full weight would bulge out.
fn closing_blob(e: &Ellipsoid, initial_a: f64, x: DVec3, f: f64) -> Blob {
    let mut blob = Blob::from_ellipsoid(e, initial_a);
    let u = e.radius_squared(x) / (1.0 + blob.a);
    if u < 1.0 {
        blob.b = blob.b.min((-f).sqrt() / (1.0 - u));
    }
    blob
}

/// Blobs from `first_new` on, and every blob whose support box overlaps one of theirs.
pub(super) fn overlapping(blobs: &[Blob], first_new: usize) -> Vec<bool> {
    let boxes: Vec<_> = blobs.iter().map(Blob::support_bounds).collect();
    (0..blobs.len())
        .map(|i| i >= first_new || boxes[first_new..].iter().any(|b| b.overlaps(&boxes[i])))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn sphere(c: DVec3, r: f64) -> Ellipsoid {
        Ellipsoid {
            center: c,
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
        }
    }

    #[test]
    fn radial_gap_is_exact_for_a_sphere() {
        let e = sphere(DVec3::new(1.0, 0.0, 0.0), 2.0);
        assert!((radial_gap(&e, DVec3::new(1.0, 3.5, 0.0)) - 1.5).abs() < 1e-12);
        assert_eq!(radial_gap(&e, DVec3::new(1.5, 0.0, 0.0)), 0.0);
    }

    #[test]
    fn closes_the_gap_with_the_candidate_that_reaches_it() {
        // One blob covers the left of two touching spheres; the right one is missing.
        let left = sphere(DVec3::new(-1.0, 0.0, 0.0), 1.0);
        let right = sphere(DVec3::new(1.0, 0.0, 0.0), 1.0);
        let far = sphere(DVec3::new(0.0, 5.0, 0.0), 1.0);
        let mut blobs = vec![Blob::from_ellipsoid(&left, 1.0)];
        let points: Vec<DVec3> = (0..200)
            .map(|i| {
                let t = i as f64 / 200.0 * std::f64::consts::TAU;
                let c = if i % 2 == 0 { -1.0 } else { 1.0 };
                DVec3::new(c + t.cos(), t.sin(), 0.0)
            })
            .collect();
        let diag = 7.0;
        let field = BlobField::new(&blobs, 1.0);
        let worst = worst_shortfalls(&field, &points, 0.002 * diag, 0.03 * diag, 3, diag);
        assert_eq!(worst.len(), 3, "the right circle falls short everywhere");
        assert!(worst.iter().all(|(x, f)| x.x > 0.0 && *f < 0.0));
        let at: Vec<DVec3> = worst.iter().map(|w| w.0).collect();
        let candidates = [far, right, left];
        let mut used = [false, false, true];
        let chosen = nearest_unused(&candidates, &mut used, &at, 0.05 * diag);
        assert_eq!(
            chosen,
            [(1, 0)],
            "one candidate reaches the gap; the far one is too far"
        );
        assert_eq!(used, [false, true, true]);
        let (x, f) = worst[0];
        blobs.push(closing_blob(&right, 1.0, x, f));
        let closed = BlobField::new(&blobs, 1.0).value(x);
        assert!(closed.abs() < 1e-9, "F at the worst point after: {closed}");
    }
}
