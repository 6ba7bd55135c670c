//! What a sample adds to its ray ([`Accumulator`]): the energy-conserving step
//! `L += T·(1 − e^{−σh})·albedo·L_in`, `T −= T·(1 − e^{−σh})` (Hillaire 2015), the light by
//! render pass, the opacity-weighted depth, the optical depth along the ray for the sky's
//! forward lobe, and the early termination. Where the samples go is the stepper's
//! ([`super::steps::MarchSteps`]).

use glam::Vec3A;

use crate::render::counters::{self, Counter};
use crate::render::integrator::march::pixel::{PixelPasses, PixelResult};
use crate::render::light::ShadowDepths;
use crate::render::light::shading::{RayWeights, Shading};

/// Transmittance below which a ray stops (its coverage is then `1 − T ≥ 0.999`).
pub(crate) const MIN_TRANSMITTANCE: f32 = 1e-3;

/// One ray's running sums, accumulating the render passes with `PASSES`.
#[derive(Clone, Debug)]
pub(super) struct Accumulator<const PASSES: bool> {
    /// Transmittance `T` from the eye to the current sample.
    t_acc: f32,
    /// Radiance scattered toward the eye so far (premultiplied).
    rgb: Vec3A,
    /// The same by render pass (with `PASSES`).
    passes: PixelPasses,
    /// `Σ t·absorbed`: the depth weighted by each sample's share of the opacity.
    depth_sum: f32,
    /// Optical depth `τ` along the ray so far.
    tau: f32,
    /// The phase weights toward the eye, formed at the first shaded sample: a ray that misses
    /// the cloud (most of a wide frame's sky) never pays for its 26 sky cells.
    weights: Option<RayWeights>,
}

impl<const PASSES: bool> Accumulator<PASSES> {
    /// Nothing seen yet: transmittance 1.
    #[inline]
    pub(super) fn new() -> Self {
        Accumulator {
            t_acc: 1.0,
            rgb: Vec3A::ZERO,
            passes: PixelPasses::ZERO,
            depth_sum: 0.0,
            tau: 0.0,
            weights: None,
        }
    }

    /// Transmittance from the eye to the current sample.
    #[inline]
    pub(super) fn transmittance(&self) -> f32 {
        self.t_acc
    }

    /// The share of the pixel's light a segment of extinction `sigma` and length `len` absorbs,
    /// `T·(1 − e^{−σh})` (also its share of the pixel's opacity, for the ID mattes).
    #[inline]
    pub(super) fn absorbed(&self, sigma: f32, len: f32) -> f32 {
        self.t_acc * (1.0 - (-sigma * len).exp())
    }

    /// Add the light scattered toward the eye along `dir` at `x`, where the sample absorbs
    /// `absorbed` ([`Accumulator::absorbed`]): the lights' depths there, shaded.
    #[inline]
    pub(super) fn scatter<L: ShadowDepths>(
        &mut self,
        shading: &Shading,
        lights: &L,
        dir: Vec3A,
        x: Vec3A,
        absorbed: f32,
    ) {
        let w = self.weights.get_or_insert_with(|| shading.ray_weights(dir));
        counters::add(Counter::ShadedSamples, 1);
        let depths = lights.depths(x);
        let mut light = shading.in_scattered(w, &depths);
        if shading.fluence {
            light = light.with_multiple(shading.fluence_in(
                &lights.multiple(x),
                dir,
                depths.sun,
                w.sun[0],
            ));
        }
        let k = absorbed * shading.albedo;
        self.rgb += light.total() * k;
        if PASSES {
            self.passes.sun += light.sun() * k;
            self.passes.sky += light.sky() * k;
            self.passes.multiple += light.multiple() * k;
        }
    }

    /// Attenuate the ray past a sample at `t` of extinction `sigma` over `len` that absorbed
    /// `absorbed`. Returns whether the ray is now opaque enough to stop
    /// ([`MIN_TRANSMITTANCE`]).
    #[inline]
    pub(super) fn attenuate(&mut self, t: f32, sigma: f32, len: f32, absorbed: f32) -> bool {
        self.tau += sigma * len;
        self.depth_sum += t * absorbed;
        self.t_acc -= absorbed;
        self.t_acc < MIN_TRANSMITTANCE
    }

    /// The ray has left the medium along `dir` without stopping: add the sky light scattered
    /// straight on along it ([`Shading::forward_sky`]), the sky's single scattering by its
    /// forward lobe.
    #[inline]
    pub(super) fn leave(&mut self, shading: &Shading, dir: Vec3A) {
        if self.t_acc >= MIN_TRANSMITTANCE {
            let forward = shading.forward_sky(dir, self.tau);
            self.rgb += forward;
            if PASSES {
                self.passes.sky += forward;
            }
        }
    }

    /// The ray's result: radiance, transmittance, passes and the opacity-weighted mean depth
    /// (infinity where it met nothing).
    #[inline]
    pub(super) fn result(self) -> PixelResult {
        let coverage = 1.0 - self.t_acc;
        PixelResult {
            rgb: self.rgb,
            transmittance: self.t_acc,
            depth: if coverage > 0.0 {
                self.depth_sum / coverage
            } else {
                f32::INFINITY
            },
            passes: self.passes,
            holdout: 0.0,
            shadow: 1.0,
        }
    }
}
