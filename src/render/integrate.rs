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
//! the medium, see [`march`]; fine steps are thin where the ray enters the cloud and grow as its
//! transmittance falls, so each absorbs about the same share of the pixel's light); a segment of
//! length `h` is sampled at `s + ξ·h` (one jitter `ξ` per pixel) and integrated with the
//! energy-conserving form `L += T·(1 − e^{−σh})·albedo·L_in`, `T ·= e^{−σh}` (Hillaire 2015,
//! "Physically based and unified volumetric rendering in Frostbite"), exact for piecewise-constant
//! media. A ray stops when `T <` [`MIN_TRANSMITTANCE`]; one that leaves the cloud adds the sky
//! light scattered straight on along it ([`Shading::forward_sky`]).
//!
//! What a frame is rendered into is a [`Film`] ([`super::film`]): one tile driver
//! (`render_film`, also motion blur's) renders the full frame's tiles that meet its window and
//! only their pixels inside it (a region's pixels are the full frame's bits), and the march is
//! monomorphised for what it accumulates besides the beauty — the render passes, the ID mattes'
//! per-sample opacity by [`Medium::label`] ([`super::cryptomatte`]) — chosen once per frame.

use glam::Vec3A;
use rand::RngExt;
use rayon::prelude::*;

use super::Frame;
use super::camera::{CameraRays, Frustum, Ray};
use super::counters::{self, Counter};
use super::cryptomatte::{Coverage, IdMattes, RANKS, Rank};
use super::film::{Film, Region};
use super::lights::{Lights, Unshadowed};
use super::medium::Medium;
use super::settings::{EDGE_COVERAGE, RenderSettings};
use super::shading::Shading;
use crate::rng::{Stream, item_rng};

/// Tile side in pixels.
pub const TILE: u32 = 16;

/// Transmittance below which a ray stops (its coverage is then `1 − T ≥ 0.999`).
pub const MIN_TRANSMITTANCE: f32 = 1e-3;

/// Largest optical thickness of one fine step, reached where the transmittance has fallen to
/// `optical_step / MAX_OPTICAL_STEP`.
pub const MAX_OPTICAL_STEP: f32 = 1.0;

/// Most samples one ray may take (guards against unbounded intervals).
const MAX_STEPS: u32 = 1_000_000;

/// What one pixel's march produced.
#[derive(Clone, Copy, Debug)]
pub(super) struct PixelResult {
    pub(super) rgb: Vec3A,
    pub(super) transmittance: f32,
    pub(super) depth: f32,
    /// The render passes (sun, sky, multiple), when asked for.
    pub(super) passes: [Vec3A; 3],
}

/// The integrator alone, for a medium and lights of one's own (the analytic test media, the
/// Mitsuba comparison's grid): `medium` as seen by `settings.camera`, lit through `lights`,
/// into `film` (only its window's pixels, the same bits as the full frame's there, with the
/// passes and ID mattes it asks for; the beauty is the same bits whatever it asks for). A
/// frame of blobs is rendered by [`super::FrameRenderer`], which builds the medium and its
/// light grid and calls this.
///
/// With passes, the frame's [`super::Passes`] hold the sun's single scattering, the sky's (its
/// cells and the light scattered straight on) and the multiple-scattering octaves, which sum to
/// the beauty's RGB (up to rounding).
pub fn render_medium<M: Medium, L: Lights>(
    settings: &RenderSettings,
    medium: &M,
    lights: &L,
    film: &Film,
) -> Frame {
    render_tiles(settings, medium, lights, film, shaded_march(film))
}

/// Coverage and depth only (RGB stays 0): [`render_medium`]'s march without lighting, for
/// profiling the cost of shading (the benchmark) and for coverage tests.
pub fn render_medium_unshaded<M: Medium>(settings: &RenderSettings, medium: &M) -> Frame {
    let trace: MarchFn<M, Unshadowed> = march::<M, Unshadowed, false, false, false>;
    render_tiles(settings, medium, &Unshadowed, &Film::default(), trace)
}

