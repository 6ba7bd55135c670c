//! The velocity of the cloud: how fast the density at a point moves, from the animation's own
//! blob paths (docs/ARCHITECTURE.md, Animation).
//!
//! Each blob carries its neighbourhood along as an affine motion: a point with local
//! coordinates `u = S⁻¹Rᵀ(x − c)` (centre `c`, rotation `R`, semi-axes `S = diag(s)`) sits at
//! `X(u, t) = c(t) + R(t)·S(t)·u` at every time, so it moves with
//!
//! ```text
//! v_i(x) = ċ + (d/dt (R·S))·S⁻¹Rᵀ·(x − c)       (translation, rotation and growth together)
//! ```
//!
//! evaluated by a centred difference of the plan's blobs over [`DIFFERENCE_STEP`] of a frame
//! (one-sided at the shot's first and last frame). Where blobs overlap, the velocity of the
//! density is their motions weighted by each blob's share of the field:
//! `v(x) = Σ f_i(x)·v_i(x) / Σ f_i(x)` (0 where no blob reaches).
//!
//! A blob whose strength `B` changes grows or shrinks too: its own field
//! `f = B²(1 − ρ²/(1+A))²` keeps its value on the surface `ρ(t)` where `B·(1 − ρ²/(1+A))` is
//! constant, so the level set through its ellipsoid (`ρ = 1`, the blob's own surface) moves
//! at `ρ̇ = (A/2)·Ḃ/B`. The blob's neighbourhood is carried by that growth as by a change of
//! its semi-axes: an isotropic scaling about its centre at the rate `(A/2)·Ḃ/B` per second,
//! added to the gradient (`v_i(x) += (A/2)·(Ḃ/B)·(x − c)`). The diffusion's final part, where
//! category III is at full size and only the blobs' `B` rise (and I/II's blend to the fitted
//! ones), is such a growth; so is a morph's fade. A blob at `B = 0` has no share of the field,
//! so its rate does not matter (it is 0).
//!
//! Units: world units per second (the plan's blobs are in world units, times in seconds).

use glam::{DMat3, DVec3};

use super::{Plan, Timeline};
use crate::blobby::{Blob, BlobField, THRESHOLD};

/// Half-width of the centred difference, in frames (`1/1000` of a frame: far below any
/// curvature of the paths, far above f64 rounding of the positions).
pub const DIFFERENCE_STEP: f64 = 1e-3;

/// One blob's motion at an instant: `v(x) = velocity + gradient·(x − center)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlobMotion {
    /// The blob's centre at the instant.
    pub center: DVec3,
    /// Velocity of the centre (world units per second).
    pub velocity: DVec3,
    /// Velocity gradient `∂v/∂x` (per second): rotation (its antisymmetric part) and growth.
    pub gradient: DMat3,
}

impl BlobMotion {
    /// A blob that does not move.
    pub fn still(center: DVec3) -> BlobMotion {
        BlobMotion {
            center,
            velocity: DVec3::ZERO,
            gradient: DMat3::ZERO,
        }
    }

    /// The motion of blob `now` from its states `before` and `after`, `span` seconds apart. A
    /// blob with a zero or non-finite size, or a non-positive span, moves only with its centre
    /// (or not at all).
    pub fn between(before: &Blob, now: &Blob, after: &Blob, span: f64) -> BlobMotion {
        if !(span.is_finite() && span > 0.0) {
            return BlobMotion::still(now.center);
        }
        let velocity = (after.center - before.center) / span;
        let frame =
            |b: &Blob| DMat3::from_quat(b.rotation.normalize()) * DMat3::from_diagonal(b.semi_axes);
        let s = now.semi_axes;
        let gradient = if s.min_element() > 0.0 && s.is_finite() && now.rotation.is_finite() {
            // (R_b S_b − R_a S_a)/span · S⁻¹ Rᵀ: world offset now → its rate of change.
            let local_from_world = DMat3::from_diagonal(DVec3::ONE / s)
                * DMat3::from_quat(now.rotation.normalize()).transpose();
            (frame(after) - frame(before)) * local_from_world * (1.0 / span)
        } else {
            DMat3::ZERO
        };
        let gradient = gradient
            + DMat3::from_diagonal(DVec3::splat(strength_growth(before, now, after, span)));
        let finite = velocity.is_finite() && gradient.is_finite();
        BlobMotion {
            center: now.center,
            velocity: if finite { velocity } else { DVec3::ZERO },
            gradient: if finite { gradient } else { DMat3::ZERO },
        }
    }

    /// Velocity of the point `x` carried by this blob.
    #[inline]
    pub fn at(&self, x: DVec3) -> DVec3 {
        self.velocity + self.gradient * (x - self.center)
    }
}

/// `(A/2)·Ḃ/B` of blob `now` from its strengths `span` seconds apart (0 when it is off now, or
/// anything is not finite).
fn strength_growth(before: &Blob, now: &Blob, after: &Blob, span: f64) -> f64 {
    let b = now.b.abs();
    if !(b > 0.0 && span > 0.0) {
        return 0.0;
    }
    let rate = 0.5 * now.a * (after.b.abs() - before.b.abs()) / (span * b);
    if rate.is_finite() { rate } else { 0.0 }
}

