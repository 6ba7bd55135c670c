//! The march's step policy ([`MarchSteps`]): where along a ray's intervals the next sample
//! goes and how long its segment is — coarse through empty space, fine inside the medium,
//! strides through the empty band before the ray meets density, and the backtracking when a
//! long step finds density. What a sample adds is the accumulator's
//! ([`super::accumulate::Accumulator`]); the stepper only hears back what the sample saw.

use crate::render::counters::{self, Counter};
use crate::render::medium::Medium;

/// Largest optical thickness of one fine step, reached where the transmittance has fallen to
/// `optical_step / MAX_OPTICAL_STEP`.
pub(crate) const MAX_OPTICAL_STEP: f32 = 1.0;

/// Most samples one ray may take (guards against unbounded intervals).
const MAX_STEPS: u32 = 1_000_000;

/// One segment of the march: the sample's parameter `t` along the ray and the segment's
/// length, over which the sample's extinction is taken as constant.
#[derive(Clone, Copy, Debug)]
pub(super) struct Segment {
    /// Where the sample lies (`s + ξ·len`, `ξ` the pixel's jitter).
    pub(super) t: f32,
    /// The segment's length `h`, clipped to the interval.
    pub(super) len: f32,
}

/// One ray's step policy: yields the segments of each interval in turn ([`MarchSteps::enter`],
/// [`MarchSteps::next`]) and decides from each sample what the next one is
/// ([`MarchSteps::absorbs`], [`MarchSteps::advance`]).
///
/// Two speeds: coarse segments of [`Medium::step`] cross the empty parts of the intervals; the
/// first coarse sample that finds the medium is discarded and the march resumes from the last
/// sample that was empty, in fine segments of optical thickness at most `optical_step` (so a
/// step never hides a steep change of light depth); after a coarse step's worth of empty fine
/// samples the march coarsens again. Until the ray has met density, an empty sample where
/// density may lie (the billows' outer band) is followed by a stride of
/// [`Medium::empty_stride`] when that is longer than the fine step; a stride that finds density
/// is discarded like a coarse one and its span re-marched finely from the empty sample before
/// it. Segments are clipped to the interval, so piecewise-constant media integrate exactly.
#[derive(Clone, Copy, Debug)]
pub(super) struct MarchSteps {
    /// The coarse step through empty space.
    coarse: f32,
    /// `1 / σ_max`: a fine step's length per unit of optical thickness.
    inv_sigma: f32,
    /// The optical thickness a fine step absorbs at full transmittance.
    optical_step: f32,
    /// The stride through the empty band (0: none), at most a coarse step.
    stride: f32,
    /// Samples the ray may still take, over all its intervals.
    budget: u32,
    /// The end of the interval being marched.
    b: f32,
    /// The start of the next segment.
    s: f32,
    /// The next segment's length (before clipping).
    h: f32,
    /// Whether the march is at fine speed (it has found the medium's shape).
    in_medium: bool,
    /// Length of the empty samples since the medium's shape was last seen.
    empty_run: f32,
    /// Where the medium was last seen empty; a coarse step or stride that finds it re-marches
    /// from here.
    last_empty: f32,
    /// After a stride found density, the fine steps run at least to the stride's end (else
    /// they would stride again into the density they went back for, and re-march it over and
    /// over).
    fine_to: f32,
    /// The segment last yielded.
    seg: Segment,
}

impl MarchSteps {
    /// The step policy of one ray through `medium`, fine steps absorbing about `optical_step`.
    #[inline]
    pub(super) fn new<M: Medium>(medium: &M, optical_step: f32) -> MarchSteps {
        let coarse = medium.step().max(1e-9);
        MarchSteps {
            coarse,
            inv_sigma: 1.0 / medium.max_extinction().max(1e-12),
            optical_step,
            stride: medium.empty_stride().min(coarse),
            budget: MAX_STEPS,
            b: 0.0,
            s: 0.0,
            h: coarse,
            in_medium: false,
            empty_run: 0.0,
            last_empty: 0.0,
            fine_to: 0.0,
            seg: Segment { t: 0.0, len: 0.0 },
        }
    }