/// One ray's march ([`march`], monomorphised for what it accumulates).
pub(super) type MarchFn<M, L> = fn(
    &M,
    &L,
    &Shading,
    &mut <M as Medium>::Scratch,
    &Ray,
    f32,
    f32,
    &mut Coverage<'_>,
) -> PixelResult;

/// The shaded march that accumulates what `film` asks for (passes, mattes); chosen once per
/// frame, so the per-sample loop has no test for either.
pub(super) fn shaded_march<M: Medium, L: Lights>(film: &Film) -> MarchFn<M, L> {
    match (film.passes, film.mattes.is_some()) {
        (false, false) => march::<M, L, true, false, false>,
        (true, false) => march::<M, L, true, true, false>,
        (false, true) => march::<M, L, true, false, true>,
        (true, true) => march::<M, L, true, true, true>,
    }
}

fn render_tiles<M: Medium, L: Lights>(
    settings: &RenderSettings,
    medium: &M,
    lights: &L,
    film: &Film,
    trace: MarchFn<M, L>,
) -> Frame {
    let w = settings.width;
    let cam = CameraRays::new(&settings.camera, w, settings.height);
    let shading = Shading::new(settings);
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
        || medium.scratch(),
        |scratch, frustum| medium.begin_tile(frustum, scratch),
        |scratch, (x, y), coverage| {
            let pixel = y as u64 * w as u64 + x as u64;
            let mut rng = item_rng(seed, Stream::Render, pixel);
            let mut ray = |k: u32, grid: (u32, u32)| {
                let (ray, jitter) = pixel_sample(&cam, (x, y), k, grid, &mut rng);
                trace(
                    medium,
                    lights,
                    &shading,
                    scratch,
                    &ray,
                    jitter,
                    optical_step,
                    coverage,
                )
            };
            let mut sum = PixelSum::new();
            let (n, grid) = if samples > 1 {
                (samples, (samples, side))
            } else {
                let first = ray(0, (1, 1));
                if edge <= 1 || !at_edge(&first) {
                    return (first, 1);
                }
                // The centre ray stays one of the pixel's rays (no ray is wasted; the
                // generator's stream simply goes on).
                sum.add(&first);
                (edge, (edge, edge_side))
            };
            for k in 0..n {
                sum.add(&ray(k, grid));
            }
            let rays = n + (samples == 1) as u32;
            (sum.mean(rays), rays)
        },
    )
}

/// Whether a pixel's first ray ended at the cloud's edge ([`EDGE_COVERAGE`]): the pixels
/// [`super::Quality::edge_samples`] anti-aliases.
#[inline]
fn at_edge(first: &PixelResult) -> bool {
    let coverage = 1.0 - first.transmittance;
    coverage > EDGE_COVERAGE.0 && coverage < EDGE_COVERAGE.1
}

/// One row of tiles: the frame's buffers for its [`TILE`] rows of pixels (full width), which
/// its tiles' pixels are written straight into (no per-tile results held for the whole frame:
/// at 1920×1080 they had been 166 MB beside the frame's 41).
struct Band<'a> {
    /// The band's first row.
    y0: u32,
    rgb: &'a mut [[f32; 3]],
    alpha: &'a mut [f32],
    depth: &'a mut [f32],
    /// Sun, sky and multiple, when the film asks for passes.
    passes: Option<[&'a mut [[f32; 3]]; 3]>,
    /// The ID-matte ranks, when it asks for mattes.
    ranks: Option<&'a mut [[Rank; RANKS]]>,
}

impl Band<'_> {
    /// Store pixel `i` of the band (row-major within it).
    #[inline]
    fn store(&mut self, i: usize, p: &PixelResult) {
        self.rgb[i] = p.rgb.to_array();
        self.alpha[i] = 1.0 - p.transmittance;
        self.depth[i] = p.depth;
        if let Some([sun, sky, multiple]) = &mut self.passes {
            sun[i] = p.passes[0].to_array();
            sky[i] = p.passes[1].to_array();
            multiple[i] = p.passes[2].to_array();
        }
    }
}

