//! The scene's target transform: orient, scale and place the fitted model in the shot (the fit
//! cache stays keyed on the mesh and fit settings; the transform is applied after loading).
//!
//! `transform: (up: Z, rotate_deg: (0.0, 90.0, 0.0), scale: 1.0, translate: (0.0, 0.0, 0.0))`
//! maps a model point `p` to `translate + scale · R_rot · R_up · p`, where `R_up` is the
//! smallest rotation taking the model's `up` axis to +Y (the world's up; for `NegY` a half
//! turn about X) and `R_rot` rotates by `rotate_deg` degrees about the world's X, then Y, then
//! Z axes. Every field has a default (the identity). Bad values (a scale that is not a positive
//! finite number, a non-finite angle or offset) are parse errors located at the transform.

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::blobby::Blob;

/// Which of the model's axes points up.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Up {
    /// +X.
    X,
    /// +Y (the world's up; no rotation).
    #[default]
    Y,
    /// +Z (most scanned and CAD meshes).
    Z,
    /// −X.
    NegX,
    /// −Y (upside down).
    NegY,
    /// −Z.
    NegZ,
}

impl Up {
    /// Every axis, in the order of [`Up::NAMES`].
    pub const ALL: [Up; 6] = [Up::X, Up::Y, Up::Z, Up::NegX, Up::NegY, Up::NegZ];
    /// The command line's names of [`Up::ALL`] (`-x` may also be written `negx`).
    pub const NAMES: [&'static str; 6] = ["x", "y", "z", "-x", "-y", "-z"];

    /// The axis named `name` (any case): `x`, `y`, `z`, `-x`, `-y`, `-z` or `negx`, ….
    pub fn from_name(name: &str) -> Option<Up> {
        let n = name.trim().to_ascii_lowercase();
        let n = n
            .strip_prefix("neg")
            .map_or(n.clone(), |rest| format!("-{rest}"));
        Up::NAMES.iter().position(|&k| k == n).map(|i| Up::ALL[i])
    }

    /// The model axis.
    pub fn axis(self) -> DVec3 {
        match self {
            Up::X => DVec3::X,
            Up::Y => DVec3::Y,
            Up::Z => DVec3::Z,
            Up::NegX => DVec3::NEG_X,
            Up::NegY => DVec3::NEG_Y,
            Up::NegZ => DVec3::NEG_Z,
        }
    }

    /// The smallest rotation taking [`Up::axis`] to +Y (a half turn about X for `NegY`).
    pub fn rotation(self) -> DQuat {
        match self {
            Up::NegY => DQuat::from_rotation_x(std::f64::consts::PI),
            other => DQuat::from_rotation_arc(other.axis(), DVec3::Y),
        }
    }
}

/// The fields as written; checked into a [`TargetTransform`].
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default, rename = "TargetTransform")]
struct Written {
    up: Up,
    rotate_deg: DVec3,
    scale: f64,
    translate: DVec3,
}

impl Default for Written {
    fn default() -> Self {
        let t = TargetTransform::default();
        Written {
            up: t.up,
            rotate_deg: t.rotate_deg,
            scale: t.scale,
            translate: t.translate,
        }
    }
}

/// Orientation, size and place of the target in the shot.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Written")]
pub struct TargetTransform {
    /// The model's up axis, turned to +Y.
    pub up: Up,
    /// Degrees about the world's X, Y, then Z axes, after `up`.
    pub rotate_deg: DVec3,
    /// Uniform scale (> 0).
    pub scale: f64,
    /// Offset, after rotation and scale.
    pub translate: DVec3,
}

impl Default for TargetTransform {
    fn default() -> Self {
        TargetTransform {
            up: Up::Y,
            rotate_deg: DVec3::ZERO,
            scale: 1.0,
            translate: DVec3::ZERO,
        }
    }
}

impl TryFrom<Written> for TargetTransform {
    type Error = String;

    fn try_from(w: Written) -> Result<Self, String> {
        if !(w.scale.is_finite() && w.scale > 0.0) {
            return Err(format!(
                "transform.scale must be a positive finite number, got {}",
                w.scale
            ));
        }
        if !w.rotate_deg.is_finite() {
            return Err(format!(
                "transform.rotate_deg must be finite, got {}",
                w.rotate_deg
            ));
        }
        if !w.translate.is_finite() {
            return Err(format!(
                "transform.translate must be finite, got {}",
                w.translate
            ));
        }
        Ok(TargetTransform {
            up: w.up,
            rotate_deg: w.rotate_deg,
            scale: w.scale,
            translate: w.translate,
        })
    }
}

impl TargetTransform {
    /// True for the identity (nothing to do).
    pub fn is_identity(&self) -> bool {
        *self == TargetTransform::default()
    }

    /// The rotation `R_rot · R_up`.
    pub fn rotation(&self) -> DQuat {
        let r = self.rotate_deg * (std::f64::consts::PI / 180.0);
        let rot =
            DQuat::from_rotation_z(r.z) * DQuat::from_rotation_y(r.y) * DQuat::from_rotation_x(r.x);
        (rot * self.up.rotation()).normalize()
    }

    /// A model point in the shot.
    pub fn apply_point(&self, p: DVec3) -> DVec3 {
        self.translate + self.scale * (self.rotation() * p)
    }

    /// The blobs moved into the shot: centres mapped, rotations composed, semi-axes scaled
    /// (`A` and `B` unchanged, so each blob's field is the original one carried along).
    pub fn apply(&self, blobs: &mut [Blob]) {
        if self.is_identity() {
            return;
        }
        let r = self.rotation();
        for b in blobs {
            b.center = self.translate + self.scale * (r * b.center);
            b.rotation = (r * b.rotation).normalize();
            b.semi_axes *= self.scale;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn z_up_stands_upright_and_fields_are_carried_along() {
        let t = TargetTransform {
            up: Up::Z,
            rotate_deg: DVec3::new(0.0, 90.0, 0.0),
            scale: 2.0,
            translate: DVec3::new(1.0, 0.0, 0.0),
        };
        // Z up -> Y; then 90° about Y takes -Z (the old +Y) to -X.
        let up = t.apply_point(DVec3::Z) - t.apply_point(DVec3::ZERO);
        assert!((up - DVec3::new(0.0, 2.0, 0.0)).length() < 1e-12, "{up}");
        let fwd = t.apply_point(DVec3::Y) - t.apply_point(DVec3::ZERO);
        assert!((fwd - DVec3::new(-2.0, 0.0, 0.0)).length() < 1e-12, "{fwd}");
        let blob = Blob {
            center: DVec3::new(0.3, -0.2, 0.5),
            rotation: DQuat::from_rotation_x(0.4),
            semi_axes: DVec3::new(0.5, 0.2, 0.3),
            a: 1.2,
            b: 1.5,
        };
        let mut moved = [blob];
        t.apply(&mut moved);
        for p in [DVec3::new(0.4, -0.1, 0.6), DVec3::new(0.1, -0.3, 0.4)] {
            let here = blob.value(p);
            let there = moved[0].value(t.apply_point(p));
            assert!((here - there).abs() < 1e-9, "{here} vs {there}");
        }
        for up in Up::ALL {
            let r = up.rotation() * up.axis();
            assert!((r - DVec3::Y).length() < 1e-12, "{up:?}");
        }
        assert_eq!(Up::from_name("Z"), Some(Up::Z));
        assert_eq!(Up::from_name("-y"), Some(Up::NegY));
        assert_eq!(Up::from_name("NegX"), Some(Up::NegX));
        assert_eq!(Up::from_name("w"), None);
    }
}
