//! Where a frame is rendered: the one pipeline from a frame's blobs to its pixels, used by the
//! shot loop, [`crate::scene::Shot::render_frame`], the statistics, the preview and motion blur
//! alike.
//!
//! ```text
//! blobs ──► BlobMedium::new ──► for_light_grid ──► LightGrid ──► integrator ──► Frame
//!           (the medium)        (its copy without    (the lights:  (tiles, march,
//!                                billows finer than   shadow depths) film, shutter)
//!                                two grid cells)
//! ```
//!
//! In: per frame, [`RenderSettings`], the blobs and [`FrameOptions`] — the shutter (motion blur,
//! [`crate::render::integrator::motion_blur`]) and the film (region, passes, ID mattes, [`Film`]). Out: the
//! [`Frame`] and a [`RenderReport`].
//!
//! A [`FrameRenderer`] renders a shot's frames in order, each reusing what it can of the one
//! before: the light grid's buffers always (no few hundred megabytes allocated and zeroed a
//! frame), the light grid itself where the cloud and the sun have not changed, the whole frame
//! in a hold (same cloud, settings and film: the renderer is deterministic and its jitter fixed
//! per pixel, so the frame would come out bit for bit the same). Every light grid — the frame's,
//! or one per time sample of a fast shutter — is built by `light_grid` from the medium's
//! light-grid copy ([`BlobMedium::for_light_grid`]), so the blurred and the unblurred frames
//! are lit alike.
//!
//! Frames are counted two ways, and the renderer needs neither: a [`FrameIndex`] is the
//! 0-based position in the shot (what plans, settings and the per-frame seeds are indexed by),
//! a frame number is what the files and the command line show (`shot.start_frame` plus the
//! index). Time reaches the render through `settings.time` only.
//!
//! [`FrameIndex`]: crate::render::FrameIndex

use glam::Vec3A;

use crate::blobby::Blob;
use crate::render::integrator::motion_blur::{self, Blur, BlurReport, Bounded, Shutter};
use crate::render::integrator::reference::render_path_traced;
use crate::render::integrator::{MotionSource, render_medium, render_medium_moving};
use crate::render::light::grid::LightGrid;
use crate::render::medium::Medium;
use crate::render::medium::blobs::BlobMedium;
use crate::render::output::film::Film;
use crate::render::{Frame, RenderSettings};

/// The whole frame, beauty only: [`FrameOptions::default`]'s film.
static BEAUTY: Film = Film {
    region: None,
    passes: false,
    mattes: None,
    motion: false,
};

/// How a frame is seen besides its settings: through which shutter, into which film.
#[derive(Clone, Copy, Debug)]
pub struct FrameOptions<'a> {
    /// The open shutter (motion blur: the cloud integrated over its time samples); `None`, or
    /// a shutter in which nothing moves (`Shutter::is_still`), for an instant.
    pub shutter: Option<&'a Shutter>,
    /// What the frame is rendered into: its window, the passes and the ID mattes. Every pixel
    /// rendered has the whole frame's bits whatever it asks for.
    pub film: &'a Film,
    /// The cloud's velocity at the frame's time and the frame rate, for the motion vectors
    /// ([`Film::motion`]; without it they are 0).
    pub motion: Option<MotionSource<'a>>,
}

impl Default for FrameOptions<'_> {
    /// An instant, the whole frame, beauty only.
    fn default() -> Self {
        FrameOptions {
            shutter: None,
            film: &BEAUTY,
            motion: None,
        }
    }
}

/// What a frame could take from the last one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reuse {
    /// Nothing but buffers: the cloud or the sun changed, the shutter is open (or the first
    /// frame).
    Buffers,
    /// The light grid: same cloud and sun, another camera or image setting.
    LightGrid,
    /// The whole frame: a hold.
    Frame,
}

/// What rendering a frame did, for the record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderReport {
    /// What was reused from the last frame.
    pub reuse: Reuse,
    /// What the shutter did, when the frame was blurred.
    pub blur: Option<BlurReport>,
}

/// Renders frames one after another (see the module doc), keeping the last one's medium, light
/// grid and frame. Each frame equals a fresh renderer's bit for bit.
#[derive(Debug, Default)]
pub struct FrameRenderer {
    last: Option<Last>,
}

