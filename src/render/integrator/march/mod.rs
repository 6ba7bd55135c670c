//! One ray's march through a [`Medium`] (see [`march`] and the integrator's module doc): the
//! coarse and fine segments, the energy-conserving step, the lighting of each sample through
//! [`ShadowDepths`] and [`Shading`], and the running mean of a pixel's rays ([`PixelSum`]).

mod pixel;

use pixel::PixelPasses;
pub(crate) use pixel::{PixelResult, PixelSum};

use glam::Vec3A;

use crate::render::camera::Ray;
use crate::render::counters::{self, Counter};
use crate::render::light::ShadowDepths;
use crate::render::light::shading::Shading;
use crate::render::medium::Medium;
use crate::render::output::cryptomatte::Coverage;
use crate::render::output::film::Film;

/// Transmittance below which a ray stops (its coverage is then `1 − T ≥ 0.999`).
pub(crate) const MIN_TRANSMITTANCE: f32 = 1e-3;

/// Largest optical thickness of one fine step, reached where the transmittance has fallen to
/// `optical_step / MAX_OPTICAL_STEP`.
pub(crate) const MAX_OPTICAL_STEP: f32 = 1.0;

/// Most samples one ray may take (guards against unbounded intervals).
const MAX_STEPS: u32 = 1_000_000;

/// One ray's march ([`march`], monomorphised for what it accumulates).
pub(crate) type MarchFn<M, L> = fn(
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
pub(crate) fn shaded_march<M: Medium, L: ShadowDepths>(film: &Film) -> MarchFn<M, L> {
    match (film.passes, film.mattes.is_some()) {
        (false, false) => march::<M, L, true, false, false>,
        (true, false) => march::<M, L, true, true, false>,
        (false, true) => march::<M, L, true, false, true>,
        (true, true) => march::<M, L, true, true, true>,
    }
}

/// March one ray. `jitter ∈ [0, 1)` places the sample inside each segment.
///
/// Two speeds: coarse segments of [`Medium::step`] cross the empty parts of the intervals; the
/// first coarse sample that finds extinction is discarded and the march resumes from the last
/// sample that was empty, in fine
/// segments of optical thickness at most `optical_step` (so a step never hides a steep change
/// of light depth); after a coarse step's worth of empty fine samples the march coarsens again.
/// Until the ray has met density, an empty sample where density may lie (the billows' outer
/// band) is followed by a stride of [`Medium::empty_stride`] when that is longer than the fine
/// step; a stride that finds density is discarded like a coarse one and its span re-marched
/// finely from the empty sample before it.
/// Segments are clipped to the interval, so piecewise-constant media integrate exactly.
///
/// With `MATTES`, each sample's share of the pixel's opacity goes to `coverage`, for the matte
/// of the medium's piece that dominates it ([`Medium::label`]); with `PASSES`, its light by
/// component to the result's passes. Neither changes the beauty's bits.
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn march<
    M: Medium,
    L: ShadowDepths,
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
    let stride = medium.empty_stride().min(coarse);
    let (mut t_acc, mut rgb, mut depth_sum, mut tau) = (1.0f32, Vec3A::ZERO, 0.0f32, 0.0f32);
    let mut budget = MAX_STEPS;
    let mut passes = PixelPasses::ZERO;
    'intervals: for n in 0..medium.intervals(scratch).len() {
        let [a, b] = medium.intervals(scratch)[n];
        // `last_empty`: where the medium was last seen empty; a coarse hit re-marches from it.
        let (mut s, mut h, mut in_medium, mut empty_run, mut last_empty) =
            (a, coarse, false, 0.0f32, a);
        // `fine_to`: after a stride found density, the fine steps run at least to the stride's
        // end (else they would stride again into the density they went back for, and re-march
        // it over and over).
        let mut fine_to = a;
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
                last_empty = t;
                s += len;
                if s >= fine_to {
                    let f = fine(t_acc);
                    h = if stride > f && t_acc == 1.0 {
                        stride
                    } else {
                        f
                    };
                }
                continue;
            }
            let f = fine(t_acc);
            if h > f {
                // A stride found density (the only step longer than the fine one here): go back
                // to the empty sample before it and step finely over the whole stride.
                fine_to = s + len;
                h = f;
                s = last_empty;
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
                    passes.sun += light.sun() * k;
                    passes.sky += light.sky() * k;
                    passes.multiple += light.multiple() * k;
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
        passes.sky += forward;
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
