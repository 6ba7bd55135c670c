//! Motion blur: a frame seen through an open shutter, the cloud integrated over time.
//!
//! In: the frame's blobs and a [`Shutter`] — time samples at the centres of equal strata of the
//! shutter interval, each with the blobs at that time and their centres' velocities (from the
//! animation's own paths). Out: the [`Frame`] and a [`BlurReport`].
//!
//! Each pixel traces `max(samples, time_samples)` rays: the same rays (positions in the pixel
//! and march jitters, from the pixel's own generator) as the unblurred frame, each assigned a
//! stratum — stratum `(k + r) mod T` for ray `k`, with `r` a random rotation — and a random time
//! inside it; both come from a generator seeded per pixel and frame
//! (`Stream::Shutter`), so frames stay bit-identical at any thread count. Within its stratum a
//! ray sees the stratum's cloud with every blob moved along its centre's velocity
//! ([`BlobMedium::moving`], [`Medium::set_time_offset`]), so the time samples are continuous,
//! not `T` ghosts. All strata march with the frame's coarse step.
//!
//! Light: one light grid, the frame's, lights every time sample — unless a blob travels more
//! than [`MAX_LIGHT_SHIFT`] of the cloud's extent (in light-grid cells,
//! [`BlurReport::shift_cells`]) within the shutter; then each stratum gets a grid of its own (all
//! on one lattice over the whole shutter), since shadows cells off would show. The grids are
//! built by the frame renderer ([`crate::render::integrator::frame_renderer`]) from each medium's light-grid copy,
//! as an unblurred frame's are (before, motion blur built them from the full-detail medium:
//! at 960×540 `Final`, a shutter of 0.5 on a moving aggregation, 2 of 255 levels at most in the
//! 8-bit frame).
//!
//! Cost: the rays of a pixel are its time samples, so with one ray per pixel (`Final`) each time
//! sample costs one more march of the frame, plus one blob conversion (the light grid is shared);
//! with `samples ≥ time_samples` the time samples ride on the anti-aliasing rays and cost only
//! the conversion (docs/MEASUREMENTS.md, "Motion blur"). A blurred pixel already traces several
//! rays, so `edge_samples` adds none.

use glam::{DVec3, Vec3A};
use rand::RngExt;

use crate::blobby::Blob;
use crate::render::Frame;
use crate::render::camera::{CameraRays, Frustum, Ray};
use crate::render::integrator::shadow_total::ShadowTotal;
use crate::render::integrator::surface_rays::{
    self, Corners, HOLDOUT_EDGE_RAYS, ShadowRays, TileHoldouts,
};
use crate::render::integrator::{
    MotionSource, PixelOut, PixelSum, ScreenMotion, pixel_sample, render_film, shaded_march,
};
use crate::render::light::grid::LightGrid;
use crate::render::light::shading::Shading;
use crate::render::medium::Medium;
use crate::render::medium::blobs::BlobMedium;
use crate::render::medium::lattice::GridShape;
use crate::render::output::film::Film;
use crate::render::settings::RenderSettings;
use crate::rng::{Stream, item_rng, key};

/// Largest blob travel from the frame's time to the shutter's ends, as a fraction of the light
/// grid's longest side (the cloud's extent), that one light grid built at the frame's time
/// lights: shadows then land at most 1 % of the cloud off, measured to keep a moving cloud
/// within 2 % of the mean of its sub-frame renders (`motion_blur/tests.rs`; at 1.7 cells of a
/// 64-cell grid, 2.6 % of the extent, the error was 2.3 %). At `Final`'s 224 cells this is
/// 2.2 cells.
pub(crate) const MAX_LIGHT_SHIFT: f32 = 0.01;

/// One time sample of a frame's shutter.
#[derive(Clone, Debug, PartialEq)]
pub struct TimeSample {
    /// Seconds from the frame's time to the middle of the stratum.
    pub offset: f64,
    /// The blobs at that time (index = identity, as in the frame's list).
    pub blobs: Vec<Blob>,
    /// Velocity of each blob's centre at that time (world units per second).
    pub velocity: Vec<DVec3>,
}

