//! The ray-marching integrator: tiles in parallel, one jittered march per pixel through a
//! [`Medium`], single scattering from the sun (plus the octave approximation of multiple
//! scattering) and ambient sky light, with early termination.
//!
//! In: [`RenderSettings`], a medium and its lights. Out: a [`Frame`] of premultiplied cloud
//! radiance, coverage and depth. Deterministic at any thread count: each pixel depends only on
//! its own generator `item_rng(seed, Stream::Render, pixel)`. The jitter is fixed per pixel,
//! not per frame, so a cloud that does not move renders to the same bits in every frame (no
//! shimmer in holds).
//!
//! With `quality.samples = n > 1` a pixel averages `n` rays on a stratified `⌈√n⌉²` grid
//! inside it (each jittered within its cell), anti-aliasing the eroded edges. With one ray a
//! pixel and `quality.edge_samples = n > 1`, only the pixels whose first ray is partly covered
//! trace `n` more (adaptive anti-aliasing of the silhouette, at the cost of its pixels).
//!
//! Each merged interval `[a, b]` is walked in segments (coarse through empty space, fine inside
//! the medium, see [`march()`]; fine steps are thin where the ray enters the cloud and grow as its
//! transmittance falls, so each absorbs about the same share of the pixel's light); a segment of
//! length `h` is sampled at `s + ξ·h` (one jitter `ξ` per pixel) and integrated with the
//! energy-conserving form `L += T·(1 − e^{−σh})·albedo·L_in`, `T ·= e^{−σh}` (Hillaire 2015,
//! "Physically based and unified volumetric rendering in Frostbite"), exact for piecewise-constant
//! media. A ray stops when `T < 10⁻³` (`MIN_TRANSMITTANCE`); one that leaves the cloud adds the
//! sky light scattered straight on along it ([`Shading::forward_sky`]).
//!
//! Files: `march` (one ray: the loop in `mod.rs` over the stepper of `steps.rs`, which says
//! where the samples go, and the accumulator of `accumulate.rs`, which says what each adds; a
//! pixel's results and its passes in `pixel.rs`), `tiles` (the tile driver and the frame's
//! buffers), [`frame_renderer`] (the blob pipeline and the shot's reuse), [`motion_blur`] (the shutter);
//! the pixel's rays come from [`crate::render::sampler`].
//!
//! What a frame is rendered into is a [`Film`] ([`crate::render::output::film`]): one tile driver
//! (`render_film`, also motion blur's) renders the full frame's tiles that meet its window and
//! only their pixels inside it (a region's pixels are the full frame's bits), and the march is
//! monomorphised for what it accumulates besides the beauty — the render passes, the ID mattes'
//! per-sample opacity by [`Medium::label`] ([`crate::render::output::cryptomatte`]), the motion
//! vectors' per-sample screen motion (`march/motion.rs`, from a [`MotionSource`]) — chosen once
//! per frame.

pub(crate) mod frame_renderer;
pub(crate) mod motion_blur;

mod march;
pub(crate) mod reference;
pub(crate) mod shadow_total;
pub(crate) mod surface_rays;
mod tiles;

pub use march::motion::{CloudVelocity, MotionSource};
pub(crate) use march::{MarchFn, PixelResult, PixelSum, ScreenMotion, march, shaded_march};
pub(crate) use tiles::{PixelOut, render_film};

use glam::Vec3A;

use crate::render::camera::Frustum;
use shadow_total::ShadowTotal;
use surface_rays::{Corners, HOLDOUT_EDGE_RAYS, ShadowRays, TileHoldouts};

use crate::render::Frame;
use crate::render::camera::CameraRays;
use crate::render::light::shading::Shading;
use crate::render::light::{ShadowDepths, Unshadowed};
use crate::render::medium::Medium;
use crate::render::output::film::Film;
use crate::render::sampler::pixel_sample;
use crate::render::settings::{EDGE_COVERAGE, RenderSettings};
use crate::rng::{Stream, item_rng};

/// The integrator alone, for a medium and lights of one's own (the analytic test media, the
/// Mitsuba comparison's grid): `medium` as seen by `settings.camera`, lit through `lights`,
/// into `film` (only its window's pixels, the same bits as the full frame's there, with the
/// passes and ID mattes it asks for; the beauty is the same bits whatever it asks for). A
/// frame of blobs is rendered by [`crate::render::FrameRenderer`], which builds the medium and its
/// light grid and calls this.
///
/// With passes, the frame's [`crate::render::Passes`] hold the sun's single scattering, the sky's (its
/// cells and the light scattered straight on) and the multiple-scattering octaves, which sum to
/// the beauty's RGB (up to rounding).
pub fn render_medium<M: Medium, L: ShadowDepths>(
    settings: &RenderSettings,
    medium: &M,
    lights: &L,
    film: &Film,
) -> Frame {
    render_medium_moving(settings, medium, lights, film, None)
}

/// [`render_medium`] with the motion vectors of `motion` when `film` asks for them.
pub(crate) fn render_medium_moving<M: Medium, L: ShadowDepths>(
    settings: &RenderSettings,
    medium: &M,
    lights: &L,
    film: &Film,
    motion: Option<&MotionSource<'_>>,
) -> Frame {
    render_tiles(settings, medium, lights, film, motion, shaded_march(film))
}

/// Coverage and depth only (RGB stays 0): [`render_medium`]'s march without lighting, for
/// profiling the cost of shading (the benchmark) and for coverage tests.
pub fn render_medium_unshaded<M: Medium>(settings: &RenderSettings, medium: &M) -> Frame {
    let trace: MarchFn<M, Unshadowed> = march::<M, Unshadowed, false, false, false, false>;
    render_tiles(settings, medium, &Unshadowed, &Film::default(), None, trace)
}

