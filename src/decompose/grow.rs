//! Three-stage growth of one candidate ellipsoid from a seed (DESIGN.md §3.4; Bischoff &
//! Kobbelt 2002): inscribed sphere → wedge → perpendicular stage.
//!
//! In: the [`ObstacleSet`], a seed point `p` with outward unit normal `n`, and limits.
//! Out: a [`Grown`] ellipsoid containing no obstacle (obstacles may touch its boundary), or
//! `None` when the seed is unusable. All quadrics live in seed-local coordinates (origin `p`).
//!
//! Each stage is a one-parameter family `Q(t)` whose inside grows monotonically with `t` where
//! obstacles can be, so "the first obstacle touched" is a minimum of a per-obstacle ratio, and
//! every obstacle with ratio below `t` lies inside `Q(t) < 0`: the bounding box of `Q(t)` is an
//! exact pruning region for [`ObstacleSet::first_touch`].

use glam::DVec3;

use super::obstacles::ObstacleSet;
use super::quadric::Quadric;
use crate::geometry::{Aabb, Ellipsoid};

/// Fraction of the wedge stage's ellipticity limit `α < 2/(1 + n_p·n_q)` that is used.
pub const ALPHA_SAFETY: f64 = 0.95;

/// Limits of one growth, in the mesh's units.
#[derive(Clone, Copy, Debug)]
pub struct GrowLimits {
    /// Cap of every semi-axis (and of the stage-1 radius search).
    pub max_semi_axis: f64,
    /// Seeds whose inscribed sphere is smaller than this are dropped.
    pub min_radius: f64,
    /// Stop after stage 1 (spheres).
    pub sphere_only: bool,
}

/// A grown candidate.
#[derive(Clone, Copy, Debug)]
pub struct Grown {
    /// The final ellipsoid (world space), semi-axes capped.
    pub ellipsoid: Ellipsoid,
    /// Radius of the stage-1 inscribed sphere.
    pub sphere_radius: f64,
    /// Last stage that succeeded (1, 2 or 3).
    pub stage: u8,
}

/// Box of a local-space quadric's inside, moved to world space and padded by `pad`.
fn world_bounds(q: &Quadric, p: DVec3, pad: f64) -> Option<Aabb> {
    q.bounds()
        .map(|b| Aabb {
            min: b.min + p,
            max: b.max + p,
        })
        .map(|b| b.expanded(pad))
}