/// An open shutter: time samples at the centres of equal strata.
#[derive(Clone, Debug, PartialEq)]
pub struct Shutter {
    /// The strata in time order.
    pub samples: Vec<TimeSample>,
    /// Length of one stratum in seconds (the shutter's length over the number of samples).
    pub stratum: f64,
}

impl Shutter {
    /// True when every time sample's blobs equal `frame` (nothing moves while the shutter is
    /// open: the blurred frame is the frame itself).
    pub(crate) fn is_still(&self, frame: &[Blob]) -> bool {
        self.samples
            .iter()
            .all(|s| s.blobs == frame && s.velocity.iter().all(|v| *v == DVec3::ZERO))
    }
}

/// What the blur did, for the record.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlurReport {
    /// Largest travel of a blob centre from its frame position within the shutter, in cells
    /// of the frame's light grid.
    pub shift_cells: f32,
    /// Light grids built (1, or one per stratum past `MAX_LIGHT_SHIFT` of the extent).
    pub light_grids: usize,
}

/// A blurred frame's time samples and how they are lit, worked out by [`Blob`] travel; the
/// light grids themselves are built by the frame renderer ([`crate::render::integrator::frame_renderer`]).
pub(crate) struct Blur {
    /// The medium of each stratum, moving, marched with the frame's coarse step.
    pub(crate) slices: Vec<BlobMedium>,
    /// `Some(box)` when each stratum gets a light grid of its own, all over `box` (the frame's
    /// and every stratum's supports; `None` inside when all are empty); `None` when the frame's
    /// one grid lights every stratum.
    pub(crate) stratum_bounds: Option<Option<(Vec3A, Vec3A)>>,
    /// Largest blob travel within the shutter, in light-grid cells.
    shift_cells: f32,
}

impl Blur {
    /// The time samples of `shutter` for the frame whose medium is `frame_medium` (from
    /// `frame_blobs`, `settings.time` the frame's time; each stratum's noise evolves at its own
    /// time), and whether one light grid lights them all (see the module doc).
    pub(crate) fn new(
        settings: &RenderSettings,
        frame_medium: &BlobMedium,
        frame_blobs: &[Blob],
        shutter: &Shutter,
    ) -> Blur {
        let half = (0.5 * shutter.stratum) as f32;
        let slices: Vec<BlobMedium> = shutter
            .samples
            .iter()
            .map(|s| {
                let mut at = settings.clone();
                at.time = (settings.time as f64 + s.offset) as f32;
                let mut m = BlobMedium::moving(&at, &s.blobs, &s.velocity, half);
                m.set_step(frame_medium.step());
                m
            })
            .collect();
        let cells = settings.light_grid_cells(frame_medium.bounds());
        let shift = shift_cells(cells, frame_medium, frame_blobs, shutter);
        let stratum_bounds = (shift > MAX_LIGHT_SHIFT * cells.max(2) as f32).then(|| {
            // One lattice over the frame and every stratum, so a part that holds still is
            // sampled at the same nodes in each.
            std::iter::once(frame_medium)
                .chain(&slices)
                .filter_map(|m| m.bounds())
                .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
        });
        Blur {
            slices,
            stratum_bounds,
            shift_cells: shift,
        }
    }

    /// The record of this blur lit by `light_grids` grids.
    pub(crate) fn report(&self, light_grids: usize) -> BlurReport {
        BlurReport {
            shift_cells: self.shift_cells,
            light_grids,
        }
    }
}

/// A medium reporting wider bounds than its own (every stratum's light grid then spans the same
/// box, the whole shutter's); all else is the medium's.
pub(crate) struct Bounded<'a, M> {
    /// The medium.
    pub(crate) medium: &'a M,
    /// The box it reports.
    pub(crate) bounds: (Vec3A, Vec3A),
}