/// A thread's scratch for the pixels: the march's, the shadow pass's (the medium begun on
/// [`Frustum::EVERYTHING`]; with the pass only), and the tile's holdouts.
pub(crate) struct PixelScratch<S> {
    pub(crate) march: S,
    pub(crate) shadow: Option<S>,
    pub(crate) tile: TileHoldouts,
}

impl<S> PixelScratch<S> {
    /// A thread's scratch for `medium`, with the shadow pass's when `shadow_pass`.
    pub(crate) fn new<M: Medium<Scratch = S>>(medium: &M, shadow_pass: bool) -> PixelScratch<S> {
        PixelScratch {
            march: medium.scratch(),
            shadow: shadow_pass.then(|| {
                let mut s = medium.scratch();
                medium.begin_tile(&Frustum::EVERYTHING, &mut s);
                s
            }),
            tile: TileHoldouts::default(),
        }
    }
}

fn render_tiles<M: Medium, L: ShadowDepths>(
    settings: &RenderSettings,
    medium: &M,
    lights: &L,
    film: &Film,
    motion: Option<&MotionSource<'_>>,
    trace: MarchFn<M, L>,
) -> Frame {
    let surfaces = settings.surfaces.as_deref();
    let shadow_pass = surfaces.is_some_and(|s| s.shadow_pass());
    let shading = Shading::new(settings);
    let total = shadow_pass.then(|| ShadowTotal::new(settings, shading.sun_radiance, medium));
    let to_sun = -Vec3A::from(settings.sun.travel_dir());
    let w = settings.width;
    let cam = CameraRays::new(&settings.camera, w, settings.height);
    let screen = motion
        .filter(|_| film.motion)
        .map(|m| ScreenMotion::new(cam, m));
    let seed = settings.seed;
    let samples = settings.quality.samples.max(1);
    let side = (samples as f32).sqrt().ceil() as u32;
    let edge = settings.quality.edge_samples;
    let edge_side = (edge as f32).sqrt().ceil() as u32;
    let optical_step = settings.quality.optical_step.max(1e-3);
    render_film(
        settings,
        film,
        &cam,
        screen.as_ref(),
        || PixelScratch::new(medium, shadow_pass),
        |scratch, frustum, whole| {
            medium.begin_tile(frustum, &mut scratch.march);
            scratch.tile.begin(surfaces, &cam, whole, frustum);
        },
        |scratch, (x, y), coverage, motion| {
            let pixel = y as u64 * w as u64 + x as u64;
            let mut rng = item_rng(seed, Stream::Render, pixel);
            let PixelScratch {
                march,
                shadow,
                tile,
            } = scratch;
            let corners = tile.pixel(x, y);
            let mut sky_rng = total
                .as_ref()
                .map(|_| item_rng(seed, Stream::SkyShadow, pixel));
            let mut shadow_sum = Vec3A::ZERO;
            // Covered where no cloud can be and no shadow is asked for: where the ray stops
            // does not matter, only that it does.
            let blind = corners == Corners::All && shadow.is_none() && medium.tile_is_empty(march);
            let mut ray = |k: u32, grid: (u32, u32)| {
                let (ray, jitter) = pixel_sample(&cam, (x, y), k, grid, &mut rng);
                let t_hold = if blind {
                    f32::MAX
                } else {
                    surface_rays::stop(surfaces, corners, &ray)
                };
                let mut r = trace(
                    medium,
                    lights,
                    &shading,
                    march,
                    &ray,
                    jitter,
                    optical_step,
                    t_hold,
                    coverage,
                    motion,
                );
                let pass = shadow
                    .as_mut()
                    .zip(total.as_ref().zip(sky_rng.as_mut()))
                    .map(|(scratch, (total, rng))| ShadowRays {
                        scratch,
                        total,
                        rng,
                    });
                shadow_sum += surface_rays::mark(
                    &mut r, surfaces, medium, pass, &ray, t_hold, to_sun, jitter,
                );
                r
            };
            let mut sum = PixelSum::new();
            let (n, grid) = if samples > 1 {
                (samples, (samples, side))
            } else {
                let first = ray(0, (1, 1));
                // A holdout's edge through the pixel: more rays, whatever the cloud does.
                let held = corners == Corners::Some;
                if !held && (edge <= 1 || !at_edge(&first)) {
                    return PixelOut {
                        result: first,
                        rays: 1,
                        shadow_total: shadow_sum,
                    };
                }
                // The centre ray stays one of the pixel's rays (no ray is wasted; the
                // generator's stream simply goes on).
                sum.add(&first);
                if held {
                    let n = edge.max(HOLDOUT_EDGE_RAYS);
                    (n, (n, (n as f32).sqrt().ceil() as u32))
                } else {
                    (edge, (edge, edge_side))
                }
            };
            for k in 0..n {
                sum.add(&ray(k, grid));
            }
            let rays = n + (samples == 1) as u32;
            PixelOut {
                result: sum.mean(rays),
                rays,
                shadow_total: shadow_sum / rays as f32,
            }
        },
    )
}

/// Whether a pixel's first ray ended at the cloud's edge ([`EDGE_COVERAGE`]): the pixels
/// [`crate::render::Quality::edge_samples`] anti-aliases.
#[inline]
fn at_edge(first: &PixelResult) -> bool {
    let coverage = 1.0 - first.transmittance;
    coverage > EDGE_COVERAGE.0 && coverage < EDGE_COVERAGE.1
}
