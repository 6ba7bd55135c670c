//! One ray's march through a [`Medium`] ([`march`]): a stepper that says where the samples go
//! ([`steps::MarchSteps`]: coarse, fine and stride segments, backtracking) and an accumulator
//! that says what each adds ([`accumulate::Accumulator`]: transmittance, light by pass, depth,
//! early termination), lit through [`ShadowDepths`] and [`Shading`]; and the running mean of a
//! pixel's rays ([`PixelSum`]). The split is pbrt-v4's (`SampleT_maj` yields the segments, the
//! integrator's callback accumulates), except that the step here hears back what each sample
//! saw.

mod accumulate;
pub(crate) mod motion;
mod pixel;
mod steps;

pub(crate) use motion::{MotionSum, ScreenMotion};
pub(crate) use pixel::{PixelPasses, PixelResult, PixelSum};

use crate::render::camera::Ray;
use crate::render::light::ShadowDepths;
use crate::render::light::shading::Shading;
use crate::render::medium::Medium;
use crate::render::output::cryptomatte::Coverage;
use crate::render::output::film::Film;

use accumulate::Accumulator;
use steps::{MarchSteps, Segment};

/// One ray's march ([`march`], monomorphised for what it accumulates).
pub(crate) type MarchFn<M, L> = fn(
    &M,
    &L,
    &Shading,
    &mut <M as Medium>::Scratch,
    &Ray,
    f32,
    f32,
    f32,
    &mut Coverage<'_>,
    &mut MotionSum<'_>,
) -> PixelResult;

/// The shaded march that accumulates what `film` asks for (passes, mattes, motion vectors);
/// chosen once per frame, so the per-sample loop has no test for any of them.
pub(crate) fn shaded_march<M: Medium, L: ShadowDepths>(film: &Film) -> MarchFn<M, L> {
    match (film.passes, film.mattes.is_some(), film.motion) {
        (false, false, false) => march::<M, L, true, false, false, false>,
        (true, false, false) => march::<M, L, true, true, false, false>,
        (false, true, false) => march::<M, L, true, false, true, false>,
        (true, true, false) => march::<M, L, true, true, true, false>,
        (false, false, true) => march::<M, L, true, false, false, true>,
        (true, false, true) => march::<M, L, true, true, false, true>,
        (false, true, true) => march::<M, L, true, false, true, true>,
        (true, true, true) => march::<M, L, true, true, true, true>,
    }
}

/// March one ray through the medium's intervals. `jitter ∈ [0, 1)` places the sample inside
/// each segment; fine segments absorb about `optical_step` of the pixel's light. The segments
/// are [`MarchSteps`]' (its doc has the policy); each sample that absorbs is integrated with
/// the energy-conserving step by the [`Accumulator`], and a ray that leaves the cloud adds the
/// sky light scattered straight on along it. The ray stops at `t_max` (a holdout's surface:
/// infinity when it meets none, and then the march is the same to the bit); a ray stopped there
/// adds no sky light straight on (the holdout hides the sky behind it).
///
/// With `SHADE`, the samples are lit (else coverage and depth only); with `MATTES`, each
/// sample's share of the pixel's opacity goes to `coverage`, for the matte of the medium's
/// piece that dominates it ([`Medium::label`]); with `PASSES`, its light by component to the
/// result's passes; with `MOTION`, its screen motion weighted by its share of the opacity to
/// `motion` ([`MotionSum`]). None of the last three changes the beauty's bits.
#[inline]
#[allow(clippy::too_many_arguments)]
pub(crate) fn march<
    M: Medium,
    L: ShadowDepths,
    const SHADE: bool,
    const PASSES: bool,
    const MATTES: bool,
    const MOTION: bool,
>(
    medium: &M,
    lights: &L,
    shading: &Shading,
    scratch: &mut M::Scratch,
    ray: &Ray,
    jitter: f32,
    optical_step: f32,
    t_max: f32,
    coverage: &mut Coverage<'_>,
    motion: &mut MotionSum<'_>,
) -> PixelResult {
    medium.begin_ray(ray, scratch);
    let mut steps = MarchSteps::new(medium, optical_step);
    let mut acc = Accumulator::<PASSES>::new();
    'intervals: for n in 0..medium.intervals(scratch).len() {
        let [a, b] = medium.intervals(scratch)[n];
        if a >= t_max {
            break;
        }
        steps.enter([a, b.min(t_max)]);
        while let Some(Segment { t, len }) = steps.next(jitter) {
            let x = ray.at(t);
            let (sigma, inside) = medium.sample(scratch, t, x);
            if !steps.absorbs(sigma, inside, acc.transmittance()) {
                continue;
            }
            let absorbed = acc.absorbed(sigma, len);
            if MATTES {
                coverage.add(medium.label(scratch, t), absorbed);
            }
            if MOTION {
                motion.add(x, absorbed);
            }
            if SHADE {
                acc.scatter(shading, lights, ray.dir, x, absorbed);
            }
            if acc.attenuate(t, sigma, len, absorbed) {
                break 'intervals;
            }
            steps.advance(acc.transmittance());
        }
    }
    if SHADE && t_max == f32::INFINITY {
        acc.leave(shading, ray.dir);
    }
    acc.result()
}

/// Transmittance below which a shadow ray stops ([`optical_depth`]).
const MIN_SHADOW_TRANSMITTANCE: f32 = 1e-4;

/// Steps of the shadow pass's march per coarse step of the medium ([`optical_depth`]).
const SHADOW_STEPS_PER_COARSE: f32 = 8.0;

/// The optical depth `∫σ dt` along `ray` through the medium's intervals (the shadow pass's ray
/// toward the sun from a surface): uniform steps of an eighth of the medium's coarse step
/// ([`Medium::step`]), each sampled at `jitter` inside it — no coarse steps through the
/// empty parts, which would step over the thin fringe a grazing shadow ray crosses (one such
/// ray a camera ray is affordable) — stopping once the transmittance is below 10⁻⁴. `scratch`
/// must have begun a tile that contains the ray ([`crate::render::Frustum::EVERYTHING`]).
pub(crate) fn optical_depth<M: Medium>(
    medium: &M,
    scratch: &mut M::Scratch,
    ray: &Ray,
    jitter: f32,
) -> f32 {
    medium.begin_ray(ray, scratch);
    let h = medium.step().max(1e-9) / SHADOW_STEPS_PER_COARSE;
    let min_tau = -MIN_SHADOW_TRANSMITTANCE.ln();
    let mut tau = 0.0f32;
    for n in 0..medium.intervals(scratch).len() {
        let [a, b] = medium.intervals(scratch)[n];
        let mut s = a;
        while s < b {
            let len = h.min(b - s);
            let t = s + jitter * len;
            tau += medium.extinction(scratch, t, ray.at(t)) * len;
            if tau > min_tau {
                return tau;
            }
            s += len;
        }
    }
    tau
}
