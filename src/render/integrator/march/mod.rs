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
pub(crate) use pixel::{PixelResult, PixelSum};

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
/// sky light scattered straight on along it.
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
    coverage: &mut Coverage<'_>,
    motion: &mut MotionSum<'_>,
) -> PixelResult {
    medium.begin_ray(ray, scratch);
    let mut steps = MarchSteps::new(medium, optical_step);
    let mut acc = Accumulator::<PASSES>::new();
    'intervals: for n in 0..medium.intervals(scratch).len() {
        steps.enter(medium.intervals(scratch)[n]);
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
    if SHADE {
        acc.leave(shading, ray.dir);
    }
    acc.result()
}
