//! Three-stage growth of one candidate ellipsoid from a seed (docs/ARCHITECTURE.md, Decomposition; Bischoff &
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
//!
//! Contact margin: with point obstacles the first contact `q` (and `r`) is not the tangency
//! point of a smooth surface; the samples around it lie on the grown surface up to tiny
//! differences, with either sign of distance to the tangent plane, so the next stage stops at
//! once on a near-tie (observed: `α ≈ 0.006` at the pole of a 2:1:0.5 ellipsoid that should
//! reach `α = 3`). Each stage therefore starts from its predecessor pulled in by a small
//! clearance `μ` at the contact (`μ ≪ ε`; the contacts remain on the obstacle layer's scale).
//!
//! Thin results: the perpendicular stage grows along the plane normal until an obstacle is
//! touched, and an ellipsoid thinner than the gaps between samples can grow through the surface
//! between them (observed on the horse: needles 0.003·D thick, 0.06·D long, half outside the
//! mesh). Its result is kept only when its smallest semi-axis is at least
//! `min_stage3_axis` (1.5 mean sample spacings in the pipeline); ~2 % of seeds fall back to the
//! wedge stage, which showed no such leaks.

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
    /// Clearance kept from the contacts `q` (sphere shrunk by it before the wedge stage) and
    /// `r` (wedge backed off by it before the perpendicular stage).
    pub margin: f64,
    /// A perpendicular-stage result thinner than this (smallest semi-axis) is rejected in
    /// favour of the wedge stage: it can slip between samples (module notes).
    pub min_stage3_axis: f64,
    /// Use the touching obstacle's own smooth normal as `n_q` instead of the sphere's normal
    /// `(q − c)/ρ` there (the design's choice, used by the pipeline); see [`grow_seed`].
    pub surface_normal_at_q: bool,
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
///
/// `n_q` is the sphere's normal at `q`, or with `surface_normal_at_q` the sample's
/// own smooth normal. Either way the family passes through `p` and `q`, stays tangent to `P_p`
/// (so `a > 0` is outside), `a < 0 < b` has `Q' ≥ Q1 ≥ 0`, and the ellipticity limit is
/// `2/(1 + n_p·n_q)`: every member is an ellipsoid free of obstacles. (Before the contact
/// margin existed, the sample normal helped a little against near-ties; with the margin both
/// recover a 2:1:0.5 ellipsoid to ~2 %.)
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

    // Stage 2: Q' = Q1 + α·Q2, Q2 = −a·b with a = n_p·x, b = n_q·(x − q) (local coordinates),
    // on the sphere shrunk by the margin (module notes), still tangent at p.
    let rho2 = rho - limits.margin.min(0.25 * rho);
    let c = -rho2 * n;
    let Some(sphere_nq) = (obstacles.position(q_idx) - p - c).try_normalize() else {
        return Some(capped(grown, p, limits));
    };
    let q = c + rho2 * sphere_nq;
    let nq = if limits.surface_normal_at_q {
        obstacles.normal(q_idx)
    } else {
        sphere_nq
    };
    let q1 = Quadric::sphere(c, rho2);
    let q2 = Quadric::neg_plane_product(n, 0.0, nq, nq.dot(q));
    let nq_q = nq.dot(q);
    let alpha_cap =
        (ALPHA_SAFETY * 2.0 / (1.0 + n.dot(nq))).min(4.0 * (limits.max_semi_axis / rho2).powi(2));
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
                let s = x * x + y * y + z * z + 2.0 * rho2 * a; // Q1 = |x − c|² − ρ²
                s.max(0.0) / (a * b)
            } else {
                f64::INFINITY
            }
        },
    );
    // Back off α so that Q' passes about one margin inside r.
    let alpha = match r_idx {
        Some(i) => {
            let r = obstacles.position(i) - p;
            let ab = (n.dot(r) * (nq.dot(r) - nq_q)).abs();
            let grad = 2.0 * (q1.add_scaled(alpha, &q2).matrix() * r + q1.add_scaled(alpha, &q2).b);
            let back = limits.margin * grad.length() / ab;
            if back.is_finite() {
                (alpha - back).max(0.0)
            } else {
                alpha
            }
        }
        None => alpha,
    };
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
    if let Some(e) = qp.add_scaled(beta, &q3).ellipsoid()
        && e.semi_axes.min_element() >= limits.min_stage3_axis
    {
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
