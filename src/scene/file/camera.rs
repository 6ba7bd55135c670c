//! The scene camera per frame: automatic framing of the target or a fixed camera, with an
//! optional orbit around the vertical axis over the shot; or keyframes.
//!
//! Keyframes (`camera: Keyframes([(time: 0.0, position: …, look_at: …, fov_deg: …), …])`) are
//! interpolated by [`crate::spline::catmull_rom`] (a cubic Hermite spline with Catmull–Rom
//! tangents for uneven times, as the target transform's keys): position, look-at point and
//! field of view pass through every key, smoothly. Before the first key and after
//! the last the camera holds still. At least two keys, strictly increasing finite times, finite
//! points, `position ≠ look_at` and a field of view in (0, 180) — or the scene does not parse.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::chan::ChanCamera;
use super::usd_camera::UsdCamera;
use crate::geometry::Aabb;
use crate::render::{Camera, InvalidField};

/// The camera: automatic framing of the target, or fixed (optionally orbiting), or keyframes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum CameraSpec {
    /// Frame the target's bounding sphere from a direction.
    Auto(AutoCamera),
    /// An explicit pinhole camera (world units).
    Fixed(FixedCamera),
    /// Keyframes in seconds, smoothly interpolated (see the module doc).
    Keyframes(CameraKeyframes),
    /// The shot's tracked camera from a Nuke `.chan` file, one line per frame
    /// ([`super::chan`]).
    Chan(ChanCamera),
    /// The shot's tracked camera from a USD stage's `Camera` prim, by frame number
    /// ([`super::usd_camera`]).
    Usd(UsdCamera),
}

impl Default for CameraSpec {
    fn default() -> Self {
        CameraSpec::Auto(AutoCamera::default())
    }
}

/// Automatic framing: look at the centre of the target's bounding box from `azimuth_deg`
/// (0 = from +Z, 90 = from +X) and `elevation_deg` (above the horizon), at `distance` times
/// the distance at which the bounding sphere just fills the narrower field of view.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AutoCamera {
    /// Horizontal angle around +Y, degrees.
    pub azimuth_deg: f32,
    /// Angle above the horizon, degrees.
    pub elevation_deg: f32,
    /// Distance relative to the snug framing (> 0; 1 = bounding sphere fills the frame).
    pub distance: f32,
    /// Vertical field of view, degrees.
    pub fov_deg: f32,
    /// Degrees the camera orbits around +Y over the shot (counter-clockwise seen from above).
    pub orbit_deg: f32,
}

impl Default for AutoCamera {
    fn default() -> Self {
        AutoCamera {
            azimuth_deg: 30.0,
            elevation_deg: 15.0,
            distance: 1.0,
            fov_deg: 35.0,
            orbit_deg: 0.0,
        }
    }
}

/// A fixed camera in the target's units.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FixedCamera {
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Up hint.
    pub up: Vec3,
    /// Vertical field of view, degrees.
    pub fov_deg: f32,
    /// Degrees the camera orbits around the vertical axis through `look_at` over the shot.
    pub orbit_deg: f32,
}

