//! Free flights and transmittance through a [`Medium`] against its majorant
//! ([`super::majorant::Majorant`]): delta tracking (Woodcock et al. 1965) samples where a path
//! first collides, ratio tracking (Novák et al. 2014) estimates the transmittance of a shadow
//! ray, both unbiased for any density below the majorant.
//!
//! In: the medium, a ray, the path's generator. Out: a collision distance or a transmittance
//! estimate; every density evaluation is counted in [`Tracker::evaluations`].

use glam::Vec3A;
use rand::RngExt;
use rand_pcg::Pcg64Mcg;

use super::majorant::Majorant;
use crate::render::camera::Ray;
use crate::render::medium::Medium;

/// Below this transmittance a ratio-tracked shadow ray plays Russian roulette: it goes on with
/// probability `T / ROULETTE_T`, then carrying `ROULETTE_T` (unbiased; a ray deep in a thick
/// cloud stops early instead of evaluating the density all the way out).
const ROULETTE_T: f32 = 0.1;

/// A thread's tracking state: the medium's scratch, the current ray's majorant spans (copied
/// out of the scratch, reused: no allocation per ray once warm) and the work counters.
pub(crate) struct Tracker<S> {
    /// The medium's scratch (begun on every ray: [`Frustum::EVERYTHING`] per tile).
    ///
    /// [`Frustum::EVERYTHING`]: crate::render::camera::Frustum::EVERYTHING
    pub(crate) medium: S,
    spans: Vec<[f32; 2]>,
    /// Density evaluations so far.
    pub(crate) evaluations: u64,
    /// Rays begun so far (camera, continuation and shadow rays).
    pub(crate) rays: u64,
}

impl<S> Tracker<S> {
    /// A tracker with `medium` as its scratch.
    pub(crate) fn new(medium: S) -> Tracker<S> {
        Tracker {
            medium,
            spans: Vec::new(),
            evaluations: 0,
            rays: 0,
        }
    }

    /// Prepare `ray`: the medium's intervals along it become the majorant's spans.
    pub(crate) fn begin<M: Medium<Scratch = S>>(&mut self, medium: &M, ray: &Ray) {
        medium.begin_ray(ray, &mut self.medium);
        self.spans.clear();
        self.spans.extend_from_slice(medium.intervals(&self.medium));
        self.rays += 1;
    }

    /// `σ_t` at `t` of the ray begun, never above the majorant (a medium whose
    /// [`Medium::max_extinction`] is not a bound would otherwise bias the tracking).
    #[inline]
    fn sigma<M: Medium<Scratch = S>>(&mut self, medium: &M, ray: &Ray, t: f32, bar: f32) -> f32 {
        self.evaluations += 1;
        let x: Vec3A = ray.at(t);
        medium.extinction(&mut self.medium, t, x).clamp(0.0, bar)
    }

    /// Delta tracking along the ray begun: the distance of its first real collision, or `None`
    /// when it leaves the medium.
    pub(crate) fn free_flight<M: Medium<Scratch = S>>(
        &mut self,
        medium: &M,
        majorant: &Majorant,
        ray: &Ray,
        rng: &mut Pcg64Mcg,
    ) -> Option<f32> {
        let bar = majorant.sigma;
        if bar <= 0.0 {
            return None;
        }
        for k in 0..self.spans.len() {
            let [a, b] = self.spans[k];
            let mut t = a;
            loop {
                let u: f32 = rng.random();
                t -= (1.0 - u).ln() / bar;
                if t >= b {
                    break;
                }
                let sigma = self.sigma(medium, ray, t, bar);
                let v: f32 = rng.random();
                if v * bar < sigma {
                    return Some(t);
                }
            }
        }
        None
    }

    /// Ratio tracking along the ray begun: an unbiased estimate of its transmittance out of the
    /// medium (with Russian roulette below [`ROULETTE_T`]).
    pub(crate) fn transmittance<M: Medium<Scratch = S>>(
        &mut self,
        medium: &M,
        majorant: &Majorant,
        ray: &Ray,
        rng: &mut Pcg64Mcg,
    ) -> f32 {
        let bar = majorant.sigma;
        if bar <= 0.0 {
            return 1.0;
        }
        let mut tr = 1.0f32;
        for k in 0..self.spans.len() {
            let [a, b] = self.spans[k];
            let mut t = a;
            loop {
                let u: f32 = rng.random();
                t -= (1.0 - u).ln() / bar;
                if t >= b {
                    break;
                }
                tr *= 1.0 - self.sigma(medium, ray, t, bar) / bar;
                if tr <= 0.0 {
                    return 0.0;
                }
                if tr < ROULETTE_T {
                    let v: f32 = rng.random();
                    if v * ROULETTE_T >= tr {
                        return 0.0;
                    }
                    tr = ROULETTE_T;
                }
            }
        }
        tr
    }
}
