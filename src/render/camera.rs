//! Pinhole camera rays and per-tile view frusta.
//!
//! In: [`Camera`] (look-at, vertical field of view, an optional lens shift) and the image size. Out: unit ray
//! directions through pixel positions (pixel `(x, y)` covers `[x, x+1) × [y, y+1)`, top row
//! first, +Y up, right-handed: the camera looks down its −Z), and [`Frustum`]s bounding the
//! rays of a tile, used to cull blobs once per tile; and the ray–ellipsoid intersection the
//! media use.

use glam::{Vec2, Vec3, Vec3A};

/// A pinhole camera in world space (the model's units), +Y up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Point the camera looks at.
    pub look_at: Vec3,
    /// Up hint (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_deg: f32,
    /// Lens shift: the image centre's offset from the view axis, in units of half the image
    /// height on the image plane (`tan(fov/2)` at distance 1), +x right, +y up. Zero (every
    /// camera but a USD one with aperture offsets) is the centred pinhole, bit for bit as
    /// before the shift existed; a shifted window is an off-axis frustum (USD's
    /// `horizontalApertureOffset`/`verticalApertureOffset`).
    pub shift: Vec2,
}

/// A ray `origin + t·dir`, `dir` unit length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3A,
    /// Unit direction.
    pub dir: Vec3A,
}

impl Ray {
    /// The point at parameter `t` (a distance, as `dir` is unit).
    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.dir * t
    }
}

/// Parameters `(t0, t1)` with `t0 ≥ 0` where the ray `o + t·d` is inside the unit ball
/// `|p| < 1`; `o` and `d` are in the ellipsoid's unit frame (`d` need not be unit length, and
/// `t` is then the same parameter as in world space). `None` on a miss, a tangent touch, a ball
/// entirely behind the origin, or a zero direction (its own branch: the ray does not move).
#[inline]
pub(crate) fn ray_ellipsoid(local_origin: Vec3A, local_dir: Vec3A) -> Option<(f32, f32)> {
    let a = local_dir.length_squared();
    if a <= f32::MIN_POSITIVE {
        return None;
    }
    let b = local_origin.dot(local_dir);
    let c = local_origin.length_squared() - 1.0;
    let disc = b * b - a * c;
    if disc <= 0.0 {
        return None;
    }
    // Numerically stable roots: q = −(b + sign(b)√disc), t = q/a and c/q.
    let q = -(b + disc.sqrt().copysign(b));
    let (r0, r1) = (q / a, if q != 0.0 { c / q } else { q / a });
    let (t0, t1) = (r0.min(r1), r0.max(r1));
    (t1 > 0.0).then_some((t0.max(0.0), t1))
}

/// The camera's orthonormal frame and image-plane scale.
#[derive(Clone, Copy, Debug)]
pub struct CameraRays {
    /// Eye position.
    pub position: Vec3A,
    /// Unit view direction (the optical axis).
    pub forward: Vec3A,
    /// The ray through the image centre before normalising: `forward`, plus the lens shift.
    axis: Vec3A,
    right: Vec3A,
    up: Vec3A,
    /// `tan(fov/2)`: half the image-plane height at distance 1.
    tan_half: f32,
    width: f32,
    height: f32,
}

impl CameraRays {
    /// The frame for `camera` and a `width × height` image. Degenerate input gets a fallback:
    /// `look_at == position` looks down −Z; an `up` parallel to the view uses +Z (or +X) as up.
    pub fn new(camera: &Camera, width: u32, height: u32) -> CameraRays {
        let position = Vec3A::from(camera.position);
        let forward = (Vec3A::from(camera.look_at) - position)
            .try_normalize()
            .unwrap_or(Vec3A::NEG_Z);
        let right = [Vec3A::from(camera.up), Vec3A::Y, Vec3A::Z, Vec3A::X]
            .into_iter()
            .find_map(|up| forward.cross(up).try_normalize())
            .unwrap_or(Vec3A::X);
        let up = right.cross(forward);
        let fov = camera.fov_deg.clamp(0.1, 179.0).to_radians();
        let tan_half = (0.5 * fov).tan();
        // Only a shifted lens moves the axis: a zero shift keeps `forward` bit for bit (adding
        // zero terms could turn a −0 component into +0, and with it a ray's reciprocal).
        let axis = if camera.shift == Vec2::ZERO {
            forward
        } else {
            forward + (right * camera.shift.x + up * camera.shift.y) * tan_half
        };
        CameraRays {
            position,
            forward,
            axis,
            right,
            up,
            tan_half,
            width: width.max(1) as f32,
            height: height.max(1) as f32,
        }
    }

