//! A rendered frame: what the integrator fills and the outputs write (its own file, so the
//! writers in [`crate::render::output`] need nothing from the integrator above them).

use crate::render::output::cryptomatte::IdMattes;
use crate::render::output::film::Region;

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
    /// Transmittance-weighted mean distance from the eye along the pixel's ray (infinity where
    /// the ray hits nothing).
    pub depth: Vec<f32>,
    /// The render passes, when rendered with them ([`crate::render::Film::passes`]).
    pub passes: Option<Box<Passes>>,
    /// The ID mattes, when rendered with them ([`crate::render::Film::mattes`]).
    pub mattes: Option<Box<IdMattes>>,
    /// The motion vectors, when rendered with them ([`crate::render::Film::motion`]): each
    /// pixel's forward motion over one frame in pixels, `[u, v]` with `u` to the right and `v`
    /// **up**, the cloud's velocity averaged along the ray by each sample's share of the
    /// opacity; `[0, 0]` where there is no cloud. Written as the EXR's `forward.u`, `forward.v`.
    pub motion: Option<Vec<[f32; 2]>>,
    /// The `holdout` layer, when the shot has holdouts: the share of each pixel's rays that a
    /// holdout stopped (1 where one covers the pixel, fractional at its edges).
    pub holdout: Option<Vec<f32>>,
    /// The `shadow` layer (the shadow-catcher pass), when asked for: the sun's transmittance
    /// through the cloud from the surface each pixel sees (the ground plane or a holdout), 1
    /// where it sees none or the cloud casts no shadow there.
    pub shadow: Option<Vec<f32>>,
    /// The `shadow_total` layer (RGB), with `shadow`: the light the cloud lets through to the
    /// surface each pixel sees from the sun **and** the sky, over the light that reaches it
    /// without the cloud (`integrator/shadow_total/`); 1 where it sees none.
    pub shadow_total: Option<Vec<[f32; 3]>>,
    /// The window rendered, when only a region was ([`crate::render::Film::region`]); the pixels outside it
    /// are empty (no cloud).
    pub region: Option<Region>,
}

/// A frame's light by component, premultiplied like [`Frame::rgb`]; `sun + sky + multiple` is
/// the frame's RGB up to rounding.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Passes {
    /// Sunlight scattered once.
    pub sun: Vec<[f32; 3]>,
    /// Sky light scattered once (the sky cells, and the forward lobe straight through).
    pub sky: Vec<[f32; 3]>,
    /// The multiple-scattering approximation (sun and sky octaves beyond the first).
    pub multiple: Vec<[f32; 3]>,
}

impl Passes {
    /// Black passes of `n` pixels.
    pub(crate) fn zeros(n: usize) -> Passes {
        Passes {
            sun: vec![[0.0; 3]; n],
            sky: vec![[0.0; 3]; n],
            multiple: vec![[0.0; 3]; n],
        }
    }
}
