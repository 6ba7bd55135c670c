//! The motion-vector pass: each march sample's forward screen motion over one frame, weighted
//! by its share of the pixel's opacity (what it absorbs, `T·(1 − e^{−σh})`), averaged over the
//! pixel's rays ([`MotionSum`]).
//!
//! A sample at `x` whose density moves at `v(x)` (world units per second, the
//! [`CloudVelocity`] the VDB's `vel` grid is sampled from) is at `x + v/fps` one frame later;
//! its motion is the difference of the two points' image positions ([`ScreenMotion`]), in
//! pixels: `u` to the right, `v` **up** (Nuke's convention: its image's y axis points up). The
//! pixel's vector is `Σ absorbed·d / Σ absorbed` over its rays' samples; 0 where no ray met the
//! cloud.

use glam::{DVec3, Vec2, Vec3A};

use crate::render::camera::CameraRays;

/// The velocity of a cloud's density at a point (world units per second): what the
/// motion-vector pass projects. [`crate::animate::VelocityField`] is the blobs' (the VDB's
/// `vel`).
pub trait CloudVelocity: Sync + std::fmt::Debug {
    /// Velocity of the density at `x`, world units per second.
    fn velocity_at(&self, x: DVec3) -> DVec3;
}

/// Where a frame's motion vectors come from: the cloud's velocity and the shot's frame rate
/// (the vectors are per frame, the velocity per second).
#[derive(Clone, Copy, Debug)]
pub struct MotionSource<'a> {
    /// The cloud's velocity at the frame's time.
    pub velocity: &'a dyn CloudVelocity,
    /// Frames per second.
    pub fps: f64,
}

/// A frame's camera and its cloud's velocity: the screen motion of a point over one frame.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ScreenMotion<'a> {
    cam: CameraRays,
    velocity: &'a dyn CloudVelocity,
    /// Seconds per frame.
    frame: f64,
}

impl<'a> ScreenMotion<'a> {
    /// The motion of `source`'s cloud as seen through `cam`.
    pub(crate) fn new(cam: CameraRays, source: &MotionSource<'a>) -> ScreenMotion<'a> {
        ScreenMotion {
            cam,
            velocity: source.velocity,
            frame: if source.fps > 0.0 {
                1.0 / source.fps
            } else {
                0.0
            },
        }
    }

    /// The forward motion of the point `x` over one frame, in pixels (`u` right, `v` up); 0
    /// when either end is not in front of the camera.
    #[inline]
    pub(crate) fn displacement(&self, x: Vec3A) -> Vec2 {
        let v = self.velocity.velocity_at(x.as_dvec3());
        let moved = Vec3A::from((v * self.frame).as_vec3()) + x;
        match (self.cam.project(x), self.cam.project(moved)) {
            (Some(a), Some(b)) => Vec2::new(b.x - a.x, a.y - b.y),
            _ => Vec2::ZERO,
        }
    }
}

/// One pixel's motion being summed over its rays' samples: `Σ absorbed·d`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct MotionSum<'a> {
    screen: Option<&'a ScreenMotion<'a>>,
    sum: Vec2,
}