    /// Start the interval `[a, b]`, at coarse speed from `a`.
    #[inline]
    pub(super) fn enter(&mut self, [a, b]: [f32; 2]) {
        self.b = b;
        self.s = a;
        self.h = self.coarse;
        self.in_medium = false;
        self.empty_run = 0.0;
        self.last_empty = a;
        self.fine_to = a;
    }

    /// The next segment of the interval, its sample placed at `jitter ∈ [0, 1)` inside it;
    /// `None` at the interval's end or when the ray's budget is spent.
    #[inline]
    pub(super) fn next(&mut self, jitter: f32) -> Option<Segment> {
        if !(self.s < self.b && self.budget > 0) {
            return None;
        }
        self.budget -= 1;
        let len = self.h.min(self.b - self.s);
        self.seg = Segment {
            t: self.s + jitter * len,
            len,
        };
        Some(self.seg)
    }

    /// The fine step at transmittance `t_acc`: it keeps the light each step absorbs,
    /// `T·(1 − e^{−σh})`, near `optical_step` — thin where the ray enters the cloud (what the
    /// eye sees most, and where the sunlit skin's light changes fastest), growing to
    /// [`MAX_OPTICAL_STEP`] as the transmittance falls.
    #[inline]
    fn fine(&self, t_acc: f32) -> f32 {
        ((self.optical_step / t_acc).min(MAX_OPTICAL_STEP) * self.inv_sigma)
            .clamp(self.coarse * 1e-3, self.coarse)
    }

    /// What the last segment's sample saw (`sigma` and whether it lies inside the medium's
    /// shape, [`Medium::sample`]) at transmittance `t_acc`: `true` when it is to be
    /// accumulated (then [`MarchSteps::advance`] follows); `false` when the march has moved on
    /// past an empty sample or gone back to re-march a step too long for the density it found.
    #[inline]
    pub(super) fn absorbs(&mut self, sigma: f32, inside: bool, t_acc: f32) -> bool {
        let Segment { t, len } = self.seg;
        if counters::ENABLED {
            if !self.in_medium {
                counters::add(Counter::CoarseSamples, 1);
            } else if !inside {
                counters::add(Counter::FineOutside, 1);
            }
        }
        if !inside {
            self.last_empty = t;
            self.s += len;
            self.empty_run += len;
            if self.in_medium && self.empty_run >= self.coarse {
                self.in_medium = false;
                self.h = self.coarse;
            }
            return false;
        }
        self.empty_run = 0.0;
        if !self.in_medium {
            self.in_medium = true;
            let f = self.fine(t_acc);
            if f < self.h {
                // Found the medium at coarse speed: re-march finely from the last empty sample
                // (everything before it was sampled empty; what follows was only assumed so).
                self.h = f;
                self.s = self.last_empty;
                return false;
            }
        }
        if sigma <= 0.0 {
            counters::add(Counter::EmptyFine, 1);
            self.last_empty = t;
            self.s += len;
            if self.s >= self.fine_to {
                let f = self.fine(t_acc);
                // Stride only before the ray has met density (`t_acc == 1`).
                self.h = if self.stride > f && t_acc == 1.0 {
                    self.stride
                } else {
                    f
                };
            }
            return false;
        }
        let f = self.fine(t_acc);
        if self.h > f {
            // A stride found density (the only step longer than the fine one here): go back to
            // the empty sample before it and step finely over the whole stride.
            self.fine_to = self.s + len;
            self.h = f;
            self.s = self.last_empty;
            return false;
        }
        true
    }

    /// Past an accumulated sample, now at transmittance `t_acc`: the next fine segment.
    #[inline]
    pub(super) fn advance(&mut self, t_acc: f32) {
        self.s += self.seg.len;
        self.h = self.fine(t_acc);
    }
}
