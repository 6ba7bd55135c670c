//! Adaptive blob budget: spend the blobs the optimisation switched off where the model falls
//! shortest of the mesh.
//!
//! A surface sample with `F < 0` lies outside the model: the blob surface stops short of the
//! mesh there (a thin tip, a ridge). The remedy is a blob that reaches it, and the
//! decomposition already grew one inscribed ellipsoid per candidate seed; the unused candidate
//! whose surface passes nearest the sample is added, and the optimiser then fits it in.

use glam::DVec3;
use rayon::prelude::*;

use super::super::{Blob, BlobField};
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
/// two closer than `separation`. Deterministic: ties break by sample index.
pub fn worst_shortfalls(
    field: &BlobField,
    points: &[DVec3],
    tolerance: f64,
    separation: f64,
    count: usize,
    diag: f64,
) -> Vec<(DVec3, f64)> {
    let floor = 10.0 / diag;
    let short: Vec<(f64, usize, f64)> = points
        .par_iter()
        .enumerate()
        .filter_map(|(k, &x)| {
            let (f, g) = field.value_and_gradient(x);
            let d = f / g.length().max(floor);
            (d < -tolerance).then_some((d, k, f))
        })
        .collect();
    let mut short: Vec<_> = short;
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

/// Add up to `count` blobs from the unused `candidates` at the model's worst shortfalls
/// (starting `A` = `initial_a`). Returns how many were added.
#[allow(clippy::too_many_arguments)]
pub fn add_at_shortfalls(
    blobs: &mut Vec<Blob>,
    candidates: &[Ellipsoid],
    used: &mut [bool],
    points: &[DVec3],
    count: usize,
    diag: f64,
    threshold: f64,
    initial_a: f64,
) -> usize {
    if count == 0 {
        return 0;
    }
    let field = BlobField::new(blobs, threshold);
    let worst = worst_shortfalls(&field, points, 0.002 * diag, 0.03 * diag, count, diag);
    let at: Vec<DVec3> = worst.iter().map(|w| w.0).collect();
    let chosen = nearest_unused(candidates, used, &at, 0.05 * diag);
    for &(i, k) in &chosen {
        let mut blob = Blob::from_ellipsoid(&candidates[i], initial_a);
        // Just enough weight to close the gap at the worst point: the blob adds to a field
        // that is already nearly at the threshold there, and its full weight would bulge out.
        let (x, f) = worst[k];
        let u = blob.ellipsoid().radius_squared(x) / (1.0 + blob.a);
        if u < 1.0 {
            blob.b = blob.b.min((-f).sqrt() / (1.0 - u));
        }
        blobs.push(blob);
    }
    chosen.len()
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
    fn adds_the_candidate_that_reaches_the_gap() {
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
        let candidates = [far, right, left];
        let mut used = [false, false, true];
        let added =
            add_at_shortfalls(&mut blobs, &candidates, &mut used, &points, 3, 7.0, 1.0, 1.0);
        assert_eq!(added, 1, "one gap, at least 0.03·D wide, wants one blob");
        assert_eq!(blobs[1].center, right.center);
        assert_eq!(used, [false, true, true]);
    }
}
