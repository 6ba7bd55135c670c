//! Phase functions, the sky dome and the per-frame shading constants.
//!
//! In: [`RenderSettings`]. Out: [`Shading`], which the integrator evaluates per ray (phase
//! weights, which depend only on the ray direction) and per sample (sun and sky in-scattering
//! from the optical depths toward the sun and straight up).
//!
//! - Henyey & Greenstein (1941), "Diffuse radiation in the galaxy", ApJ 93: the phase function.
//! - Wrenninge, Kulla & Lundqvist (2013), "Oz: the great and volumetric", SIGGRAPH Talks: the
//!   multiple-scattering approximation, a sum of octaves with extinction, contribution and
//!   anisotropy scaled by `a^i, b^i, c^i` (here a = b = c = ½).

use std::f32::consts::PI;

use glam::{Vec3, Vec3A};

use super::settings::{RenderSettings, Sky};

/// Henyey–Greenstein phase function `(1 − g²) / (4π (1 + g² − 2gμ)^{3/2})` for the cosine `μ`
/// between the light's travel direction and the scattered direction. Integrates to 1 over the
/// sphere for any `g ∈ (−1, 1)`.
#[inline]
pub fn henyey_greenstein(mu: f32, g: f32) -> f32 {
    let g2 = g * g;
    let d = (1.0 + g2 - 2.0 * g * mu).max(1e-6);
    (1.0 - g2) / (4.0 * PI * d * d.sqrt())
}

/// Weight of the backward lobe in [`cloud_phase`].
pub const BACK_LOBE_WEIGHT: f32 = 0.2;
/// Asymmetry of the backward lobe relative to the scene's `g`.
pub const BACK_LOBE_RATIO: f32 = -0.4;

/// The cloud's two-lobe phase function: `(1 − w)·HG(μ, g) + w·HG(μ, −0.4 g)` with
/// `w =` [`BACK_LOBE_WEIGHT`]; the back lobe brightens the side facing the sun, as Mie
/// scattering by droplets does. Integrates to 1.
#[inline]
pub fn cloud_phase(mu: f32, g: f32) -> f32 {
    (1.0 - BACK_LOBE_WEIGHT) * henyey_greenstein(mu, g)
        + BACK_LOBE_WEIGHT * henyey_greenstein(mu, BACK_LOBE_RATIO * g)
}

/// Fraction of the horizon colour seen below the horizon (a dim ground).
const GROUND: f32 = 0.35;

impl Sky {
    /// Sky radiance seen in direction `dir` (unit; linear RGB): horizon → zenith above the
    /// horizon (square-root ramp in `dir.y`), horizon → dim ground below.
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        match *self {
            Sky::Gradient { zenith, horizon } => {
                if dir.y >= 0.0 {
                    horizon.lerp(zenith, dir.y.min(1.0).sqrt())
                } else {
                    horizon.lerp(horizon * GROUND, (-dir.y).min(1.0).sqrt())
                }
            }
        }
    }

    /// Mean radiance of the upper hemisphere (cosine-free average), the ambient light from
    /// above.
    pub fn upper_mean(&self) -> Vec3 {
        match *self {
            // ∫ √y dy over [0, 1] = 2/3 (uniform solid angle in the upper hemisphere is uniform y).
            Sky::Gradient { zenith, horizon } => horizon.lerp(zenith, 2.0 / 3.0),
        }
    }

    /// Mean radiance of the lower hemisphere (the ground).
    pub fn lower_mean(&self) -> Vec3 {
        match *self {
            Sky::Gradient { horizon, .. } => horizon.lerp(horizon * GROUND, 2.0 / 3.0),
        }
    }
}

/// Ambient light reaching depth `τ_up` is attenuated by `exp(−AMBIENT_EXTINCTION·τ_up)`: diffuse
/// sky light penetrates further than a collimated beam would.
pub const AMBIENT_EXTINCTION: f32 = 0.35;

/// Per-frame shading constants.
#[derive(Clone, Debug)]
pub struct Shading {
    /// Unit direction the sunlight travels.
    pub sun_dir: Vec3A,
    /// Sun colour × intensity.
    pub sun_radiance: Vec3A,
    /// Single-scattering albedo.
    pub albedo: f32,
    /// Phase asymmetry.
    pub g: f32,
    /// Scattering octaves (1 = single scattering only), at most [`MAX_OCTAVES`].
    pub octaves: u32,
    /// Sky light from above (before occlusion).
    pub sky_up: Vec3A,
    /// Ground light from below (unoccluded, weak).
    pub sky_down: Vec3A,
}

/// Upper bound on the multiple-scattering octaves.
pub const MAX_OCTAVES: u32 = 6;