/// What the last frame left.
#[derive(Debug)]
struct Last {
    /// Its settings with `time` zeroed (time reaches the frame only through the medium).
    settings: RenderSettings,
    medium: BlobMedium,
    film: Film,
    /// Blurred: neither its frame nor its light grid stand for another frame.
    blurred: bool,
    grid: Option<LightGrid>,
    frame: Frame,
}

impl FrameRenderer {
    /// A renderer with nothing to reuse yet.
    pub fn new() -> FrameRenderer {
        FrameRenderer::default()
    }

    /// Render one frame with a fresh renderer and keep nothing.
    pub fn render_once(
        settings: &RenderSettings,
        blobs: &[Blob],
        options: &FrameOptions<'_>,
    ) -> (Frame, RenderReport) {
        let mut r = FrameRenderer::new();
        let report = r.render_reporting(settings, blobs, options).1;
        let last = r.last.take().expect("a frame was just rendered");
        (last.frame, report)
    }

    /// Render the frame of `blobs` (index = identity) with `settings` through `options`.
    pub fn render(
        &mut self,
        settings: &RenderSettings,
        blobs: &[Blob],
        options: &FrameOptions<'_>,
    ) -> &Frame {
        self.render_reporting(settings, blobs, options).0
    }

    /// [`FrameRenderer::render`], also saying what was reused and what the shutter did.
    pub fn render_reporting(
        &mut self,
        settings: &RenderSettings,
        blobs: &[Blob],
        options: &FrameOptions<'_>,
    ) -> (&Frame, RenderReport) {
        let film = options.film;
        let motion = options.motion.as_ref();
        let shutter = options.shutter.filter(|s| !s.is_still(blobs));
        let medium = BlobMedium::new(settings, blobs);
        let mut key = settings.clone();
        key.time = 0.0;
        // A still cloud from a frame that was not blurred, into an instant.
        let still = shutter.is_none()
            && self
                .last
                .as_ref()
                .is_some_and(|l| !l.blurred && l.medium == medium);
        // (Not with motion vectors: a cloud that holds still in this frame may be about to
        // move, which its vectors show.)
        if still
            && !film.motion
            && self
                .last
                .as_ref()
                .is_some_and(|l| l.settings == key && l.film == *film)
        {
            let last = self.last.as_ref().expect("checked above");
            let report = RenderReport {
                reuse: Reuse::Frame,
                blur: None,
            };
            return (&last.frame, report);
        }
        let previous = self.last.take();
        let (frame, grid, report) = match shutter {
            // The path tracer: no light grid, the frame's instant (module doc of `reference`).
            _ if settings.quality.reference.is_some() => {
                let (frame, _) = render_path_traced(settings, &medium, film);
                let report = RenderReport {
                    reuse: Reuse::Buffers,
                    blur: None,
                };
                (frame, None, report)
            }
            Some(shutter) => {
                let (frame, grid, blur) =
                    render_blurred(settings, &medium, blobs, shutter, film, motion, previous);
                let report = RenderReport {
                    reuse: Reuse::Buffers,
                    blur: Some(blur),
                };
                (frame, grid, report)
            }
            None => {
                let (grid, reuse) = match previous {
                    Some(l)
                        if still
                            && same_light(&l.settings, settings)
                            && l.settings.light_grid_cells(medium.bounds())
                                == settings.light_grid_cells(medium.bounds()) =>
                    {
                        (l.grid, Reuse::LightGrid)
                    }
                    previous => (
                        light_grid(settings, &medium, None, previous.and_then(|l| l.grid)),
                        Reuse::Buffers,
                    ),
                };
                let frame = render_medium_moving(settings, &medium, &grid, film, motion);
                let report = RenderReport { reuse, blur: None };
                (frame, grid, report)
            }
        };
        let last = self.last.insert(Last {
            settings: key,
            medium,
            film: film.clone(),
            blurred: report.blur.is_some(),
            grid,
            frame,
        });
        (&last.frame, report)
    }
}

