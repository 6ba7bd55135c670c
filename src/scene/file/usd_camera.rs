//! A shot's camera from a USD stage: `camera: Usd((file: "shot.usda", prim: "/World/cam"))`,
//! a `UsdGeomCamera` prim as a matchmove package or DCC exports it (`.usda`, `.usdc` or
//! `.usdz`; read by [`super::usd_read`]).
//!
//! - Placement: the prim's world transform (its `xformOp`s and its ancestors'); the camera looks
//!   down its local −Z with +Y up, as nephele's does.
//! - Time: frame number `n` of the shot (`shot.start_frame` on, so a 1001-based plate's
//!   time codes 1001… line up) is read at time code `n · timeCodesPerSecond / shot.fps` — the
//!   frame number itself when the stage's rate is the shot's, or when the stage states no rate
//!   (neither `timeCodesPerSecond` nor `framesPerSecond`). Samples are interpolated linearly
//!   between time codes and held outside them.
//! - Lens: the vertical field of view and the lens shift come from `focalLength`, the apertures
//!   and the aperture offsets after the film back is fitted to the image as USD's fallback
//!   `aspectRatioConformPolicy`, `expandAperture`, does: the aperture grows in one direction
//!   (about its centre, the offsets kept) until its aspect is the image's, so nothing of the
//!   film back is cropped. Offsets make an off-axis window ([`crate::render::Camera::shift`]).
//! - `clippingRange` is read and checked (finite) but does not clip the cloud.
//!
//! Every frame's camera is read when the scene is loaded; an error names the USD file and is
//! located at the scene's `camera.file` (the stage cannot be read) or `camera.prim` (no such
//! prim, not a camera, a lens value that is not positive and finite, a transform op nephele
//! does not read).

use std::path::Path;

use glam::{DVec3, Vec2};
use serde::{Deserialize, Serialize};

use super::usd_read::{CameraSample, Field, StageCamera, UsdReadError};
use crate::geometry::Aabb;
use crate::render::Camera;

/// A camera read from a USD stage (`camera: Usd((file: "shot.usda", prim: "/World/cam"))`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UsdCamera {
    /// The stage (relative paths resolve against the scene file's folder).
    pub file: String,
    /// The absolute path of the `Camera` prim in it.
    pub prim: String,
    /// The camera of each frame of the shot, from the first, read when the scene is loaded
    /// (not written in scene files).
    #[serde(skip)]
    pub frames: Vec<CameraSample>,
    /// The frame number of `frames[0]`.
    #[serde(skip)]
    pub first_frame: u32,
}

impl UsdCamera {
    /// Read the camera of every frame number in `frames` from the stage at `path` (`file`
    /// resolved), for a shot of `fps` frames per second (the time rule of the module doc).
    pub fn load(
        &mut self,
        path: &Path,
        frames: std::ops::RangeInclusive<u32>,
        fps: f64,
    ) -> Result<(), UsdReadError> {
        // The reader is a large third-party parser: should it panic on a malformed file, the
        // scene gets an error naming the file rather than a crash.
        let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let stage = StageCamera::open(path, &self.prim)?;
            let scale = stage.time_codes_per_second().map_or(1.0, |tcps| tcps / fps);
            frames
                .clone()
                .map(|n| stage.sample(time_code(n, scale)))
                .collect::<Result<Vec<_>, _>>()
        }));
        self.frames = read.unwrap_or_else(|_| {
            Err(UsdReadError {
                field: Field::File,
                message: format!(
                    "{}: the USD reader failed on this file (it may be malformed)",
                    path.display()
                ),
            })
        })?;
        self.first_frame = *frames.start();
        Ok(())
    }

    /// The camera of frame number `frame` for an image of `aspect` (width / height). Its
    /// look-at point is on the view axis at the depth of the centre of `bounds` (the target's
    /// box; one unit ahead when that centre is not in front), where the renderer measures a
    /// pixel's footprint.
    pub fn at(&self, frame: u32, aspect: f32, bounds: &Aabb) -> Camera {
        let k = frame.saturating_sub(self.first_frame) as usize;
        let Some(s) = self.frames.get(k.min(self.frames.len().saturating_sub(1))) else {
            // Loading reads every frame; an unloaded camera looks down −Z from the origin.
            return lens_camera(DVec3::ZERO, DVec3::NEG_Z, DVec3::Y, 1.0, [0.0; 2]);
        };
        let eye = s.to_world.transform_point3(DVec3::ZERO);
        let forward = (-s.to_world.transform_vector3(DVec3::Z)).normalize();
        let up = s.to_world.transform_vector3(DVec3::Y);
        let depth = (bounds.center() - eye).dot(forward);
        let depth = if depth > 0.0 { depth } else { 1.0 };
        let (tan_half, shift) = fit(s, aspect as f64);
        lens_camera(eye, forward * depth, up, tan_half, shift)
    }
}

/// The time code of frame number `frame` on a stage whose rate is `scale` times the shot's.
pub fn time_code(frame: u32, scale: f64) -> f64 {
    frame as f64 * scale
}

/// `tan` of half the vertical field of view and the lens shift (in half image heights) of the
/// sample's film back fitted to an image of `aspect` by `expandAperture`.
pub fn fit(s: &CameraSample, aspect: f64) -> (f64, [f64; 2]) {
    let [h, v] = s.aperture;
    // Wider than the image: keep the width, grow the height; else keep the height.
    let v = if h / v > aspect { h / aspect } else { v };
    let [ho, vo] = s.aperture_offset;
    (0.5 * v / s.focal_length, [2.0 * ho / v, 2.0 * vo / v])
}

fn lens_camera(eye: DVec3, ahead: DVec3, up: DVec3, tan_half: f64, shift: [f64; 2]) -> Camera {
    Camera {
        position: eye.as_vec3(),
        look_at: (eye + ahead).as_vec3(),
        up: up.as_vec3(),
        fov_deg: (2.0 * tan_half.atan()).to_degrees() as f32,
        shift: Vec2::new(shift[0] as f32, shift[1] as f32),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat4;

    fn sample(aperture: [f64; 2], offset: [f64; 2]) -> CameraSample {
        CameraSample {
            to_world: DMat4::IDENTITY,
            focal_length: 10.0,
            aperture,
            aperture_offset: offset,
            clipping_range: [1.0, 1e6],
        }
    }

    #[test]
    fn the_film_back_expands_to_the_image() {
        // A 4:3 back on a 16:9 image keeps its height; a 2.39:1 back keeps its width.
        let (t, shift) = fit(&sample([24.0, 18.0], [0.0; 2]), 16.0 / 9.0);
        assert!((t - 0.9).abs() < 1e-12);
        assert_eq!(shift, [0.0, 0.0]);
        let (t, _) = fit(&sample([23.9, 10.0], [0.0; 2]), 16.0 / 9.0);
        assert!((t - 0.5 * 23.9 * 9.0 / 16.0 / 10.0).abs() < 1e-12);
        // Offsets in half heights of the fitted back.
        let (_, shift) = fit(&sample([24.0, 18.0], [3.0, -1.8]), 16.0 / 9.0);
        assert!((shift[0] - 1.0 / 3.0).abs() < 1e-12 && (shift[1] + 0.2).abs() < 1e-12);
        assert_eq!(time_code(1001, 1.0), 1001.0);
        assert_eq!(time_code(1001, 2.0), 2002.0);
    }
}