/// The velocity of the density of one instant: every blob's motion and the field that weighs
/// them. Immutable once built; cheap to query from many threads.
#[derive(Clone, Debug)]
pub struct VelocityField {
    field: BlobField,
    motions: Vec<BlobMotion>,
}

impl VelocityField {
    /// The velocity field of `now`, from the same blobs (index = identity) `span` seconds
    /// apart, `before` and `after`. The three lists must have the same length.
    pub fn new(before: &[Blob], now: &[Blob], after: &[Blob], span: f64) -> VelocityField {
        assert!(
            before.len() == now.len() && after.len() == now.len(),
            "blob lists of different lengths: {} {} {}",
            before.len(),
            now.len(),
            after.len()
        );
        let motions = (0..now.len())
            .map(|i| BlobMotion::between(&before[i], &now[i], &after[i], span))
            .collect();
        VelocityField {
            field: BlobField::new(now, THRESHOLD),
            motions,
        }
    }

    /// The velocity field of `plan` at `t` seconds: a centred difference over
    /// ±[`DIFFERENCE_STEP`] of a frame, clipped to the shot (one-sided at its first and last
    /// frame, where the plan's paths end).
    pub fn of_plan(plan: &Plan, t: f64) -> VelocityField {
        VelocityField::of_path(plan.timeline(), t, |t| plan.at(t))
    }

    /// The velocity field at `t` seconds of the blobs `at(t)` over the shot of `timeline`
    /// (as [`VelocityField::of_plan`]: a centred difference, one-sided at the shot's ends).
    pub fn of_path(timeline: Timeline, t: f64, at: impl Fn(f64) -> Vec<Blob>) -> VelocityField {
        let h = DIFFERENCE_STEP / timeline.fps;
        let t0 = (t - h).max(0.0).min(t);
        let t1 = (t + h).min(timeline.end()).max(t);
        let now = at(t);
        if t1 <= t0 {
            return VelocityField::new(&now, &now, &now, 0.0);
        }
        VelocityField::new(&at(t0), &now, &at(t1), t1 - t0)
    }

    /// The blobs' motions (index = blob identity).
    pub fn motions(&self) -> &[BlobMotion] {
        &self.motions
    }

    /// Velocity of the density at `x` (world units per second): the blobs' motions weighted
    /// by their share of the field there; 0 where no blob reaches.
    pub fn velocity(&self, x: DVec3) -> DVec3 {
        let (mut sum, mut weight) = (DVec3::ZERO, 0.0);
        for &i in self.field.blobs_near(x) {
            let f = self.field.blob_value(i as usize, x);
            if f > 0.0 {
                sum += self.motions[i as usize].at(x) * f;
                weight += f;
            }
        }
        if weight > 0.0 {
            sum / weight
        } else {
            DVec3::ZERO
        }
    }
}

