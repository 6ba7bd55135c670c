//! A target that moves (issue 51): the scene's `transform` keyed over the shot — translate,
//! rotate and scale, each channel interpolated by the keyed camera's spline
//! ([`crate::spline::catmull_rom`]) — carries the whole cloud along.
//!
//! The plan is made once, with the target placed where the keys put it at the shot's first
//! frame (`t = 0`, the rest placement `P₀`); the cloud at time `t` is that plan's cloud moved by
//! `M(t) = P(t) · P₀⁻¹`, a similarity (rotation, uniform scale, translation). Each blob's centre
//! is mapped, its rotation composed and its semi-axes scaled, so its field — and the billows
//! anchored to its frame — are carried along unchanged. Velocities follow from the same moved
//! blobs ([`super::Direction`]), so `vel`, the shutter and the motion vectors include the motion:
//! at a point `x`, `v = Ṫ + ω × (x − T) + (ṡ/s)(x − T)` where the target is still in the plan.
//!
//! Rotations are keyed as the scene's `rotate_deg` (degrees about the world's X, then Y, then
//! Z, after the model's `up`) and interpolated per angle, as a DCC's Euler channels are.

use glam::{DQuat, DVec3};
use serde::Serialize;

use crate::blobby::Blob;

/// The rotation of a placement: `rotate_deg` (degrees about the world's X, then Y, then Z)
/// after `up` (the rotation standing the model upright). The one rule of the scene's
/// `transform.rotate_deg`.
pub fn placement_rotation(up: DQuat, rotate_deg: DVec3) -> DQuat {
    let r = rotate_deg * (std::f64::consts::PI / 180.0);
    let rot =
        DQuat::from_rotation_z(r.z) * DQuat::from_rotation_y(r.y) * DQuat::from_rotation_x(r.x);
    (rot * up).normalize()
}

/// A similarity: `p ↦ translate + scale · rotation · p`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    /// Unit rotation.
    pub rotation: DQuat,
    /// Uniform scale (> 0).
    pub scale: f64,
    /// Offset, after rotation and scale.
    pub translate: DVec3,
}

impl Similarity {
    /// The identity.
    pub const IDENTITY: Similarity = Similarity {
        rotation: DQuat::IDENTITY,
        scale: 1.0,
        translate: DVec3::ZERO,
    };

    /// `p` mapped.
    #[inline]
    pub fn apply_point(&self, p: DVec3) -> DVec3 {
        self.translate + self.scale * (self.rotation * p)
    }

    /// The inverse map.
    pub fn inverse(&self) -> Similarity {
        let r = self.rotation.inverse();
        Similarity {
            rotation: r,
            scale: 1.0 / self.scale,
            translate: -(r * self.translate) / self.scale,
        }
    }

    /// `self ∘ other` (first `other`, then `self`).
    pub fn then_after(&self, other: &Similarity) -> Similarity {
        Similarity {
            rotation: (self.rotation * other.rotation).normalize(),
            scale: self.scale * other.scale,
            translate: self.apply_point(other.translate),
        }
    }

    /// The blobs moved: centres mapped, rotations composed, semi-axes scaled (`A` and `B`
    /// unchanged, so each blob's field is carried along).
    pub fn apply(&self, blobs: &mut [Blob]) {
        for b in blobs {
            b.center = self.apply_point(b.center);
            b.rotation = (self.rotation * b.rotation).normalize();
            b.semi_axes *= self.scale;
        }
    }
}

/// One key of a moving target: where the `transform` puts the target at `time` (every channel
/// given; a channel the scene does not key holds the transform's own value).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PlacementKey {
    /// Seconds from the shot's first frame.
    pub time: f64,
    /// Offset, after rotation and scale.
    pub translate: DVec3,
    /// Degrees about the world's X, then Y, then Z, after the model's `up`.
    pub rotate_deg: DVec3,
    /// Uniform scale (> 0).
    pub scale: f64,
}

/// Check keys: at least two, finite, times strictly increasing, scales positive. The message
/// names the key.
pub fn check_keys(keys: &[PlacementKey]) -> Result<(), String> {
    if keys.len() < 2 {
        return Err(format!(
            "transform.keys: need at least two keys (a target that does not move needs none), \
             got {}",
            keys.len()
        ));
    }
    for (i, k) in keys.iter().enumerate() {
        if !(k.time.is_finite() && k.translate.is_finite() && k.rotate_deg.is_finite()) {
            return Err(format!(
                "transform key {i}: time, translate and rotate_deg must be finite"
            ));
        }
        if !(k.scale.is_finite() && k.scale > 0.0) {
            return Err(format!(
                "transform key {i}: scale must be a positive finite number, got {}",
                k.scale
            ));
        }
    }
    crate::spline::check_increasing("transform key", keys.iter().map(|k| k.time))?;
    Ok(())
}