/// Whether a light grid built under `a` lights a frame under `b` (same medium and cells
/// given): the sun, the holdouts and, when the grid holds the fluence estimate, everything it
/// was traced with (sky, albedo, phase, photons, seed, contrast).
fn same_light(a: &RenderSettings, b: &RenderSettings) -> bool {
    let (ca, cb) = (&a.cloud, &b.cloud);
    a.sun == b.sun
        && a.surfaces == b.surfaces
        && ca.multiple_scattering == cb.multiple_scattering
        && a.quality.ms_photons == b.quality.ms_photons
        && (!ca.multiple_scattering
            || a.quality.ms_photons == 0
            || (a.sky == b.sky
                && ca.albedo == cb.albedo
                && ca.phase_g == cb.phase_g
                && ca.ms_contrast == cb.ms_contrast
                && a.seed == b.seed))
}

/// The reference the march is checked against: `blobs` rendered with `settings` through the
/// same light grid, but marched with fine and coarse steps `divisor` times shorter. Slow: for
/// tests and speed work (a faster march must stay within 2/255 of the reference at a quarter of
/// the fine step; the accuracy tests in `tests/it/render.rs`).
pub fn render_reference(settings: &RenderSettings, blobs: &[Blob], divisor: f32) -> Frame {
    let medium = BlobMedium::new(settings, blobs);
    let grid = light_grid(settings, &medium, None, None);
    let mut fine = settings.clone();
    fine.quality.optical_step /= divisor;
    let mut reference = medium.clone();
    reference.set_step(medium.step() / divisor);
    reference.set_stride(0.0);
    render_medium(&fine, &reference, &grid, &BEAUTY)
}

/// A blurred frame: the shutter's time samples ([`Blur::new`]), lit by the frame's light grid
/// or, past [`motion_blur::MAX_LIGHT_SHIFT`], one grid per time sample over the whole
/// shutter's box; then the strata marched ([`motion_blur::render_slices`]). Also returns the
/// frame's grid (if one served every sample) for the next frame's buffers.
fn render_blurred(
    settings: &RenderSettings,
    medium: &BlobMedium,
    blobs: &[Blob],
    shutter: &Shutter,
    film: &Film,
    motion: Option<&MotionSource<'_>>,
    previous: Option<Last>,
) -> (Frame, Option<LightGrid>, BlurReport) {
    let blur = Blur::new(settings, medium, blobs, shutter);
    let previous = previous.and_then(|l| l.grid);
    let lights: Vec<Option<LightGrid>> = match blur.stratum_bounds {
        Some(bounds) => blur
            .slices
            .iter()
            .map(|m| bounds.and_then(|b| light_grid(settings, m, Some(b), None)))
            .collect(),
        None => vec![light_grid(settings, medium, None, previous)],
    };
    let report = blur.report(lights.len());
    if blur.slices.is_empty() {
        let frame = render_medium_moving(settings, medium, &lights[0], film, motion);
        return (frame, lights.into_iter().next().flatten(), report);
    }
    let frame = motion_blur::render_slices(
        settings,
        &blur.slices,
        &lights,
        shutter.stratum as f32,
        film,
        motion,
    );
    let grid = if lights.len() == 1 {
        lights.into_iter().next().flatten()
    } else {
        None
    };
    (frame, grid, report)
}

/// The light grid of `medium` (the frame's, or a time sample's), built from its light-grid
/// copy: without the billows finer than two of the grid's cells, which the grid could only
/// alias. `over`: the box the grid spans when wider than the medium's own bounds (every
/// time sample of a fast shutter on one lattice). `previous`: a grid whose buffers to reuse.
/// `None` when the medium is empty.
///
/// The only place a frame's light grid is made.
pub(crate) fn light_grid(
    settings: &RenderSettings,
    medium: &BlobMedium,
    over: Option<(Vec3A, Vec3A)>,
    previous: Option<LightGrid>,
) -> Option<LightGrid> {
    match over {
        None => LightGrid::for_frame_reusing(settings, &medium.for_light_grid(settings), previous),
        Some(bounds) => {
            let cells = settings.light_grid_cells(Some(bounds));
            let coarse = medium.for_lattice_over(bounds, cells);
            let bounded = Bounded {
                medium: &coarse,
                bounds,
            };
            LightGrid::for_frame_reusing(settings, &bounded, previous)
        }
    }
}
