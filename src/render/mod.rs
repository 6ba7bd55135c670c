//! The cloud renderer: a single-scattering ray marcher through the blob field treated as a
//! density volume, with a sun, a Henyey–Greenstein phase function and an ambient sky.
//!
//! In: [`RenderSettings`] and a frame's blobs (index = identity: a blob keeps its index across
//! frames so that noise anchored to it travels with it; dead or zero-size blobs are skipped).
//! Out: a linear HDR [`Frame`], written as EXR and tone-mapped PNG by [`output`].

pub mod output;
pub mod settings;

pub use settings::{Camera, CloudMaterial, Noise, Quality, RenderSettings, Sky, Sun};

use crate::blobby::Blob;

/// A rendered frame: linear, premultiplied cloud radiance and coverage.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB radiance scattered toward the camera by the cloud (premultiplied), row-major,
    /// top row first.
    pub rgb: Vec<[f32; 3]>,
    /// Coverage `1 − transmittance` per pixel.
    pub alpha: Vec<f32>,
    /// Transmittance-weighted mean depth along the ray (infinity where the ray hits nothing).
    pub depth: Vec<f32>,
}

/// Render one frame. `frame_index` decorrelates per-pixel jitter between frames.
/// Deterministic for a given input at any thread count.
pub fn render_frame(settings: &RenderSettings, blobs: &[Blob], frame_index: u32) -> Frame {
    let _ = (settings, blobs, frame_index);
    todo!("render helper")
}
