//! The scene camera per frame: automatic framing of the target or a fixed camera, with an
//! optional orbit around the vertical axis over the shot.

use glam::Vec3;

use super::file::CameraSpec;
use crate::geometry::Aabb;
use crate::render::Camera;

/// The camera at shot fraction `u ∈ [0, 1]` (0 = first frame, 1 = last) for an image of the
/// given `aspect` (width / height), framing `bounds` (the target's box) when automatic.
pub fn camera_at(spec: &CameraSpec, bounds: &Aabb, aspect: f32, u: f64) -> Camera {
    match spec {
        CameraSpec::Fixed(c) => {
            let eye = orbit(c.position, c.look_at, c.orbit_deg * u as f32);
            Camera {
                position: eye,
                look_at: c.look_at,
                up: c.up,
                fov_deg: c.fov_deg,
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
    use crate::scene::file::AutoCamera;
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
        let cam = camera_at(&spec, &b, 16.0 / 9.0, 0.0);
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
        let cam = camera_at(&spec, &b, 16.0 / 9.0, 1.0);
        assert!((cam.position - Vec3::new(-d, 1.0, 0.0)).length() < 1e-3);
    }
}
