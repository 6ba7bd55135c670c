//! What a ray's march gives ([`PixelResult`], its light by pass in [`PixelPasses`]) and the
//! running mean of a pixel's rays ([`PixelSum`]).

use std::ops::{AddAssign, Mul};

use glam::Vec3A;

/// One ray's or pixel's light by render pass (premultiplied): what the frame's
/// [`crate::render::Passes`] hold per pixel. `sun + sky + multiple` is the beauty's RGB up to
/// rounding.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct PixelPasses {
    /// Sunlight scattered once.
    pub(crate) sun: Vec3A,
    /// Sky light scattered once (the sky cells, and the forward lobe straight through).
    pub(crate) sky: Vec3A,
    /// The multiple-scattering approximation (sun and sky octaves beyond the first).
    pub(crate) multiple: Vec3A,
}

impl PixelPasses {
    /// No light in any pass.
    pub(crate) const ZERO: PixelPasses = PixelPasses {
        sun: Vec3A::ZERO,
        sky: Vec3A::ZERO,
        multiple: Vec3A::ZERO,
    };
}

impl AddAssign for PixelPasses {
    /// Pass by pass.
    #[inline]
    fn add_assign(&mut self, o: PixelPasses) {
        self.sun += o.sun;
        self.sky += o.sky;
        self.multiple += o.multiple;
    }
}

impl Mul<f32> for PixelPasses {
    type Output = PixelPasses;

    /// Every pass scaled by `k`.
    #[inline]
    fn mul(self, k: f32) -> PixelPasses {
        PixelPasses {
            sun: self.sun * k,
            sky: self.sky * k,
            multiple: self.multiple * k,
        }
    }
}

/// What one ray's march (or the mean of a pixel's rays) produced.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PixelResult {
    /// Radiance scattered toward the eye (premultiplied).
    pub(crate) rgb: Vec3A,
    /// Transmittance along the ray (`1 −` coverage).
    pub(crate) transmittance: f32,
    /// Opacity-weighted mean distance along the ray (infinity where it met nothing).
    pub(crate) depth: f32,
    /// The render passes, when asked for (else zero).
    pub(crate) passes: PixelPasses,
    /// Share of the rays stopped by a holdout (the `holdout` layer; 0 without holdouts).
    pub(crate) holdout: f32,
    /// The sun's transmittance through the cloud from the surface the rays see (the `shadow`
    /// layer; 1 where they see none, and without the pass).
    pub(crate) shadow: f32,
}

/// The running mean of a pixel's rays (coverage-weighted depth).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PixelSum {
    acc: PixelResult,
    depth_w: f32,
}

impl PixelSum {
    /// No rays yet.
    pub(crate) fn new() -> PixelSum {
        PixelSum {
            acc: PixelResult {
                rgb: Vec3A::ZERO,
                transmittance: 0.0,
                depth: 0.0,
                passes: PixelPasses::ZERO,
                holdout: 0.0,
                shadow: 0.0,
            },
            depth_w: 0.0,
        }
    }

    /// Add one ray's result.
    pub(crate) fn add(&mut self, r: &PixelResult) {
        self.acc.rgb += r.rgb;
        self.acc.transmittance += r.transmittance;
        self.acc.passes += r.passes;
        self.acc.holdout += r.holdout;
        self.acc.shadow += r.shadow;
        if r.depth.is_finite() {
            let c = 1.0 - r.transmittance;
            self.acc.depth += r.depth * c;
            self.depth_w += c;
        }
    }

    /// The mean of `n` rays added.
    pub(crate) fn mean(self, n: u32) -> PixelResult {
        let mut acc = self.acc;
        let inv = 1.0 / n as f32;
        acc.rgb *= inv;
        acc.transmittance *= inv;
        acc.passes = acc.passes * inv;
        acc.holdout *= inv;
        acc.shadow *= inv;
        acc.depth = if self.depth_w > 0.0 {
            acc.depth / self.depth_w
        } else {
            f32::INFINITY
        };
        acc
    }
}