impl<'a> MotionSum<'a> {
    /// Nothing summed yet; without `screen`, nothing is (the vectors stay 0).
    #[inline]
    pub(crate) fn new(screen: Option<&'a ScreenMotion<'a>>) -> MotionSum<'a> {
        MotionSum {
            screen,
            sum: Vec2::ZERO,
        }
    }

    /// A sample at `x` that absorbed `absorbed` of the pixel's light.
    #[inline]
    pub(crate) fn add(&mut self, x: Vec3A, absorbed: f32) {
        if let Some(s) = self.screen {
            self.sum += s.displacement(x) * absorbed;
        }
    }

    /// The pixel's vector after `rays` rays of mean coverage `alpha`: the opacity-weighted
    /// mean of its samples' motions (0 where nothing was met).
    #[inline]
    pub(crate) fn vector(&self, rays: u32, alpha: f32) -> [f32; 2] {
        let weight = rays as f32 * alpha;
        if weight > 0.0 {
            (self.sum / weight).to_array()
        } else {
            [0.0; 2]
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{DQuat, DVec3, Vec3};

    use crate::animate::VelocityField;
    use crate::blobby::Blob;
    use crate::render::{
        Camera, CloudMaterial, Film, FrameOptions, FrameRenderer, MotionSource, Quality,
        RenderSettings, Sky, Sun,
    };

    const FPS: f64 = 24.0;

    /// A lumpy cloud of overlapping balls about `o`, about 1.2 units across.
    fn cloud(o: DVec3) -> Vec<Blob> {
        (0..9)
            .map(|i| {
                let a = i as f64 * 0.9;
                let c = o + DVec3::new(0.4 * a.cos(), 0.3 * (1.7 * a).sin(), 0.35 * a.sin());
                crate::animate::sphere_blob(c, 0.3 + 0.03 * (i % 3) as f64)
            })
            .collect()
    }

    fn settings(camera: Camera) -> RenderSettings {
        RenderSettings {
            width: 72,
            height: 48,
            camera,
            sun: Sun::default(),
            sky: Sky::default(),
            cloud: CloudMaterial::default(),
            exposure: 0.0,
            length_scale: 1.0,
            seed: 3,
            time: 0.0,
            quality: Quality::preview(),
            base: None,
            surfaces: None,
        }
    }

    /// The blobs moved rigidly by `f(t)` a small time `h` before and after: the velocity field
    /// of that motion (centred difference).
    fn field(blobs: &[Blob], f: impl Fn(&Blob, f64) -> Blob) -> VelocityField {
        let h = 1e-3;
        let at = |t: f64| blobs.iter().map(|b| f(b, t)).collect::<Vec<_>>();
        VelocityField::new(&at(-h), blobs, &at(h), 2.0 * h)
    }

    /// The frame with and without motion vectors: the beauty is the same bits.
    fn render(
        settings: &RenderSettings,
        blobs: &[Blob],
        v: &VelocityField,
    ) -> crate::render::Frame {
        let film = Film {
            motion: true,
            ..Film::default()
        };
        let options = FrameOptions {
            shutter: None,
            film: &film,
            motion: Some(MotionSource {
                velocity: v,
                fps: FPS,
            }),
        };
        let (frame, _) = FrameRenderer::render_once(settings, blobs, &options);
        let (plain, _) = FrameRenderer::render_once(settings, blobs, &FrameOptions::default());
        assert!(plain.motion.is_none());
        assert!(
            frame.rgb == plain.rgb && frame.alpha == plain.alpha && frame.depth == plain.depth,
            "the motion vectors changed the beauty"
        );
        frame
    }

    /// A cloud translating across the view at a known speed, seen from far (a nearly
    /// orthographic view, so every depth of it moves alike on screen): its speed in pixels per
    /// frame, within 0.1 px wherever alpha > 0.5, and 0 where there is no cloud.
    #[test]
    fn a_translating_cloud_moves_at_its_speed_in_pixels_per_frame() {
        let o = DVec3::new(1.0, 2.0, -3.0);
        let eye = o + DVec3::new(0.0, 0.0, 120.0);
        let camera = Camera {
            position: eye.as_vec3(),
            look_at: o.as_vec3(),
            up: Vec3::Y,
            fov_deg: 1.2,
            shift: glam::Vec2::ZERO,
        };
        let s = settings(camera);
        // Pixels per world unit at the cloud's distance.
        let scale = 48.0 / (2.0 * 120.0 * (0.6f64).to_radians().tan());
        // 4.5 px right and 2.5 px down a frame, and a little toward the camera.
        let speed = DVec3::new(4.5, -2.5, 0.2) / scale * FPS;
        let blobs = cloud(o);
        let v = field(&blobs, |b, t| Blob {
            center: b.center + speed * t,
            ..*b
        });
        let frame = render(&s, &blobs, &v);
        let motion = frame.motion.as_ref().expect("motion vectors");
        let (mut n, mut worst) = (0, 0.0f32);
        for (i, m) in motion.iter().enumerate() {
            if frame.alpha[i] > 0.5 {
                n += 1;
                let e = (m[0] - 4.5).abs().max((m[1] + 2.5).abs());
                worst = worst.max(e);
            } else if frame.alpha[i] == 0.0 {
                assert_eq!(*m, [0.0, 0.0], "pixel {i} has no cloud");
            }
        }
        eprintln!("translation: {n} pixels with alpha > 0.5, worst error {worst:.4} px");
        assert!(n > 200, "{n} pixels covered");
        assert!(worst < 0.1, "worst error {worst} px");
    }

    /// A cloud spinning about the camera's axis, in perspective: every point of a ray through
    /// the image offset `r` (pixels, y up) from the axis moves by `ω·dt·(−r_y, r_x)` on
    /// screen whatever its depth.
    #[test]
    fn a_cloud_spinning_about_the_view_axis_turns_on_screen() {
        let o = DVec3::new(0.5, 0.0, 0.0);
        let camera = Camera {
            position: (o + DVec3::new(0.0, 0.0, 4.0)).as_vec3(),
            look_at: o.as_vec3(),
            up: Vec3::Y,
            fov_deg: 30.0,
            shift: glam::Vec2::ZERO,
        };
        let s = settings(camera);
        // 0.1 rad a frame: 3.6 px at the image's sides.
        let omega = 0.1 * FPS;
        let blobs = cloud(o);
        let v = field(&blobs, |b, t| {
            let q = DQuat::from_rotation_z(omega * t);
            Blob {
                center: o + q * (b.center - o),
                rotation: q * b.rotation,
                ..*b
            }
        });
        let frame = render(&s, &blobs, &v);
        let motion = frame.motion.as_ref().expect("motion vectors");
        let (mut n, mut worst) = (0, 0.0f64);
        let step = omega / FPS;
        for (i, m) in motion.iter().enumerate() {
            if frame.alpha[i] > 0.5 {
                let (x, y) = ((i % 72) as f64 + 0.5, (i / 72) as f64 + 0.5);
                let (rx, ry) = (x - 36.0, 24.0 - y);
                let want = [-step * ry, step * rx];
                let e = (m[0] as f64 - want[0])
                    .abs()
                    .max((m[1] as f64 - want[1]).abs());
                worst = worst.max(e);
                n += 1;
            }
        }
        eprintln!("rotation: {n} pixels with alpha > 0.5, worst error {worst:.4} px");
        assert!(n > 200, "{n} pixels covered");
        assert!(worst < 0.1, "worst error {worst} px");
    }
}
