//! The cloud renderer: a single-scattering ray marcher through the blob field treated as a
//! density volume, with a sun, a Henyey–Greenstein phase function and an ambient sky.
//!
//! In: [`RenderSettings`] and a frame's blobs (index = identity: a blob keeps its index across
//! frames so that noise anchored to it travels with it; dead or zero-size blobs are skipped).
//! Out: a linear HDR [`Frame`], written as EXR and tone-mapped PNG by [`output`].
//!
//! # The front
//!
//! What code outside the crate (the CLI, the Python package, the integration tests) may use;
//! everything else in `render/` is `pub(crate)`, its sub-modules included, except [`output`].
//!
//! - **Frames of blobs**: [`FrameRenderer`] (the one frame pipeline, with the shot's reuse) and
//!   [`render_frame`] (one frame of it, once), with [`FrameOptions`]: the shutter ([`Shutter`],
//!   its [`TimeSample`]s), the film ([`Film`]: a [`Region`], passes, ID [`Mattes`], motion
//!   vectors) and the cloud's velocity for the motion vectors ([`MotionSource`], any
//!   [`CloudVelocity`]; `march/motion.rs`). Out: a
//!   [`Frame`] (its [`Passes`] and [`IdMattes`]) and a [`RenderReport`] ([`Reuse`],
//!   [`BlurReport`]). [`FrameIndex`] is a frame's 0-based place in its shot.
//! - **What is seen**: [`RenderSettings`]: [`Camera`], [`Sun`], [`Sky`], [`CloudMaterial`]
//!   ([`NoiseSettings`], a flat base [`BasePlane`] from [`CumulusBase`]), [`Quality`] from a
//!   [`QualityPreset`]. [`CameraRays`] is the camera's ray through any point of the image (what
//!   the EXR's and the USD stage's cameras are checked against), [`SkyDome`] the sky's radiance
//!   (what a frame is composited over), [`phase`] the cloud's phase function.
//! - **Media of one's own**: the integrator alone, [`render_medium`] (and
//!   [`render_medium_unshaded`], coverage only), marches any [`Medium`] (pbrt's contract:
//!   intervals and extinction along a [`Ray`], culled per tile by a [`Frustum`]), lit by any
//!   [`ShadowDepths`]: [`LightDepths`] toward the sun and the [`SKY_DIRECTIONS`] sky cells
//!   ([`sky_directions`]), from a [`LightGrid`] built from a medium, exactly through a
//!   [`Homogeneous`] medium ([`HomogeneousLights`]), or none ([`Unshadowed`]). Media here: the
//!   blob cloud, [`BlobMedium`], and [`Homogeneous`] in a [`Shape`], for closed forms.
//! - **The shot's surfaces**: [`Surfaces`] (`surfaces.rs`): holdouts ([`HoldoutMesh`], cast
//!   through `bvh.rs`) that stop the camera's rays and, with `shadows`, the light grid's light;
//!   the ground plane ([`Ground`]) of the `shadow` pass (`integrator/surface_rays.rs`).
//! - **Files**: [`output`]: EXR (with the camera and provenance of [`output::FrameMetadata`]),
//!   PNG, the EXR's colour space, Cryptomatte ids.
//!
//! # Inside
//!
//! Where is a frame rendered? In one place, [`FrameRenderer`] (`integrator/frame_renderer.rs`):
//! the blobs become a density-only [`Medium`] ([`BlobMedium::new`], `medium/`); its light-grid
//! copy ([`BlobMedium::for_light_grid`]) feeds the per-frame [`LightGrid`] (`light/`: optical
//! depth toward the sun, `light/sun_depth.rs`, and toward the sky cells, `light/sky_depth.rs`);
//! the integrator (`integrator/`) marches every pixel through the blob supports only (tile
//! frustum culling, then per-ray ellipsoid intervals), evaluating the noisy density
//! (`medium/density.rs`, `medium/noise.rs`) and the lighting (`light/shading.rs`: phase
//! functions in `light/phase.rs`, the sky dome in `light/sky_dome.rs`, the depths from any
//! [`ShadowDepths`]). The shot's reuse (holds, a still cloud), the shutter and the film
//! ([`FrameOptions`]) are its options; the shot loop, `Shot::render_frame`, the statistics, the
//! preview and motion blur all call it.
//!
//! The folders: `camera.rs`, `sampler.rs`, `integrator/` (march, tiles, motion blur, reuse),
//! `medium/` (density, blobs, noise, lattice), `light/` (grid, sun and sky depths, sky dome,
//! phase, shading), `output/` (film, EXR, PNG, Cryptomatte, colour).
//!
//! Where is sunlight computed? Its shadowing in `light/sun_depth.rs` (assembled with the sky's
//! in `light/grid.rs`), its scattering toward the eye in `light/shading.rs`.
//!
//! References:
//! - L. G. Henyey, J. L. Greenstein (1941), "Diffuse radiation in the galaxy", ApJ 93, 70–83.
//! - M. Wrenninge, C. Kulla, V. Lundqvist (2013), "Oz: the great and volumetric", SIGGRAPH Talks
//!   (multiple-scattering octaves).
//! - S. Hillaire (2015/2016), "Physically based sky, atmosphere and cloud rendering in
//!   Frostbite" (energy-conserving step integration, the octave scheme in real time).
//! - K. Perlin (2002), "Improving noise", SIGGRAPH (gradient noise).
//! - M. Wrenninge (2012), *Production Volume Rendering* (pyroclastic displacement by `|noise|`:
//!   the billows of `Billows`, `medium/noise.rs`).
//! - A. Bouthors, F. Neyret (2004), "Modeling clouds shape", Eurographics short papers (cumulus as
//!   puffs on puffs, each level smaller: octaves that follow the local feature size).
//! - A. Schneider (2015, 2017), "The real-time volumetric cloudscapes of Horizon Zero Dawn"
//!   (billows at several scales on a base shape; a flat, rounded-off cloud base).