impl Default for FixedCamera {
    fn default() -> Self {
        FixedCamera {
            position: Vec3::new(0.0, 1.2, 4.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov_deg: 35.0,
            orbit_deg: 0.0,
        }
    }
}

impl CameraSpec {
    /// Check the camera's values: finite, a field of view in (0, 180) degrees, a positive
    /// distance, `position ≠ look_at`. Keyframes are checked while parsing, with the file
    /// position.
    pub fn validate(&self) -> Result<(), InvalidField> {
        let finite = InvalidField::check_finite;
        let fov = |f: f32| {
            if f.is_finite() && f > 0.0 && f < 180.0 {
                Ok(())
            } else {
                Err(InvalidField::new(
                    "camera.fov_deg",
                    format!("must be in (0, 180), got {f}"),
                ))
            }
        };
        match self {
            CameraSpec::Auto(c) => {
                finite("camera", &[c.azimuth_deg, c.elevation_deg, c.orbit_deg])?;
                fov(c.fov_deg)?;
                if !(c.distance.is_finite() && c.distance > 0.0) {
                    return Err(InvalidField::new(
                        "camera.distance",
                        format!("must be positive, got {}", c.distance),
                    ));
                }
            }
            CameraSpec::Fixed(c) => {
                finite("camera", &[c.orbit_deg])?;
                finite("camera.position", &c.position.to_array())?;
                finite("camera.look_at", &c.look_at.to_array())?;
                finite("camera.up", &c.up.to_array())?;
                fov(c.fov_deg)?;
                if c.position.distance(c.look_at) <= 0.0 {
                    return Err(InvalidField::new(
                        "camera",
                        "position and look_at must differ".to_string(),
                    ));
                }
            }
            CameraSpec::Keyframes(_) => {}
            CameraSpec::Chan(c) => {
                fov(c.fov_deg)?;
                if c.file.trim().is_empty() {
                    return Err(InvalidField::new(
                        "camera.file",
                        "name the .chan file (relative to the scene file's folder)".to_string(),
                    ));
                }
            }
            CameraSpec::Usd(c) => {
                if c.file.trim().is_empty() {
                    return Err(InvalidField::new(
                        "camera.file",
                        "name the USD file (relative to the scene file's folder)".to_string(),
                    ));
                }
                if !c.prim.starts_with('/') {
                    return Err(InvalidField::new(
                        "camera.prim",
                        format!(
                            "must be the camera prim's absolute path (\"/World/cam\"), got {:?}",
                            c.prim
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// One camera keyframe.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraKey {
    /// Seconds from the first frame.
    pub time: f64,
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub look_at: Vec3,
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov_deg: f32,
}

fn default_fov() -> f32 {
    35.0
}

/// Checked camera keyframes (see the module doc).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<CameraKey>")]
pub struct CameraKeyframes(Vec<CameraKey>);

impl TryFrom<Vec<CameraKey>> for CameraKeyframes {
    type Error = String;

    fn try_from(keys: Vec<CameraKey>) -> Result<Self, String> {
        if keys.len() < 2 {
            return Err(format!(
                "camera keyframes: need at least two keys, got {}",
                keys.len()
            ));
        }
        for (i, k) in keys.iter().enumerate() {
            if !(k.time.is_finite() && k.position.is_finite() && k.look_at.is_finite()) {
                return Err(format!(
                    "camera keyframe {i}: time, position and look_at must be finite"
                ));
            }
            if !(k.fov_deg.is_finite() && k.fov_deg > 0.0 && k.fov_deg < 180.0) {
                return Err(format!(
                    "camera keyframe {i}: fov_deg must be in (0, 180), got {}",
                    k.fov_deg
                ));
            }
            if k.position.distance(k.look_at) <= 0.0 {
                return Err(format!(
                    "camera keyframe {i}: position and look_at must differ"
                ));
            }
        }
        crate::spline::check_increasing("camera keyframe", keys.iter().map(|k| k.time))?;
        Ok(CameraKeyframes(keys))
    }
}

impl CameraKeyframes {
    /// The keys, in time order.
    pub fn keys(&self) -> &[CameraKey] {
        &self.0
    }

    /// The camera at `t` seconds.
    pub fn at(&self, t: f64) -> Camera {
        let k = &self.0;
        let times: Vec<f64> = k.iter().map(|c| c.time).collect();
        let hermite = |f: &dyn Fn(&CameraKey) -> Vec3| -> Vec3 {
            crate::spline::catmull_rom::<f32, Vec3>(&times, t, |j| f(&k[j]))
        };
        let fov = hermite(&|c| Vec3::splat(c.fov_deg)).x.clamp(1.0, 179.0);
        Camera {
            position: hermite(&|c| c.position),
            look_at: hermite(&|c| c.look_at),
            up: Vec3::Y,
            fov_deg: fov,
            shift: glam::Vec2::ZERO,
        }
    }
}

/// The camera of frame number `frame`, at shot fraction `u ∈ [0, 1]` (0 = first frame, 1 =
/// last) and time `t` seconds, for an image of the given `aspect` (width / height), framing `bounds` (the target's box)
/// when automatic.
pub fn camera_at(
    spec: &CameraSpec,
    bounds: &Aabb,
    aspect: f32,
    u: f64,
    t: f64,
    frame: u32,
) -> Camera {
    match spec {
        CameraSpec::Keyframes(k) => k.at(t),
        CameraSpec::Chan(c) => c.at(frame as i64),
        CameraSpec::Usd(c) => c.at(frame, aspect, bounds),
        CameraSpec::Fixed(c) => {
            let eye = orbit(c.position, c.look_at, c.orbit_deg * u as f32);
            Camera {
                position: eye,
                look_at: c.look_at,
                up: c.up,
                fov_deg: c.fov_deg,
                shift: glam::Vec2::ZERO,
            }
        }
        CameraSpec::Auto(c) => {
            let centre = bounds.center().as_vec3();
            let radius = (0.5 * bounds.diagonal()).max(1e-9) as f32;
            let half_v = (0.5 * c.fov_deg).to_radians();
            // Half of the narrower field of view (horizontal in portrait images).
            let half_h = (half_v.tan() * aspect).atan();
            let half = half_v.min(half_h);
            let dist = c.distance * radius / half.sin();
            let (az, el) = (c.azimuth_deg.to_radians(), c.elevation_deg.to_radians());
            let dir = Vec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
            let eye = orbit(centre + dir * dist, centre, c.orbit_deg * u as f32);
            Camera {
                position: eye,
                look_at: centre,
                up: Vec3::Y,
                fov_deg: c.fov_deg,
                shift: glam::Vec2::ZERO,
            }
        }
    }
}

/// `eye` rotated by `deg` degrees around the vertical axis through `pivot` (counter-clockwise
/// seen from above).
fn orbit(eye: Vec3, pivot: Vec3, deg: f32) -> Vec3 {
    let q = glam::Quat::from_rotation_y(deg.to_radians());
    pivot + q * (eye - pivot)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn auto_camera_frames_the_bounding_sphere() {
        let b = Aabb {
            min: DVec3::new(-1.0, 0.0, -1.0),
            max: DVec3::new(1.0, 2.0, 1.0),
        };
        let spec = CameraSpec::Auto(AutoCamera {
            azimuth_deg: 90.0,
            elevation_deg: 0.0,
            ..AutoCamera::default()
        });
        let cam = camera_at(&spec, &b, 16.0 / 9.0, 0.0, 0.0, 1);
        assert!((cam.look_at - Vec3::new(0.0, 1.0, 0.0)).length() < 1e-6);
        // From +X, at radius / sin(fov/2).
        let r = 3f32.sqrt();
        let d = r / (17.5f32).to_radians().sin();
        assert!(
            (cam.position - Vec3::new(d, 1.0, 0.0)).length() < 1e-4,
            "{}",
            cam.position
        );
        // A half orbit puts it on the other side.
        let spec = CameraSpec::Auto(AutoCamera {
            azimuth_deg: 90.0,
            elevation_deg: 0.0,
            orbit_deg: 180.0,
            ..AutoCamera::default()
        });
        let cam = camera_at(&spec, &b, 16.0 / 9.0, 1.0, 1.0, 1);
        assert!((cam.position - Vec3::new(-d, 1.0, 0.0)).length() < 1e-3);
    }

    #[test]
    fn keyframes_pass_through_keys_smoothly() {
        let key = |time: f64, x: f32, fov: f32| CameraKey {
            time,
            position: Vec3::new(x, 1.0, 5.0),
            look_at: Vec3::ZERO,
            fov_deg: fov,
        };
        let k = CameraKeyframes::try_from(vec![
            key(0.0, 0.0, 30.0),
            key(1.0, 2.0, 40.0),
            key(3.0, 2.0, 40.0),
        ])
        .unwrap();
        for c in k.keys() {
            let cam = k.at(c.time);
            assert!((cam.position - c.position).length() < 1e-5);
            assert!((cam.fov_deg - c.fov_deg).abs() < 1e-4);
        }
        // Held before the first and after the last key.
        assert_eq!(k.at(-1.0).position, k.at(0.0).position);
        assert_eq!(k.at(9.0).position, k.at(3.0).position);
        // No jump in velocity at a key: finite differences on both sides agree.
        let d = 1e-3;
        let v1 = (k.at(1.0).position - k.at(1.0 - d).position) / d as f32;
        let v2 = (k.at(1.0 + d).position - k.at(1.0).position) / d as f32;
        assert!(
            (v1 - v2).length() < 0.05 * (1.0 + v1.length()),
            "{v1} vs {v2}"
        );
        assert!(CameraKeyframes::try_from(vec![key(0.0, 0.0, 30.0)]).is_err());
        assert!(CameraKeyframes::try_from(vec![key(1.0, 0.0, 30.0), key(1.0, 1.0, 30.0)]).is_err());
        assert!(
            CameraKeyframes::try_from(vec![key(0.0, 0.0, 30.0), key(1.0, f32::NAN, 30.0)]).is_err()
        );
    }
}