/// Grow from seed `p` (outward unit normal `n`) against `obstacles`; `order` is the chunk order
/// from [`ObstacleSet::chunks_by_distance`] for `p`.
pub fn grow_seed(
    obstacles: &ObstacleSet,
    order: &[(f64, u32)],
    p: DVec3,
    n: DVec3,
    limits: &GrowLimits,
) -> Option<Grown> {
    let pad = 1e-9 * limits.max_semi_axis;
    let none = [u32::MAX; 2];
    // Stage 1: spheres tangent at p, centre p − ρn; x enters at ρ = |x−p|² / (−2(x−p)·n).
    let (rho, q_idx) = obstacles.first_touch(
        order,
        p,
        limits.max_semi_axis,
        none,
        |r| {
            let c = p - r * n;
            Some(Aabb {
                min: c - DVec3::splat(r + pad),
                max: c + DVec3::splat(r + pad),
            })
        },
        |x, y, z| {
            let dn = x * n.x + y * n.y + z * n.z;
            let d2 = x * x + y * y + z * z;
            if dn < 0.0 {
                d2 / (-2.0 * dn)
            } else {
                f64::INFINITY
            }
        },
    );
    let q_idx = q_idx?;
    if !(rho >= limits.min_radius) {
        return None;
    }
    // Local space until `capped` moves it to the world.
    let sphere = Ellipsoid {
        center: -rho * n,
        rotation: glam::DQuat::IDENTITY,
        semi_axes: DVec3::splat(rho),
    };
    let mut grown = Grown {
        ellipsoid: sphere,
        sphere_radius: rho,
        stage: 1,
    };
    if limits.sphere_only {
        return Some(capped(grown, p, limits));
    }

    // Stage 2: Q' = Q1 + α·Q2, Q2 = −a·b with a = n_p·x, b = n_q·(x − q) (local coordinates).
    let c = -rho * n;
    let q = obstacles.position(q_idx) - p;
    let Some(nq) = ((q - c) / rho).try_normalize() else {
        return Some(capped(grown, p, limits));
    };
    let q1 = Quadric::sphere(c, rho);
    let q2 = Quadric::neg_plane_product(n, 0.0, nq, nq.dot(q));
    let nq_q = nq.dot(q);
    let alpha_cap =
        (ALPHA_SAFETY * 2.0 / (1.0 + n.dot(nq))).min(4.0 * (limits.max_semi_axis / rho).powi(2));
    let (alpha, r_idx) = obstacles.first_touch(
        order,
        p,
        alpha_cap,
        [q_idx, u32::MAX],
        |t| world_bounds(&q1.add_scaled(t, &q2), p, pad),
        |x, y, z| {
            let a = x * n.x + y * n.y + z * n.z;
            let b = x * nq.x + y * nq.y + z * nq.z - nq_q;
            if a < 0.0 && b < 0.0 {
                let s = x * x + y * y + z * z + 2.0 * rho * a; // Q1 = |x − c|² − ρ²
                s.max(0.0) / (a * b)
            } else {
                f64::INFINITY
            }
        },
    );
    let qp = q1.add_scaled(alpha, &q2);
    match qp.ellipsoid() {
        Some(e) => {
            grown.ellipsoid = e;
            grown.stage = 2;
        }
        None => return Some(capped(grown, p, limits)),
    }
    let Some(r_idx) = r_idx else {
        return Some(capped(grown, p, limits));
    };

    // Stage 3: cylinder Q3 over the cut of Q' with the plane (p, q, r); Q = Q' + β·Q3.
    let r = obstacles.position(r_idx) - p;
    let m = q.cross(r);
    if !(m.length() > 1e-9 * q.length() * r.length()) {
        return Some(capped(grown, p, limits));
    }
    let m = m.normalize();
    let q3 = qp.projected_along(m);
    let Some(beta_cap) = beta_limit(&qp, m, 2.0 * limits.max_semi_axis) else {
        return Some(capped(grown, p, limits));
    };
    let (beta, _) = obstacles.first_touch(
        order,
        p,
        beta_cap,
        [q_idx, r_idx],
        |t| world_bounds(&qp.add_scaled(t, &q3), p, pad),
        |x, y, z| {
            let v = DVec3::new(x, y, z);
            let s3 = q3.eval(v);
            if s3 < 0.0 {
                qp.eval(v).max(0.0) / -s3
            } else {
                f64::INFINITY
            }
        },
    );
    if let Some(e) = qp.add_scaled(beta, &q3).ellipsoid() {
        grown.ellipsoid = e;
        grown.stage = 3;
    }
    Some(capped(grown, p, limits))
}

/// A `β` at which `Q' + β·Q3` reaches about `extent` along `m` from the cut ellipse's centre:
/// along that line `Q = Q'(o + t m) − β·k` with `k = −Q'(o)`, so `β ≈ A'_mm·extent²/k`.
fn beta_limit(qp: &Quadric, m: DVec3, extent: f64) -> Option<f64> {
    // Centre of the cut: minimise Q' over the plane x = u·e1 + v·e2.
    let e1 = m.any_orthonormal_vector();
    let e2 = m.cross(e1);
    let a = qp.matrix();
    let (a11, a12, a22) = (e1.dot(a * e1), e1.dot(a * e2), e2.dot(a * e2));
    let (b1, b2) = (qp.b.dot(e1), qp.b.dot(e2));
    let det = a11 * a22 - a12 * a12;
    if !(det > 0.0) {
        return None;
    }
    let u = -(a22 * b1 - a12 * b2) / det;
    let v = -(a11 * b2 - a12 * b1) / det;
    let k = -qp.eval(u * e1 + v * e2);
    let amm = m.dot(a * m);
    let beta = amm * extent * extent / k;
    (k > 0.0 && beta.is_finite() && beta > 0.0).then_some(beta)
}

/// Translate the local ellipsoid to world space and cap its semi-axes (same centre and axes:
/// the capped ellipsoid lies inside the uncapped one, so it stays obstacle-free).
fn capped(mut g: Grown, p: DVec3, limits: &GrowLimits) -> Grown {
    g.ellipsoid.center += p;
    g.ellipsoid.semi_axes = g
        .ellipsoid
        .semi_axes
        .min(DVec3::splat(limits.max_semi_axis));
    g
}