impl crate::render::CloudVelocity for VelocityField {
    /// [`VelocityField::velocity`]: what the motion-vector pass projects.
    fn velocity_at(&self, x: DVec3) -> DVec3 {
        self.velocity(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::sphere_blob;
    use glam::DQuat;

    #[test]
    fn translation_rotation_and_growth_are_recovered() {
        // A sphere moving at v, spinning at ω about z and growing at rate g (ṡ/s), over a
        // small span: v(x) = v + ω×(x − c) + g·(x − c).
        let (v, omega, g, h) = (DVec3::new(0.5, -1.0, 2.0), 0.8, 0.3, 1e-4);
        let c = DVec3::new(1.0, 2.0, 3.0);
        let at = |t: f64| Blob {
            center: c + v * t,
            rotation: DQuat::from_rotation_z(omega * t),
            semi_axes: DVec3::new(1.0, 0.5, 0.7) * (g * t).exp(),
            ..sphere_blob(c, 1.0)
        };
        let m = BlobMotion::between(&at(-h), &at(0.0), &at(h), 2.0 * h);
        for x in [c, c + DVec3::X, c + DVec3::new(0.2, -0.3, 0.4)] {
            let r = x - c;
            let expected = v + DVec3::Z.cross(r) * omega + r * g;
            assert!(
                (m.at(x) - expected).length() < 1e-6,
                "{} vs {expected}",
                m.at(x)
            );
        }
    }

    #[test]
    fn a_blob_whose_strength_rises_grows_with_its_own_surface() {
        // B rising at rate β (Ḃ/B): the level set of the blob's field through ρ = 1 moves
        // to ρ(h) with B(h)·(1 − ρ²/(1+A)) = B(0)·(1 − 1/(1+A)); the velocity at the
        // surface point is that speed, outward, and zero at the centre.
        let (beta, h) = (0.4, 1e-5);
        let c = DVec3::new(0.3, -0.2, 0.1);
        let base = Blob {
            rotation: DQuat::from_rotation_y(0.7),
            semi_axes: DVec3::new(1.0, 0.6, 0.4),
            ..sphere_blob(c, 1.0)
        };
        let at = |t: f64| Blob {
            b: base.b * (beta * t).exp(),
            ..base
        };
        let m = BlobMotion::between(&at(-h), &at(0.0), &at(h), 2.0 * h);
        let a = base.a;
        let rho_after = ((1.0 + a) * (1.0 - (base.b / at(h).b) * (1.0 - 1.0 / (1.0 + a)))).sqrt();
        let speed = (rho_after - 1.0) / h; // in ρ per second; ρ = 1 is the ellipsoid
        let axis = DMat3::from_quat(base.rotation) * DVec3::new(0.0, 0.6, 0.0);
        let v = m.at(c + axis);
        let expected = axis * speed;
        assert!(
            (v - expected).length() < 1e-4 * expected.length(),
            "{v} vs {expected}"
        );
        assert!((speed - 0.5 * a * beta).abs() < 1e-4, "{speed}");
        assert_eq!(m.at(c), DVec3::ZERO);
        // Fading out moves inward; a blob off now has no growth.
        let fade = BlobMotion::between(&at(h), &at(0.0), &at(-h), 2.0 * h);
        assert!(fade.at(c + axis).dot(axis) < 0.0);
        let off = Blob { b: 0.0, ..base };
        assert_eq!(
            BlobMotion::between(&off, &off, &at(h), 2.0 * h).gradient,
            DMat3::ZERO
        );
    }

    #[test]
    fn a_blob_flying_in_moves_at_its_planned_speed() {
        use crate::animate::{AggregationConfig, Animation, Timeline, plan};
        use crate::blobby::BlobModel;
        // One blob, no jitter: it flies along −direction at step·(K − 1)/motion seconds,
        // constant to the end of the motion, then holds.
        let cfg = AggregationConfig {
            jitter: 0.0,
            size_jitter: 0.0,
            rotation_jitter_deg: 0.0,
            repulsion: 0.0,
            ..AggregationConfig::default()
        };
        let blob = sphere_blob(DVec3::new(0.5, 1.0, -0.5), 0.4);
        let model = BlobModel {
            version: crate::blobby::model_file::MODEL_VERSION,
            primitive: crate::decompose::Primitive::Ellipsoid,
            threshold: THRESHOLD,
            source: crate::blobby::SourceInfo {
                mesh: "test".into(),
                bounds: blob.support_bounds(),
                vertices: 0,
                faces: 0,
            },
            seed: 0,
            blobs: vec![blob],
        };
        let timeline = Timeline {
            frames: 49,
            fps: 24.0,
            hold_seconds: 0.5,
        };
        let plan = plan(
            &Animation::<()>::Aggregation(cfg.clone()),
            &model,
            timeline,
            7,
        )
        .unwrap();
        let Plan::Aggregation(agg) = &plan else {
            unreachable!()
        };
        let c = &agg.clusters()[0];
        let speed = c.step * (cfg.keyframes - 1) as f64 / timeline.motion_seconds();
        let expected = -c.direction * speed;
        for k in [0, 5, 17, 30] {
            let t = timeline.time(k);
            let f = VelocityField::of_plan(&plan, t);
            let centre = plan.at(t)[0].center;
            for x in [centre, centre + DVec3::new(0.1, -0.2, 0.05)] {
                let v = f.velocity(x);
                assert!(
                    (v - expected).length() < 1e-6 * speed,
                    "frame {k}: {v} vs {expected}"
                );
            }
        }
        // In the hold it is still.
        let t = timeline.time(45);
        let still = VelocityField::of_plan(&plan, t).velocity(plan.at(t)[0].center);
        assert_eq!(still, DVec3::ZERO);
    }

    #[test]
    fn overlapping_blobs_mix_by_their_share_of_the_field() {
        let (a, b) = (sphere_blob(DVec3::ZERO, 1.0), sphere_blob(DVec3::X, 1.0));
        let moved = |blob: Blob, d: DVec3| Blob {
            center: blob.center + d,
            ..blob
        };
        let (va, vb) = (DVec3::new(1.0, 0.0, 0.0), DVec3::new(0.0, 3.0, 0.0));
        let f = VelocityField::new(
            &[moved(a, -va), moved(b, -vb)],
            &[a, b],
            &[moved(a, va), moved(b, vb)],
            2.0,
        );
        // Midway both blobs weigh the same; near a's centre a dominates.
        let mid = f.velocity(DVec3::new(0.5, 0.0, 0.0));
        assert!((mid - (va + vb) * 0.5).length() < 1e-12, "{mid}");
        let x = DVec3::new(-0.3, 0.0, 0.0);
        let (wa, wb) = (a.value(x), b.value(x));
        let expected = (va * wa + vb * wb) / (wa + wb);
        assert!((f.velocity(x) - expected).length() < 1e-12);
        assert_eq!(f.velocity(DVec3::splat(10.0)), DVec3::ZERO);
    }
}
