//! One frame's render request: everything the renderer needs for a frame of a shot, built in
//! one place ([`Shot::frame_request`]) for the shot's run, the CLI's previews and the Python
//! package alike.

use crate::animate::VelocityField;
use crate::blobby::Blob;
use crate::render::{self, Film, Frame, FrameRenderer, RenderSettings, Shutter};
use crate::scene::{SceneError, Shot};

/// A frame of a shot as the renderer takes it.
#[derive(Clone, Debug)]
pub struct FrameRequest {
    /// 0-based frame index in the shot.
    pub k: u32,
    /// Frame number (from `shot.start_frame`).
    pub frame: u32,
    /// The frame's camera, light, look, size and quality.
    pub settings: RenderSettings,
    /// The frame's blobs.
    pub blobs: Vec<Blob>,
    /// The open shutter's time samples, when the shutter is open and the cloud moves in it.
    pub shutter: Option<Shutter>,
    /// The cloud's velocity at the frame's time (the VDB's `vel`), when the shot writes motion
    /// vectors (`output.motion_vectors`).
    pub velocity: Option<VelocityField>,
    /// The shot's frame rate.
    pub fps: f64,
}

impl FrameRequest {
    /// Render it into `film` with `renderer` (which reuses what it can from the frame before:
    /// a hold the last frame, a still cloud its light grid; same bits either way).
    pub fn render_into<'r>(&self, renderer: &'r mut FrameRenderer, film: &Film) -> &'r Frame {
        renderer.render(&self.settings, &self.blobs, &self.options(film))
    }

    /// The renderer's options for it, into `film`.
    pub fn options<'a>(&'a self, film: &'a Film) -> render::FrameOptions<'a> {
        render::FrameOptions {
            shutter: self.shutter.as_ref(),
            film,
            motion: self.velocity.as_ref().map(|v| render::MotionSource {
                velocity: v,
                fps: self.fps,
            }),
        }
    }
}

impl Shot {
    /// The request of 0-based frame `k`: its settings, its blobs and its open shutter.
    pub fn frame_request(&self, k: u32) -> Result<FrameRequest, SceneError> {
        let settings = self.settings(k)?;
        let shutter = self.shutter(k, settings.quality.time_samples)?;
        let file = &self.scene().file;
        let velocity = if file.output.motion_vectors {
            // The direction's velocity: wind and retime included, as the VDB's `vel`.
            let prep = self.prepared()?;
            let t = prep.plan.timeline().time(k as usize);
            Some(prep.direction.velocity(&prep.plan, t))
        } else {
            None
        };
        Ok(FrameRequest {
            k,
            frame: self.number(k),
            blobs: self.blobs(k)?,
            settings,
            shutter,
            velocity,
            fps: file.shot.fps,
        })
    }
}
