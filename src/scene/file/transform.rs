//! The scene's target transform: orient, scale and place the fitted model in the shot (the fit
//! cache stays keyed on the mesh and fit settings; the transform is applied after loading).
//!
//! `transform: (up: Z, rotate_deg: (0.0, 90.0, 0.0), scale: 1.0, translate: (0.0, 0.0, 0.0))`
//! maps a model point `p` to `translate + scale · R_rot · R_up · p`, where `R_up` is the
//! smallest rotation taking the model's `up` axis to +Y (the world's up; for `NegY` a half
//! turn about X) and `R_rot` rotates by `rotate_deg` degrees about the world's X, then Y, then
//! Z axes. Every field has a default (the identity). Bad values (a scale that is not a positive
//! finite number, a non-finite angle or offset) are parse errors located at the transform.
//!
//! A target that moves keys the transform over the shot:
//! `transform: (up: Z, scale: 0.8, keys: [(time: 0.0, translate: (-2.0, 0.0, 0.0)),
//! (time: 4.0, translate: (2.0, 0.5, 0.0), rotate_deg: (0.0, 30.0, 0.0))])`. Each key gives
//! `time` (seconds from the first frame) and any of `translate`, `rotate_deg`, `scale`; a
//! channel a key leaves out holds the transform's own value (so `scale: 0.8` above holds
//! throughout). Between keys every channel follows the keyed camera's spline; before the first
//! key and after the last the target holds. The plan is made with the target where the keys
//! put it at `t = 0`, and [`crate::animate::TargetMotion`] carries the cloud from there. At
//! least two keys, finite values, strictly increasing times and positive scales — or the scene
//! does not parse.

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::animate::target_motion::{PlacementKey, TargetMotion, check_keys, placement_rotation};
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
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default, rename = "TargetTransform")]
struct Written {
    up: Up,
    rotate_deg: DVec3,
    scale: f64,
    translate: DVec3,
    keys: Vec<WrittenKey>,
}

/// A key as written: a channel left out holds the transform's own value.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, rename = "PlacementKey")]
struct WrittenKey {
    time: f64,
    #[serde(default)]
    translate: Option<DVec3>,
    #[serde(default)]
    rotate_deg: Option<DVec3>,
    #[serde(default)]
    scale: Option<f64>,
}

impl Default for Written {
    fn default() -> Self {
        let t = TargetTransform::default();
        Written {
            up: t.up,
            rotate_deg: t.rotate_deg,
            scale: t.scale,
            translate: t.translate,
            keys: Vec::new(),
        }
    }
}

/// Orientation, size and place of the target in the shot; with `keys`, over the shot.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
    /// The keys of a target that moves (empty: it stays where the fields above put it). With
    /// keys, `rotate_deg`, `scale` and `translate` hold the placement at `t = 0`, where the
    /// plan is made, and every key holds all three channels.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keys: Vec<PlacementKey>,
}

impl Default for TargetTransform {
    fn default() -> Self {
        TargetTransform {
            up: Up::Y,
            rotate_deg: DVec3::ZERO,
            scale: 1.0,
            translate: DVec3::ZERO,
            keys: Vec::new(),
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
        let keys: Vec<PlacementKey> = w
            .keys
            .iter()
            .map(|k| PlacementKey {
                time: k.time,
                translate: k.translate.unwrap_or(w.translate),
                rotate_deg: k.rotate_deg.unwrap_or(w.rotate_deg),
                scale: k.scale.unwrap_or(w.scale),
            })
            .collect();
        let mut t = TargetTransform {
            up: w.up,
            rotate_deg: w.rotate_deg,
            scale: w.scale,
            translate: w.translate,
            keys,
        };
        if !t.keys.is_empty() {
            check_keys(&t.keys)?;
            // The plan's placement: the keys' channels at the first frame.
            let (translate, rotate_deg, scale) = t.motion().expect("checked keys").channels(0.0);
            (t.translate, t.rotate_deg, t.scale) = (translate, rotate_deg, scale);
        }
        Ok(t)
    }
}

impl TargetTransform {
    /// True for the identity (nothing to do).
    pub fn is_identity(&self) -> bool {
        *self == TargetTransform::default()
    }

    /// The rotation `R_rot · R_up`.
    pub fn rotation(&self) -> DQuat {
        placement_rotation(self.up.rotation(), self.rotate_deg)
    }

    /// The keyed motion over the shot, `None` for a target that stays put.
    pub fn motion(&self) -> Option<TargetMotion> {
        if self.keys.is_empty() {
            return None;
        }
        TargetMotion::new(self.up.rotation(), self.keys.clone()).ok()
    }

    /// A model point in the shot (at `t = 0` for a target that moves).
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
            keys: Vec::new(),
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

    #[test]
    fn keys_hold_the_channels_they_leave_out_and_bad_keys_are_refused() {
        let parse = |text: &str| {
            ron::Options::default()
                .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
                .from_str::<TargetTransform>(text)
        };
        let t = parse(
            "(up: Z, scale: 2.0, rotate_deg: (0.0, 10.0, 0.0), keys: [(time: 0.0, translate: \
             (1.0, 0.0, 0.0)), (time: 2.0, translate: (3.0, 0.0, 0.0), rotate_deg: (0.0, 90.0, \
             0.0))])",
        )
        .unwrap();
        // The rest placement is the keys' at t = 0; unkeyed channels hold the fields' values.
        assert_eq!(t.translate, DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(t.rotate_deg, DVec3::new(0.0, 10.0, 0.0));
        assert_eq!(t.scale, 2.0);
        assert!(t.keys.iter().all(|k| k.scale == 2.0));
        assert_eq!(t.keys[0].rotate_deg, DVec3::new(0.0, 10.0, 0.0));
        let m = t.motion().expect("keyed");
        let (tr, rot, s) = m.channels(1.0);
        assert!((tr - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-12);
        assert!((rot.y - 50.0).abs() < 1e-12 && s == 2.0);
        // The plan's placement is the motion's at t = 0.
        let p = DVec3::new(0.2, 0.4, -0.1);
        let rest = m.placement(0.0).apply_point(p);
        assert!((rest - t.apply_point(p)).length() < 1e-12);
        // Written back and read again: the same transform.
        let again = parse(&ron::to_string(&t).unwrap()).unwrap();
        assert_eq!(again, t);
        assert!(TargetTransform::default().motion().is_none());
        for (bad, needle) in [
            ("(keys: [(time: 0.0)])", "at least two"),
            ("(keys: [(time: 1.0), (time: 0.5)])", "increase"),
            ("(keys: [(time: 0.0), (time: 1.0, scale: -1.0)])", "scale"),
            ("(keys: [(time: 0.0), (time: 1.0, shear: 2.0)])", "shear"),
        ] {
            let e = parse(bad).unwrap_err().to_string();
            assert!(e.contains(needle), "{bad}: {e}");
        }
    }
}