/// A keyed target transform over the shot (see the module doc); made from checked keys.
#[derive(Clone, Debug, PartialEq)]
pub struct TargetMotion {
    up: DQuat,
    keys: Vec<PlacementKey>,
    times: Vec<f64>,
    /// `P₀⁻¹`: the plan's placement undone.
    rest_inverse: Similarity,
}

impl TargetMotion {
    /// The motion of keys `keys` (checked by [`check_keys`]) for a model stood upright by `up`.
    pub fn new(up: DQuat, keys: Vec<PlacementKey>) -> Result<TargetMotion, String> {
        check_keys(&keys)?;
        let times = keys.iter().map(|k| k.time).collect();
        let mut motion = TargetMotion {
            up,
            keys,
            times,
            rest_inverse: Similarity::IDENTITY,
        };
        motion.rest_inverse = motion.placement(0.0).inverse();
        Ok(motion)
    }

    /// The keys, in time order.
    pub fn keys(&self) -> &[PlacementKey] {
        &self.keys
    }

    /// The channels at `t` seconds: translate, rotate_deg and scale on the spline (the scale
    /// kept above a thousandth of the smallest key's, where a spline could overshoot).
    pub fn channels(&self, t: f64) -> (DVec3, DVec3, f64) {
        let k = &self.keys;
        let translate: DVec3 =
            crate::spline::catmull_rom::<f64, _>(&self.times, t, |j| k[j].translate);
        let rotate_deg: DVec3 =
            crate::spline::catmull_rom::<f64, _>(&self.times, t, |j| k[j].rotate_deg);
        let scale: f64 = crate::spline::catmull_rom::<f64, _>(&self.times, t, |j| k[j].scale);
        let floor = 1e-3 * k.iter().map(|k| k.scale).fold(f64::INFINITY, f64::min);
        (translate, rotate_deg, scale.max(floor))
    }

    /// Where the keys place the model at `t` seconds (`P(t)`).
    pub fn placement(&self, t: f64) -> Similarity {
        let (translate, rotate_deg, scale) = self.channels(t);
        Similarity {
            rotation: placement_rotation(self.up, rotate_deg),
            scale,
            translate,
        }
    }

    /// The motion of the plan's cloud at `t` seconds: `M(t) = P(t) · P₀⁻¹`.
    pub fn carry(&self, t: f64) -> Similarity {
        self.placement(t).then_after(&self.rest_inverse)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(time: f64, x: f64, yaw: f64, scale: f64) -> PlacementKey {
        PlacementKey {
            time,
            translate: DVec3::new(x, 1.0, 0.0),
            rotate_deg: DVec3::new(0.0, yaw, 0.0),
            scale,
        }
    }

    #[test]
    fn the_motion_starts_at_rest_and_reaches_each_key() {
        let up = DQuat::from_rotation_arc(DVec3::Z, DVec3::Y);
        let m = TargetMotion::new(up, vec![key(0.0, -1.0, 0.0, 1.0), key(2.0, 3.0, 90.0, 2.0)])
            .unwrap();
        let p = DVec3::new(0.3, -0.2, 0.5);
        assert!((m.carry(0.0).apply_point(p) - p).length() < 1e-12);
        // At t = 2: the model point q (with P₀ q = p) is at P(2) q.
        let q = m.placement(0.0).inverse().apply_point(p);
        let want = DVec3::new(3.0, 1.0, 0.0)
            + 2.0 * (DQuat::from_rotation_y(std::f64::consts::FRAC_PI_2) * (up * q));
        assert!((m.carry(2.0).apply_point(p) - want).length() < 1e-12);
        // Between, two keys move each channel at a constant rate.
        let (tr, rot, s) = m.channels(0.5);
        assert!((tr.x - 0.0).abs() < 1e-12 && (rot.y - 22.5).abs() < 1e-12);
        assert!((s - 1.25).abs() < 1e-12);
        // The inverse and composition.
        let a = m.placement(1.3);
        let back = a.inverse().apply_point(a.apply_point(p));
        assert!((back - p).length() < 1e-12);
    }

    #[test]
    fn bad_keys_are_refused_by_name() {
        let up = DQuat::IDENTITY;
        let one = TargetMotion::new(up, vec![key(0.0, 0.0, 0.0, 1.0)]).unwrap_err();
        assert!(one.contains("at least two"), "{one}");
        let order = TargetMotion::new(up, vec![key(1.0, 0.0, 0.0, 1.0), key(1.0, 1.0, 0.0, 1.0)])
            .unwrap_err();
        assert!(
            order.contains("key 1") && order.contains("increase"),
            "{order}"
        );
        let scale = TargetMotion::new(up, vec![key(0.0, 0.0, 0.0, 1.0), key(1.0, 1.0, 0.0, 0.0)])
            .unwrap_err();
        assert!(scale.contains("scale"), "{scale}");
    }
}