#[cfg(test)]
mod bench;
/// The renderer's version: raised whenever a change makes any frame's pixels or grids differ
/// (the pinned seeded frame hashes in the tests change with it, and a test fails if they change
/// while it does not). Frames of another render version are re-rendered on resume.
pub const RENDER_VERSION: u32 = 8;

pub(crate) mod bvh;
pub(crate) mod camera;
pub(crate) mod counters;
pub(crate) mod fast_exp;
#[cfg(test)]
mod fixture;
pub(crate) mod frame;
pub(crate) mod integrator;
pub(crate) mod light;
pub(crate) mod medium;
pub(crate) mod memory;
pub mod output;
pub(crate) mod sampler;
pub(crate) mod settings;
pub(crate) mod surfaces;

// The front. Rendering a frame of blobs (and the reference march that checks it):
pub use counters::work_counts;
pub use integrator::frame_renderer::{
    FrameOptions, FrameRenderer, RenderReport, Reuse, render_reference,
};
pub use integrator::motion_blur::{BlurReport, Shutter, TimeSample};
pub use output::cryptomatte::{IdMattes, Mattes};
pub use output::film::{Film, Region};
// What is rendered, and from where:
pub use camera::{Camera, CameraRays};
pub use frame::{Frame, Passes};
pub use settings::{
    BasePlane, CloudMaterial, CumulusBase, Environment, InvalidField, NoiseSettings, PathTracing,
    Quality, QualityPreset, RenderSettings, Sky, Sun,
};
// The integrator on media of one's own, and what it asks of them:
pub use camera::{Frustum, Ray};
pub use integrator::reference::{PathStats, render_path_traced};
pub use integrator::{CloudVelocity, MotionSource, render_medium, render_medium_unshaded};
pub use light::envmap::EnvMap;
pub use light::grid::LightGrid;
pub use light::phase;
pub use light::sky_cells::{SKY_DIRECTIONS, directions as sky_directions};
pub use light::sky_dome::SkyDome;
pub use light::{HomogeneousLights, LightDepths, MultipleLight, ShadowDepths, Unshadowed};
pub use medium::blobs::BlobMedium;
pub use medium::{Homogeneous, Medium, Shape};
// The shot's opaque surfaces (holdouts, the ground plane):
pub use surfaces::{Ground, HoldoutMesh, Surfaces};

// The light grid's floor, for the blob medium's tests.
#[cfg(test)]
pub(crate) use settings::MIN_LIGHT_GRID_CELLS;

use crate::blobby::Blob;

/// A frame's 0-based position in its shot: what the plan, the per-frame settings and seeds are
/// indexed by (`k` in [`crate::scene::Shot`]). Not the frame *number*, which the files, the
/// EXR headers and the command line show: `shot.start_frame + index`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct FrameIndex(pub u32);

impl From<u32> for FrameIndex {
    fn from(k: u32) -> FrameIndex {
        FrameIndex(k)
    }
}

/// Render one frame, an instant of the whole frame, beauty only: [`FrameRenderer::render_once`]
/// with [`FrameOptions::default`]. Deterministic for a given input at any thread count; the
/// per-pixel jitter does not change between frames, so identical blobs give identical frames.
pub fn render_frame(settings: &RenderSettings, blobs: &[Blob]) -> Frame {
    FrameRenderer::render_once(settings, blobs, &FrameOptions::default()).0
}