    /// Unit direction through image position `(px, py)` in pixels (`(0, 0)` = top-left corner
    /// of the image, `(w, h)` = bottom-right).
    #[inline]
    pub fn dir(&self, px: f32, py: f32) -> Vec3A {
        let sy = (1.0 - 2.0 * py / self.height) * self.tan_half;
        let sx = (2.0 * px / self.width - 1.0) * self.tan_half * self.width / self.height;
        (self.axis + self.right * sx + self.up * sy).normalize()
    }

    /// The ray through the centre of pixel `(x, y)`.
    #[inline]
    pub fn pixel_ray(&self, x: u32, y: u32) -> Ray {
        self.ray(x as f32 + 0.5, y as f32 + 0.5)
    }

    /// The ray through image position `(px, py)` in pixels (see [`CameraRays::dir`]).
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        Ray {
            origin: self.position,
            dir: self.dir(px, py),
        }
    }

    /// Image position in pixels of the world point `p` (the inverse of [`CameraRays::dir`]:
    /// `(0, 0)` the top-left corner, y down); `None` unless `p` lies in front of the eye.
    #[inline]
    pub fn project(&self, p: Vec3A) -> Option<glam::Vec2> {
        let c = p - self.position;
        let z = c.dot(self.forward);
        if z.is_nan() || z <= 0.0 {
            return None;
        }
        let (sx, sy) = (c.dot(self.right) / z, c.dot(self.up) / z);
        Some(glam::Vec2::new(
            (sx * self.height / (self.tan_half * self.width) + 1.0) * 0.5 * self.width,
            (1.0 - sy / self.tan_half) * 0.5 * self.height,
        ))
    }

    /// The frustum of the pixel rectangle `[x0, x1) × [y0, y1)`.
    pub(crate) fn frustum(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> Frustum {
        let (x0, y0, x1, y1) = (x0 as f32, y0 as f32, x1 as f32, y1 as f32);
        let c = [
            self.dir(x0, y0),
            self.dir(x1, y0),
            self.dir(x1, y1),
            self.dir(x0, y1),
        ];
        let mid = self.dir(0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let mut planes = [Vec3A::ZERO; 4];
        for (e, plane) in planes.iter_mut().enumerate() {
            let n = c[e].cross(c[(e + 1) % 4]).normalize_or_zero();
            *plane = if n.dot(mid) < 0.0 { -n } else { n };
        }
        Frustum {
            apex: self.position,
            forward: self.forward,
            planes,
        }
    }
}

/// Four side planes through the eye (inward normals) and the view direction.
#[derive(Clone, Copy, Debug)]
pub struct Frustum {
    /// The eye.
    pub apex: Vec3A,
    /// Unit view direction (culls what is behind the eye).
    pub forward: Vec3A,
    /// Inward unit normals of the side planes.
    pub planes: [Vec3A; 4],
}

impl Frustum {
    /// The frustum that may contain everything (rays of any direction: shadow rays).
    pub const EVERYTHING: Frustum = Frustum {
        apex: Vec3A::ZERO,
        forward: Vec3A::ZERO,
        planes: [Vec3A::ZERO; 4],
    };

    /// Conservative: false only when the ball `(center, radius)` is certainly outside.
    #[inline]
    pub fn may_contain_ball(&self, center: Vec3A, radius: f32) -> bool {
        let v = center - self.apex;
        v.dot(self.forward) > -radius && self.planes.iter().all(|n| n.dot(v) > -radius)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{Vec2, Vec3};

    #[test]
    fn ray_ellipsoid_cases() {
        // Through the centre from outside.
        let (t0, t1) = ray_ellipsoid(Vec3A::new(0.0, 0.0, -3.0), Vec3A::Z).unwrap();
        assert!((t0 - 2.0).abs() < 1e-6 && (t1 - 4.0).abs() < 1e-6);
        // Non-unit direction: t scales inversely.
        let (t0, t1) = ray_ellipsoid(Vec3A::new(0.0, 0.0, -3.0), Vec3A::Z * 2.0).unwrap();
        assert!((t0 - 1.0).abs() < 1e-6 && (t1 - 2.0).abs() < 1e-6);
        // From inside: starts at 0.
        let (t0, t1) = ray_ellipsoid(Vec3A::new(0.5, 0.0, 0.0), Vec3A::X).unwrap();
        assert!(t0 == 0.0 && (t1 - 0.5).abs() < 1e-6);
        // Behind, miss, zero direction.
        assert!(ray_ellipsoid(Vec3A::new(0.0, 0.0, 3.0), Vec3A::Z).is_none());
        assert!(ray_ellipsoid(Vec3A::new(0.0, 1.5, -3.0), Vec3A::Z).is_none());
        assert!(ray_ellipsoid(Vec3A::ZERO, Vec3A::ZERO).is_none());
    }

    #[test]
    fn project_inverts_the_pixel_rays() {
        let cam = CameraRays::new(
            &Camera {
                position: Vec3::new(1.0, 2.0, 3.0),
                look_at: Vec3::new(-2.0, 0.5, -4.0),
                up: Vec3::Y,
                fov_deg: 40.0,
                shift: glam::Vec2::ZERO,
            },
            320,
            180,
        );
        for (px, py) in [(0.5, 0.5), (160.0, 90.0), (300.25, 17.75), (12.0, 170.0)] {
            let ray = cam.ray(px, py);
            let p = cam.project(ray.at(7.5)).unwrap();
            assert!(
                (p.x - px).abs() < 1e-3 && (p.y - py).abs() < 1e-3,
                "{p} vs {px},{py}"
            );
        }
        assert_eq!(cam.project(cam.position - cam.forward), None);
    }

    #[test]
    fn centre_pixel_looks_at_target_and_rows_go_down() {
        let cam = Camera {
            position: Vec3::new(0.0, 0.0, 5.0),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov_deg: 40.0,
            shift: Vec2::ZERO,
        };
        let rays = CameraRays::new(&cam, 64, 36);
        assert!((rays.dir(32.0, 18.0) - Vec3A::NEG_Z).length() < 1e-6);
        // Top edge is 20° above the axis, right edge further right (+X).
        let top = rays.dir(32.0, 0.0);
        assert!((top.y.atan2(-top.z).to_degrees() - 20.0).abs() < 1e-3);
        assert!(rays.dir(64.0, 18.0).x > 0.0);
        let f = rays.frustum(0, 0, 16, 16);
        assert!(f.may_contain_ball(rays.dir(8.0, 8.0) * 3.0 + rays.position, 0.01));
        assert!(!f.may_contain_ball(Vec3A::new(3.0, -3.0, 0.0), 0.1));
        assert!(!f.may_contain_ball(Vec3A::new(0.0, 0.0, 9.0), 0.5));
    }

    #[test]
    fn a_lens_shift_moves_the_window_off_axis() {
        let cam = Camera {
            position: Vec3::ZERO,
            look_at: Vec3::NEG_Z,
            up: Vec3::Y,
            fov_deg: 90.0,
            shift: Vec2::new(0.5, -0.25),
        };
        let rays = CameraRays::new(&cam, 200, 100);
        // The image centre is shifted by half of half the height right and a quarter down.
        let c = rays.dir(100.0, 50.0);
        assert!((c.x / -c.z - 0.5).abs() < 1e-6 && (c.y / -c.z + 0.25).abs() < 1e-6);
        // The top edge is one half-height above the centre, the right edge one half-width.
        let top = rays.dir(100.0, 0.0);
        assert!((top.y / -top.z - 0.75).abs() < 1e-6);
        let right = rays.dir(200.0, 50.0);
        assert!((right.x / -right.z - 2.5).abs() < 1e-6);
        // The optical axis (depth, culling) stays the view direction.
        assert_eq!(rays.forward, Vec3A::NEG_Z);
    }
}