/// Render the frame's tiles that meet `film`'s window in parallel, each row of tiles writing
/// into its own part of the frame. Per thread `scratch()` once; per tile `begin_tile(scratch,
/// frustum)` with the whole tile's frustum (so a region's pixels see what the full frame's
/// do); per pixel of the window `pixel(scratch, (x, y), coverage)`, which returns the pixel and
/// the number of rays whose matte weights it added to `coverage`. Pixels outside the window
/// stay empty (no cloud).
pub(super) fn render_film<S: Send>(
    settings: &RenderSettings,
    film: &Film,
    cam: &CameraRays,
    scratch: impl Fn() -> S + Sync + Send,
    begin_tile: impl Fn(&mut S, &Frustum) + Sync + Send,
    pixel: impl Fn(&mut S, (u32, u32), &mut Coverage<'_>) -> (PixelResult, u32) + Sync + Send,
) -> Frame {
    let (w, h) = (settings.width, settings.height);
    let window = film.window(w, h);
    let of_blob = film.mattes.as_ref().map_or(&[][..], |m| &m.of_blob[..]);
    let n = (w * h) as usize;
    let mut frame = Frame {
        width: w,
        height: h,
        rgb: vec![[0.0; 3]; n],
        alpha: vec![0.0; n],
        depth: vec![f32::INFINITY; n],
        passes: film.passes.then(|| Box::new(super::Passes::zeros(n))),
        mattes: film
            .mattes
            .as_ref()
            .map(|m| Box::new(IdMattes::empty(m, n))),
        region: film.region,
    };
    let band_px = (w * TILE) as usize;
    let bands = h.div_ceil(TILE) as usize;
    let Frame {
        rgb,
        alpha,
        depth,
        passes,
        mattes,
        ..
    } = &mut frame;
    let passes: Vec<Option<[&mut [[f32; 3]]; 3]>> = match passes {
        Some(p) => {
            let super::Passes { sun, sky, multiple } = &mut **p;
            sun.chunks_mut(band_px)
                .zip(sky.chunks_mut(band_px))
                .zip(multiple.chunks_mut(band_px))
                .map(|((a, b), c)| Some([a, b, c]))
                .collect()
        }
        None => (0..bands).map(|_| None).collect(),
    };
    let ranks: Vec<Option<&mut [[Rank; RANKS]]>> = match mattes {
        Some(m) => m.ranks.chunks_mut(band_px).map(Some).collect(),
        None => (0..bands).map(|_| None).collect(),
    };
    let bands: Vec<Band> = rgb
        .chunks_mut(band_px)
        .zip(alpha.chunks_mut(band_px))
        .zip(depth.chunks_mut(band_px))
        .zip(passes.into_iter().zip(ranks))
        .enumerate()
        .map(|(k, (((rgb, alpha), depth), (passes, ranks)))| Band {
            y0: k as u32 * TILE,
            rgb,
            alpha,
            depth,
            passes,
            ranks,
        })
        .collect();
    let tx = w.div_ceil(TILE);
    bands
        .into_par_iter()
        .for_each_init(scratch, |scratch, mut band| {
            let y0 = band.y0;
            for t in 0..tx {
                let whole = Region {
                    x0: t * TILE,
                    y0,
                    x1: ((t + 1) * TILE).min(w),
                    y1: (y0 + TILE).min(h),
                };
                let Some(part) = window.intersect(&whole) else {
                    continue;
                };
                begin_tile(
                    scratch,
                    &cam.frustum(whole.x0, whole.y0, whole.x1, whole.y1),
                );
                for y in part.y0..part.y1 {
                    for x in part.x0..part.x1 {
                        let mut coverage = Coverage::new(of_blob);
                        let (p, rays) = pixel(scratch, (x, y), &mut coverage);
                        let i = ((y - y0) * w + x) as usize;
                        band.store(i, &p);
                        if let Some(r) = &mut band.ranks {
                            r[i] = coverage.ranks(rays);
                        }
                    }
                }
            }
        });
    frame
}

/// March one ray. `jitter ∈ [0, 1)` places the sample inside each segment.
///
/// Two speeds: coarse segments of [`Medium::step`] cross the empty parts of the intervals; the
/// first coarse sample that finds extinction is discarded and the march resumes from the last
/// sample that was empty, in fine
/// segments of optical thickness at most `optical_step` (so a step never hides a steep change
/// of light depth); after a coarse step's worth of empty fine samples the march coarsens again.
/// Segments are clipped to the interval, so piecewise-constant media integrate exactly.
///
/// With `MATTES`, each sample's share of the pixel's opacity goes to `coverage`, for the matte
/// of the medium's piece that dominates it ([`Medium::label`]); with `PASSES`, its light by
/// component to the result's passes. Neither changes the beauty's bits.
#[inline]
#[allow(clippy::too_many_arguments)]
pub(super) fn march<
    M: Medium,
    L: Lights,
    const SHADE: bool,
    const PASSES: bool,
    const MATTES: bool,
>(
    medium: &M,
    lights: &L,
    shading: &Shading,
    scratch: &mut M::Scratch,
    ray: &Ray,
    jitter: f32,
    optical_step: f32,
    coverage: &mut Coverage<'_>,
) -> PixelResult {
    medium.begin_ray(ray, scratch);
    // The phase weights depend on the direction only: formed at the first shaded sample, so a
    // ray that misses the cloud (most of a wide frame's sky) never pays for its 26 sky cells.
    let mut weights = None;
    let coarse = medium.step().max(1e-9);
    // Fine steps keep the light each one absorbs, `T·(1 − e^{−σh})`, near `optical_step`: thin
    // where the ray enters the cloud (what the eye sees most, and where the sunlit skin's light
    // changes fastest), growing to [`MAX_OPTICAL_STEP`] as the transmittance falls.
    let inv_sigma = 1.0 / medium.max_extinction().max(1e-12);
    let fine = |t_acc: f32| {
        ((optical_step / t_acc).min(MAX_OPTICAL_STEP) * inv_sigma).clamp(coarse * 1e-3, coarse)
    };
    let (mut t_acc, mut rgb, mut depth_sum, mut tau) = (1.0f32, Vec3A::ZERO, 0.0f32, 0.0f32);
    let mut budget = MAX_STEPS;
    let mut passes = [Vec3A::ZERO; 3];
    'intervals: for n in 0..medium.intervals(scratch).len() {
        let [a, b] = medium.intervals(scratch)[n];
        // `last_empty`: where the medium was last seen empty; a coarse hit re-marches from it.
        let (mut s, mut h, mut in_medium, mut empty_run, mut last_empty) =
            (a, coarse, false, 0.0f32, a);
        while s < b && budget > 0 {
            budget -= 1;
            let len = h.min(b - s);
            let t = s + jitter * len;
            let x = ray.at(t);
            let (sigma, inside) = medium.sample(scratch, t, x);
            if counters::ENABLED {
                if !in_medium {
                    counters::add(Counter::CoarseSamples, 1);
                } else if !inside {
                    counters::add(Counter::FineOutside, 1);
                }
            }
            if !inside {
                last_empty = t;
                s += len;
                empty_run += len;
                if in_medium && empty_run >= coarse {
                    in_medium = false;
                    h = coarse;
                }
                continue;
            }
            empty_run = 0.0;
            if !in_medium {
                in_medium = true;
                let f = fine(t_acc);
                if f < h {
                    // Found the medium at coarse speed: re-march finely from the last empty
                    // sample (everything before it was sampled empty; what follows was only
                    // assumed so).
                    h = f;
                    s = last_empty;
                    continue;
                }
            }
            if sigma <= 0.0 {
                counters::add(Counter::EmptyFine, 1);
                s += len;
                continue;
            }
            let absorbed = t_acc * (1.0 - (-sigma * len).exp());
            if MATTES {
                coverage.add(medium.label(scratch, t), absorbed);
            }
            if SHADE {
                let w = weights.get_or_insert_with(|| shading.ray_weights(ray.dir));
                counters::add(Counter::ShadedSamples, 1);
                let depths = lights.depths(x);
                let light = shading.in_scattered(w, &depths);
                let k = absorbed * shading.albedo;
                rgb += light.total() * k;
                if PASSES {
                    passes[0] += light.sun() * k;
                    passes[1] += light.sky() * k;
                    passes[2] += light.multiple() * k;
                }
            }
            tau += sigma * len;
            depth_sum += t * absorbed;
            t_acc -= absorbed;
            s += len;
            if t_acc < MIN_TRANSMITTANCE {
                break 'intervals;
            }
            h = fine(t_acc);
        }
    }
    if SHADE && t_acc >= MIN_TRANSMITTANCE {
        let forward = shading.forward_sky(ray.dir, tau);
        rgb += forward;
        // Sky light scattered straight on is the sky's single scattering (its forward lobe).
        passes[1] += forward;
    }
    let coverage = 1.0 - t_acc;
    PixelResult {
        rgb,
        transmittance: t_acc,
        depth: if coverage > 0.0 {
            depth_sum / coverage
        } else {
            f32::INFINITY
        },
        passes,
    }
}

