//! One path from the camera: delta-tracked collisions, next-event estimation toward the sun
//! and the sky at every collision, the phase function sampled exactly for the next direction,
//! Russian roulette; its light by scattering order (the passes).
//!
//! The estimator, per collision `x` of a path with throughput `β` (the albedo's product so far)
//! arriving along `d`:
//!
//! ```text
//! sun:  β·a·p(−s·d)·T(x → sun)·E_sun                         s the sun's travel direction
//! sky:  β·a·p(d·l)·T(x, l)·L_sky(l)·w_l / q_l                 l uniform on the sphere, q_l = 1/4π
//! next: d' ~ p(d·d') (weight 1); leaving the cloud it sees L_sky(d')·β·a·w_p
//! ```
//!
//! with `p` the two-lobe [`cloud_phase`], `a` the albedo, `T` ratio-tracked, and `w_l`, `w_p`
//! the power heuristic between the sky's uniform sampling and the phase function's (Veach
//! 1997): a bright forward lobe is found by the phase sample, the sky behind the point by the
//! light sample. The sun is a delta light (next-event estimation alone).

use std::f32::consts::PI;

use glam::{Vec3, Vec3A};
use rand::RngExt;
use rand_pcg::Pcg64Mcg;

use super::majorant::Majorant;
use super::tracking::Tracker;
use crate::render::camera::Ray;
use crate::render::integrator::march::PixelPasses;
use crate::render::light::phase::{self, cloud_phase};
use crate::render::light::shading::Shading;
use crate::render::light::sky_dome::SkyDome;
use crate::render::medium::Medium;

/// From this many collisions on a path plays Russian roulette on its throughput.
const ROULETTE_FROM: u32 = 4;

/// Density of the sky's uniform direction sampling.
const SKY_PDF: f32 = 1.0 / (4.0 * PI);

/// What lights the paths, for one frame: the sun and the cloud's material as the march's
/// [`Shading::new`] has them, the sky as [`SkyDome::light_radiance`].
pub(crate) struct PathLights {
    /// Unit direction the sunlight travels.
    sun_dir: Vec3A,
    /// Sun colour × intensity × the sky's tint.
    sun_radiance: Vec3A,
    dome: SkyDome,
    albedo: f32,
    g: f32,
    /// Scattering orders up to `max_depth − 1`.
    max_depth: u32,
}

impl PathLights {
    /// The lights of `shading`'s frame under `dome`, paths up to `max_depth` (Mitsuba's count).
    pub(crate) fn new(shading: &Shading, dome: SkyDome, max_depth: u32) -> PathLights {
        PathLights {
            sun_dir: shading.sun_dir,
            sun_radiance: shading.sun_radiance,
            dome,
            albedo: shading.albedo,
            g: shading.g,
            max_depth: max_depth.max(2),
        }
    }

    fn sky(&self, dir: Vec3A) -> Vec3A {
        Vec3A::from(self.dome.light_radiance(Vec3::from(dir)))
    }
}

/// One camera path's estimate.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PathSample {
    /// Light by order: single scattering of the sun and the sky, and all orders ≥ 2.
    pub(crate) passes: PixelPasses,
    /// The camera ray's transmittance (ratio-tracked).
    pub(crate) transmittance: f32,
    /// Distance of the first collision (infinity when the ray met none).
    pub(crate) depth: f32,
    /// Collisions on the path.
    pub(crate) collisions: u32,
}

/// Trace the path of camera ray `ray`.
pub(crate) fn trace<M: Medium>(
    medium: &M,
    majorant: &Majorant,
    lights: &PathLights,
    tracker: &mut Tracker<M::Scratch>,
    ray: &Ray,
    rng: &mut Pcg64Mcg,
) -> PathSample {
    let mut out = PathSample {
        passes: PixelPasses::ZERO,
        transmittance: 1.0,
        depth: f32::INFINITY,
        collisions: 0,
    };
    tracker.begin(medium, ray);
    out.transmittance = tracker.transmittance(medium, majorant, ray, rng);
    let Some(t) = tracker.free_flight(medium, majorant, ray, rng) else {
        return out;
    };
    out.depth = t;
    let (mut x, mut d) = (ray.at(t), ray.dir);
    let mut beta = 1.0f32;
    let a = lights.albedo;
    for order in 1..lights.max_depth {
        out.collisions = order;
        if order >= ROULETTE_FROM {
            let q = beta.min(1.0);
            let u: f32 = rng.random();
            if q <= 0.0 || u >= q {
                break;
            }
            beta /= q;
        }
        let mut light = Vec3A::ZERO;
        // The sun.
        let p_sun = cloud_phase(-lights.sun_dir.dot(d), lights.g);
        if p_sun > 0.0 && lights.sun_radiance != Vec3A::ZERO {
            let shadow = Ray {
                origin: x,
                dir: -lights.sun_dir,
            };
            tracker.begin(medium, &shadow);
            let tr = tracker.transmittance(medium, majorant, &shadow, rng);
            light += lights.sun_radiance * (p_sun * tr);
        }
        let sun_light = light * (beta * a);
        // The sky, sampled uniformly.
        let l = uniform_sphere(rng.random(), rng.random());
        let p_l = cloud_phase(d.dot(l), lights.g);
        let sky_light_l = lights.sky(l);
        let mut sky_light = Vec3A::ZERO;
        if p_l > 0.0 && sky_light_l != Vec3A::ZERO {
            let shadow = Ray { origin: x, dir: l };
            tracker.begin(medium, &shadow);
            let tr = tracker.transmittance(medium, majorant, &shadow, rng);
            let w = power_heuristic(SKY_PDF, p_l);
            sky_light += sky_light_l * (beta * a * p_l * tr * w / SKY_PDF);
        }
        // The next direction, from the phase function (its weight p/pdf is 1).
        let (next, p_next) = sample_cloud_phase(d, lights.g, rng);
        beta *= a;
        let cont = Ray {
            origin: x,
            dir: next,
        };
        tracker.begin(medium, &cont);
        let hit = tracker.free_flight(medium, majorant, &cont, rng);
        if hit.is_none() {
            let w = power_heuristic(p_next, SKY_PDF);
            sky_light += lights.sky(next) * (beta * w);
        }
        if order == 1 {
            out.passes.sun += sun_light;
            out.passes.sky += sky_light;
        } else {
            out.passes.multiple += sun_light + sky_light;
        }
        match hit {
            Some(t) => {
                x = cont.at(t);
                d = next;
            }
            None => break,
        }
    }
    out
}