impl<M: Medium> Medium for Bounded<'_, M> {
    type Scratch = M::Scratch;

    fn scratch(&self) -> Self::Scratch {
        self.medium.scratch()
    }

    fn begin_tile(&self, frustum: &crate::render::camera::Frustum, s: &mut Self::Scratch) {
        self.medium.begin_tile(frustum, s)
    }

    fn begin_ray(&self, ray: &Ray, s: &mut Self::Scratch) {
        self.medium.begin_ray(ray, s)
    }

    fn intervals<'s>(&self, s: &'s Self::Scratch) -> &'s [[f32; 2]] {
        self.medium.intervals(s)
    }

    fn extinction(&self, s: &mut Self::Scratch, t: f32, x: glam::Vec3A) -> f32 {
        self.medium.extinction(s, t, x)
    }

    fn sample(&self, s: &mut Self::Scratch, t: f32, x: glam::Vec3A) -> (f32, bool) {
        self.medium.sample(s, t, x)
    }

    fn label(&self, s: &mut Self::Scratch, t: f32) -> u32 {
        self.medium.label(s, t)
    }

    fn bounds(&self) -> Option<(glam::Vec3A, glam::Vec3A)> {
        Some(self.bounds)
    }

    fn step(&self) -> f32 {
        self.medium.step()
    }

    fn max_extinction(&self) -> f32 {
        self.medium.max_extinction()
    }

    fn empty_stride(&self) -> f32 {
        self.medium.empty_stride()
    }
}

/// Largest travel of a live blob's centre from the frame within the shutter, in cells of a
/// light grid of `cells` on its longest side (0 for an empty frame).
fn shift_cells(
    cells: u32,
    frame_medium: &BlobMedium,
    frame_blobs: &[Blob],
    shutter: &Shutter,
) -> f32 {
    let Some((lo, hi)) = frame_medium.bounds() else {
        return 0.0;
    };
    let cell = GridShape::covering(lo, hi, cells).h as f64;
    let half = 0.5 * shutter.stratum;
    let mut travel = 0.0f64;
    for s in &shutter.samples {
        for (i, b) in s.blobs.iter().enumerate() {
            if !b.is_live() {
                continue;
            }
            let from = frame_blobs.get(i).map_or(b.center, |f| f.center);
            let v = s.velocity.get(i).copied().unwrap_or_default();
            travel = travel.max((b.center - from).length() + v.length() * half);
        }
    }
    (travel / cell.max(f64::MIN_POSITIVE)) as f32
}

/// Per-thread scratch: one medium scratch per stratum and the pixel's spatial samples.
struct Scratch<S> {
    media: Vec<S>,
    /// Per stratum, the shadow pass's scratch (begun on `Frustum::EVERYTHING`; with the pass).
    shadow: Vec<S>,
    rays: Vec<(Ray, f32)>,
    tile: TileHoldouts,
}