/// The running mean of a pixel's rays (coverage-weighted depth).
#[derive(Clone, Copy, Debug)]
pub(super) struct PixelSum {
    acc: PixelResult,
    depth_w: f32,
}

impl PixelSum {
    pub(super) fn new() -> PixelSum {
        PixelSum {
            acc: PixelResult {
                rgb: Vec3A::ZERO,
                transmittance: 0.0,
                depth: 0.0,
                passes: [Vec3A::ZERO; 3],
            },
            depth_w: 0.0,
        }
    }

    pub(super) fn add(&mut self, r: &PixelResult) {
        self.acc.rgb += r.rgb;
        self.acc.transmittance += r.transmittance;
        for (a, p) in self.acc.passes.iter_mut().zip(r.passes) {
            *a += p;
        }
        if r.depth.is_finite() {
            let c = 1.0 - r.transmittance;
            self.acc.depth += r.depth * c;
            self.depth_w += c;
        }
    }

    /// The mean of `n` rays added.
    pub(super) fn mean(self, n: u32) -> PixelResult {
        let mut acc = self.acc;
        let inv = 1.0 / n as f32;
        acc.rgb *= inv;
        acc.transmittance *= inv;
        acc.passes = acc.passes.map(|p| p * inv);
        acc.depth = if self.depth_w > 0.0 {
            acc.depth / self.depth_w
        } else {
            f32::INFINITY
        };
        acc
    }
}

/// Ray `k` of pixel `(x, y)` with `samples` rays on a `side × side` stratified grid (the pixel
/// centre when `samples == 1`) and its march jitter, drawn from the pixel's generator in the
/// order [`render_medium`] draws them.
#[inline]
pub(super) fn pixel_sample(
    cam: &CameraRays,
    (x, y): (u32, u32),
    k: u32,
    (samples, side): (u32, u32),
    rng: &mut impl rand::Rng,
) -> (Ray, f32) {
    if samples == 1 {
        return (cam.pixel_ray(x, y), rng.random());
    }
    let (cx, cy) = ((k % side) as f32, (k / side % side) as f32);
    let (u, v, jitter): (f32, f32, f32) = (rng.random(), rng.random(), rng.random());
    let ray = cam.ray(
        x as f32 + (cx + u) / side as f32,
        y as f32 + (cy + v) / side as f32,
    );
    (ray, jitter)
}