/// The power heuristic's weight of a sample drawn with density `f` against another strategy's
/// density `g` at the same direction.
#[inline]
fn power_heuristic(f: f32, g: f32) -> f32 {
    let (f2, g2) = (f * f, g * g);
    if f2 + g2 > 0.0 { f2 / (f2 + g2) } else { 0.0 }
}

/// A direction uniform on the unit sphere from two uniform numbers.
#[inline]
fn uniform_sphere(u: f32, v: f32) -> Vec3A {
    let z = 1.0 - 2.0 * u;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * PI * v;
    Vec3A::new(r * phi.cos(), r * phi.sin(), z)
}

/// A direction scattered from travel direction `d` by the two-lobe [`cloud_phase`]
/// ([`phase::sample_cloud_phase`]), and its density (the phase function's value).
pub(crate) fn sample_cloud_phase(d: Vec3A, g: f32, rng: &mut Pcg64Mcg) -> (Vec3A, f32) {
    let (dir, mu) = phase::sample_cloud_phase(d, g, [rng.random(), rng.random(), rng.random()]);
    (dir, cloud_phase(mu, g))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::light::phase::{BACK_LOBE_RATIO, BACK_LOBE_WEIGHT, basis};
    use crate::rng::{Stream, item_rng};

    /// The sampled cosines follow the two-lobe phase function: a histogram of 400,000 samples
    /// in 20 bins of `μ` against the phase function's integral over each bin (within four
    /// standard deviations of the count), and the mean cosine.
    #[test]
    fn phase_sampling_follows_the_phase_function() {
        let g = 0.75;
        let mut rng = item_rng(3, Stream::Path, 0);
        let d = Vec3A::new(0.3, -0.5, 0.8).normalize();
        let n = 400_000;
        let bins = 20;
        let mut hist = vec![0u32; bins];
        let mut mean = 0.0f64;
        for _ in 0..n {
            let (dir, pdf) = sample_cloud_phase(d, g, &mut rng);
            let mu = dir.dot(d).clamp(-1.0, 1.0);
            assert!((pdf / cloud_phase(mu, g) - 1.0).abs() < 1e-3);
            assert!((dir.length() - 1.0).abs() < 1e-4);
            hist[(((mu + 1.0) * 0.5 * bins as f32) as usize).min(bins - 1)] += 1;
            mean += mu as f64;
        }
        for (k, &c) in hist.iter().enumerate() {
            let (lo, hi) = (
                -1.0 + 2.0 * k as f64 / bins as f64,
                -1.0 + 2.0 * (k + 1) as f64 / bins as f64,
            );
            let m = 200;
            let expected: f64 = (0..m)
                .map(|i| {
                    let mu = lo + (hi - lo) * (i as f64 + 0.5) / m as f64;
                    cloud_phase(mu as f32, g) as f64 * 2.0 * std::f64::consts::PI * (hi - lo)
                        / m as f64
                })
                .sum();
            let got = c as f64 / n as f64;
            // Four standard deviations of a bin's count.
            let sd = (expected / n as f64).sqrt();
            assert!(
                (got - expected).abs() < 4.0 * sd,
                "bin {k}: {got} against {expected}"
            );
        }
        let g_mean = (1.0 - BACK_LOBE_WEIGHT) * g + BACK_LOBE_WEIGHT * BACK_LOBE_RATIO * g;
        assert!(
            (mean / n as f64 - g_mean as f64).abs() < 0.005,
            "mean cosine {}",
            mean / n as f64
        );
    }

    #[test]
    fn basis_is_orthonormal() {
        for n in [
            Vec3A::X,
            Vec3A::NEG_Z,
            Vec3A::new(0.2, -0.9, 0.1).normalize(),
        ] {
            let (t, b) = basis(n);
            assert!(t.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5 && t.dot(b).abs() < 1e-5);
            assert!((t.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
        }
    }
}