/// The tiles of a blurred frame: every pixel's rays spread over the strata of `slices`, lit by
/// `lights[j]` (or `lights[0]` for all), into `film`.
pub(crate) fn render_slices(
    settings: &RenderSettings,
    slices: &[BlobMedium],
    lights: &[Option<LightGrid>],
    stratum: f32,
    film: &Film,
    motion: Option<&MotionSource<'_>>,
) -> Frame {
    let w = settings.width;
    let cam = CameraRays::new(&settings.camera, w, settings.height);
    // The vectors of the frame's time, where each stratum's samples lie.
    let screen = motion
        .filter(|_| film.motion)
        .map(|m| ScreenMotion::new(cam, m));
    let shading = Shading::new(settings);
    let samples = settings.quality.samples.max(1);
    let side = (samples as f32).sqrt().ceil() as u32;
    let strata = slices.len() as u32;
    let rays = samples.max(strata);
    let optical_step = settings.quality.optical_step.max(1e-3);
    let trace = shaded_march::<BlobMedium, Option<LightGrid>>(film);
    // Time samples are seeded per pixel and frame (the frame by its time).
    let frame_seed = key(
        settings.seed,
        Stream::Shutter,
        settings.time.to_bits() as u64,
    );
    let surfaces = settings.surfaces.as_deref();
    let shadow_pass = surfaces.is_some_and(|s| s.shadow_pass());
    let to_sun = -Vec3A::from(settings.sun.travel_dir());
    // The sky's share through the cloud at the middle of the shutter.
    let middle = &slices[slices.len() / 2];
    let total = shadow_pass.then(|| ShadowTotal::new(settings, shading.sun_radiance, middle));
    render_film(
        settings,
        film,
        &cam,
        screen.as_ref(),
        || Scratch {
            media: slices.iter().map(|m| m.scratch()).collect(),
            shadow: if shadow_pass {
                slices
                    .iter()
                    .map(|m| {
                        let mut s = m.scratch();
                        m.begin_tile(&Frustum::EVERYTHING, &mut s);
                        s
                    })
                    .collect()
            } else {
                Vec::new()
            },
            rays: Vec::new(),
            tile: TileHoldouts::default(),
        },
        |scratch, frustum, whole| {
            for (m, s) in slices.iter().zip(scratch.media.iter_mut()) {
                m.begin_tile(frustum, s);
            }
            scratch.tile.begin(surfaces, &cam, whole, frustum);
        },
        |scratch, (x, y), coverage, motion| {
            let pixel = y as u64 * w as u64 + x as u64;
            let mut rng = item_rng(settings.seed, Stream::Render, pixel);
            let mut time = item_rng(frame_seed, Stream::Shutter, pixel);
            scratch.rays.clear();
            for k in 0..samples {
                let ray = pixel_sample(&cam, (x, y), k, (samples, side), &mut rng);
                scratch.rays.push(ray);
            }
            let mut rays = rays;
            let corners = scratch.tile.pixel(x, y);
            // One position a pixel: a holdout's edge through it spreads its rays over it.
            if samples == 1 && corners == Corners::Some {
                rays = rays.max(HOLDOUT_EDGE_RAYS + 1);
                let grid = (rays, (rays as f32).sqrt().ceil() as u32);
                scratch.rays.clear();
                for k in 0..rays {
                    let ray = pixel_sample(&cam, (x, y), k, grid, &mut rng);
                    scratch.rays.push(ray);
                }
            }
            let rotation = time.random_range(0..strata);
            let mut sum = PixelSum::new();
            let mut sky_rng = total
                .as_ref()
                .map(|_| item_rng(settings.seed, Stream::SkyShadow, pixel));
            let mut shadow_sum = Vec3A::ZERO;
            for k in 0..rays {
                let (ray, jitter) = scratch.rays[k as usize % scratch.rays.len()];
                let j = ((k + rotation) % strata) as usize;
                let dt = (time.random::<f32>() - 0.5) * stratum;
                let (m, s) = (&slices[j], &mut scratch.media[j]);
                m.set_time_offset(s, dt);
                let lights = &lights[j.min(lights.len() - 1)];
                let t_hold = surface_rays::stop(surfaces, corners, &ray);
                let mut r = trace(
                    m,
                    lights,
                    &shading,
                    s,
                    &ray,
                    jitter,
                    optical_step,
                    t_hold,
                    coverage,
                    motion,
                );
                let mut shadow = scratch.shadow.get_mut(j);
                if let Some(sh) = shadow.as_deref_mut() {
                    m.set_time_offset(sh, dt);
                }
                let pass = shadow.zip(total.as_ref().zip(sky_rng.as_mut())).map(
                    |(scratch, (total, rng))| ShadowRays {
                        scratch,
                        total,
                        rng,
                    },
                );
                shadow_sum +=
                    surface_rays::mark(&mut r, surfaces, m, pass, &ray, t_hold, to_sun, jitter);
                sum.add(&r);
            }
            PixelOut {
                result: sum.mean(rays),
                rays,
                shadow_total: shadow_sum / rays as f32,
            }
        },
    )
}

/// Centres of `n` equal strata of a shutter `shutter` frames long, centred on the frame, in
/// seconds from the frame at `fps`; and the stratum's length in seconds.
pub(crate) fn strata(shutter: f64, n: u32, fps: f64) -> (Vec<f64>, f64) {
    let n = n.max(1);
    let length = shutter / fps;
    let stratum = length / n as f64;
    let centres = (0..n)
        .map(|j| -0.5 * length + (j as f64 + 0.5) * stratum)
        .collect();
    (centres, stratum)
}

#[cfg(test)]
mod tests;