impl Shading {
    /// Constants for `settings` (a zero sun direction falls back to straight down).
    pub fn new(settings: &RenderSettings) -> Shading {
        let sun_dir = Vec3A::from(settings.sun.direction)
            .try_normalize()
            .unwrap_or(Vec3A::NEG_Y);
        Shading {
            sun_dir,
            sun_radiance: Vec3A::from(settings.sun.color * settings.sun.intensity),
            albedo: settings.cloud.albedo.clamp(0.0, 1.0),
            g: settings.cloud.phase_g.clamp(-0.99, 0.99),
            octaves: settings.quality.ms_octaves.clamp(1, MAX_OCTAVES),
            sky_up: Vec3A::from(settings.sky.upper_mean()),
            sky_down: Vec3A::from(settings.sky.lower_mean()),
        }
    }

    /// Phase weights `b^i · p(μ, c^i g)` of each octave for a ray with unit direction `dir`.
    #[inline]
    pub fn phase_weights(&self, dir: Vec3A) -> [f32; MAX_OCTAVES as usize] {
        // Scattered toward the eye: the outgoing direction is −dir.
        let mu = -self.sun_dir.dot(dir);
        let mut w = [0.0; MAX_OCTAVES as usize];
        let (mut b, mut g) = (1.0, self.g);
        for wi in w.iter_mut().take(self.octaves as usize) {
            *wi = b * cloud_phase(mu, g);
            b *= 0.5;
            g *= 0.5;
        }
        w
    }

    /// In-scattered radiance per unit scattering coefficient at a point with optical depth
    /// `tau_sun` toward the sun and `tau_up` straight up, for a ray with phase weights `w`.
    #[inline]
    pub fn in_scattered(
        &self,
        w: &[f32; MAX_OCTAVES as usize],
        tau_sun: f32,
        tau_up: f32,
    ) -> Vec3A {
        // Octave i sees extinction scaled by 2^−i: T_i = exp(−τ/2^i). Start from the last octave
        // and square upward (one exp for all octaves).
        let n = self.octaves as usize;
        let mut t = (-tau_sun / (1u32 << (n - 1)) as f32).exp();
        let mut sun = 0.0;
        for i in (0..n).rev() {
            sun += w[i] * t;
            t *= t;
        }
        // Isotropic ambient: sky from above occluded by the cloud above, ground from below.
        let amb = self.sky_up * (-AMBIENT_EXTINCTION * tau_up).exp() + self.sky_down * 0.5;
        self.sun_radiance * sun + amb * 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ p dω over the sphere by the midpoint rule in μ (the azimuth integral is 2π).
    fn integrate(p: impl Fn(f32) -> f32) -> f64 {
        let n = 200_000;
        (0..n)
            .map(|i| {
                let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                p(mu as f32) as f64 * 2.0 / n as f64
            })
            .sum::<f64>()
            * 2.0
            * std::f64::consts::PI
    }

    #[test]
    fn phase_functions_integrate_to_one() {
        for g in [-0.5, 0.0, 0.3, 0.75, 0.9] {
            let hg = integrate(|mu| henyey_greenstein(mu, g));
            assert!((hg - 1.0).abs() < 1e-3, "HG g={g}: {hg}");
            let c = integrate(|mu| cloud_phase(mu, g));
            assert!((c - 1.0).abs() < 1e-3, "cloud g={g}: {c}");
        }
    }

    #[test]
    fn hg_matches_closed_form_values() {
        // g = 0: isotropic 1/4π. Forward peak (1+g)/(4π(1−g)²), backward (1−g)/(4π(1+g)²).
        let inv4pi = 1.0 / (4.0 * PI);
        assert!((henyey_greenstein(0.3, 0.0) - inv4pi).abs() < 1e-7);
        let g = 0.75f32;
        let fwd = (1.0 + g) / (4.0 * PI * (1.0 - g) * (1.0 - g));
        let back = (1.0 - g) / (4.0 * PI * (1.0 + g) * (1.0 + g));
        assert!((henyey_greenstein(1.0, g) / fwd - 1.0).abs() < 1e-5);
        assert!((henyey_greenstein(-1.0, g) / back - 1.0).abs() < 1e-5);
        // Mean cosine equals g.
        let n = 100_000;
        let mean: f64 = (0..n)
            .map(|i| {
                let mu = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                mu * henyey_greenstein(mu as f32, g) as f64 * 2.0 / n as f64
            })
            .sum::<f64>()
            * 2.0
            * std::f64::consts::PI;
        assert!((mean - g as f64).abs() < 1e-3, "mean cosine {mean}");
    }
}
