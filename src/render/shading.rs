//! Phase functions, the sky dome and the per-frame shading constants.
//!
//! In: [`RenderSettings`]. Out: [`Shading`], which the integrator evaluates per ray (phase
//! weights, which depend only on the ray direction) and per sample (sun and sky in-scattering
//! from the optical depths toward the sun and the sky cells of [`super::sky_light`]).
//!
//! - Henyey & Greenstein (1941), "Diffuse radiation in the galaxy", ApJ 93: the phase function.
//! - Wrenninge, Kulla & Lundqvist (2013), "Oz: the great and volumetric", SIGGRAPH Talks: the
//!   multiple-scattering approximation, a sum of octaves with extinction, contribution and
//!   anisotropy scaled by `a^i, b^i, c^i` (here a = b = c = ½).

use std::f32::consts::PI;

use glam::{Vec3, Vec3A};

use super::medium::LightDepths;
use super::settings::{RenderSettings, Sky, Sun};
use super::sky_light::{DOWN, SKY_DIRECTIONS, SkyLight, UP};

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

/// Hosek–Wilkie radiance units per unit of sun intensity: with it a clear sky (turbidity 3,
/// sun 45° high) has a zenith luminance of 1/60 of the sun's intensity, as the default
/// gradient sky has (0.2 against 12).
const HW_SCALE: f32 = 1.0 / 60.0 / HW_ZENITH_LUMINANCE_45;

/// Zenith luminance of the `hw-skymodel` sky for turbidity 3, ground albedo 0.3, sun 45° high.
const HW_ZENITH_LUMINANCE_45: f32 = 4.357;

/// Optical depth of the clear atmosphere at the zenith for R, G, B (Rayleigh at 680, 550,
/// 440 nm, plus aerosol growing with turbidity, per unit turbidity above 1).
const RAYLEIGH_DEPTH: [f32; 3] = [0.041, 0.097, 0.236];
const AEROSOL_DEPTH: [f32; 3] = [0.030, 0.036, 0.043];

/// The sky as the renderer sees it: radiance per direction and hemisphere means.
#[derive(Clone, Debug)]
pub enum SkyDome {
    /// [`Sky::Gradient`].
    Gradient {
        /// Colour straight up.
        zenith: Vec3,
        /// Colour at the horizon.
        horizon: Vec3,
    },
    /// [`Sky::HosekWilkie`] for one sun position.
    HosekWilkie {
        /// The model's state for the sun's elevation.
        state: Box<hw_skymodel::rgb::SkyState>,
        /// Unit vector toward the sun (above the horizon).
        to_sun: Vec3,
        /// Radiance scale (the sun's intensity × [`HW_SCALE`]).
        scale: f32,
        /// Ground albedo.
        ground: f32,
    },
}

impl SkyDome {
    /// The dome of `sky` under `sun`. A Hosek–Wilkie sky with the sun below the horizon uses
    /// the model at elevation 0 (the model's range); inputs are validated by the scene file.
    pub fn new(sky: &Sky, sun: &Sun) -> SkyDome {
        match *sky {
            Sky::Gradient { zenith, horizon } => SkyDome::Gradient { zenith, horizon },
            Sky::HosekWilkie {
                turbidity,
                ground_albedo,
            } => {
                let to_sun = -sun.travel_dir();
                let elevation = to_sun.y.clamp(0.0, 1.0).asin();
                let params = hw_skymodel::rgb::SkyParams {
                    elevation,
                    turbidity: turbidity.clamp(1.0, 10.0),
                    albedo: [ground_albedo.clamp(0.0, 1.0); 3],
                };
                let state = hw_skymodel::rgb::SkyState::new(&params)
                    .expect("parameters clamped to the model's range");
                SkyDome::HosekWilkie {
                    state: Box::new(state),
                    to_sun: Vec3::new(to_sun.x, to_sun.y.max(0.0), to_sun.z).normalize(),
                    scale: sun.intensity.max(0.0) * HW_SCALE,
                    ground: ground_albedo.clamp(0.0, 1.0),
                }
            }
        }
    }

    /// Sky radiance seen in direction `dir` (unit; linear RGB). Gradient: horizon → zenith
    /// above the horizon (square-root ramp in `dir.y`), horizon → dim ground below.
    /// Hosek–Wilkie: the model above the horizon; below, the horizon's radiance times the
    /// ground albedo and the ground factor (a dim ground, as for the gradient).
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        match self {
            SkyDome::Gradient { zenith, horizon } => {
                if dir.y >= 0.0 {
                    horizon.lerp(*zenith, dir.y.min(1.0).sqrt())
                } else {
                    horizon.lerp(*horizon * GROUND, (-dir.y).min(1.0).sqrt())
                }
            }
            SkyDome::HosekWilkie {
                state,
                to_sun,
                scale,
                ground,
            } => {
                let up = Vec3::new(dir.x, dir.y.max(0.0), dir.z)
                    .try_normalize()
                    .unwrap_or(Vec3::Y);
                let theta = up.y.clamp(-1.0, 1.0).acos().min(0.5 * PI - 1e-3);
                let gamma = up.dot(*to_sun).clamp(-1.0, 1.0).acos();
                use hw_skymodel::rgb::Channel;
                let c = Vec3::new(
                    state.radiance(theta, gamma, Channel::R),
                    state.radiance(theta, gamma, Channel::G),
                    state.radiance(theta, gamma, Channel::B),
                ) * *scale;
                if dir.y >= 0.0 {
                    c
                } else {
                    c * (*ground * GROUND)
                }
            }
        }
    }

    /// Mean radiance of the upper hemisphere (cosine-free average), the ambient light from
    /// above.
    pub fn upper_mean(&self) -> Vec3 {
        match self {
            // ∫ √y dy over [0, 1] = 2/3 (uniform solid angle in the upper hemisphere is uniform y).
            SkyDome::Gradient { zenith, horizon } => horizon.lerp(*zenith, 2.0 / 3.0),
            SkyDome::HosekWilkie { .. } => self.hemisphere_mean(1.0),
        }
    }

    /// Mean radiance of the lower hemisphere (the ground).
    pub fn lower_mean(&self) -> Vec3 {
        match self {
            SkyDome::Gradient { horizon, .. } => horizon.lerp(*horizon * GROUND, 2.0 / 3.0),
            SkyDome::HosekWilkie { .. } => self.hemisphere_mean(-1.0),
        }
    }

    /// Mean radiance over the hemisphere `sign·y > 0` (uniform in `y` and azimuth: uniform
    /// solid angle), by the midpoint rule on a 16 × 32 grid.
    fn hemisphere_mean(&self, sign: f32) -> Vec3 {
        let (ny, nphi) = (16, 32);
        let mut sum = Vec3::ZERO;
        for i in 0..ny {
            let y = (i as f32 + 0.5) / ny as f32;
            let r = (1.0 - y * y).sqrt();
            for j in 0..nphi {
                let phi = 2.0 * PI * (j as f32 + 0.5) / nphi as f32;
                sum += self.radiance(Vec3::new(r * phi.cos(), sign * y, r * phi.sin()));
            }
        }
        sum / (ny * nphi) as f32
    }

    /// Colour of the sunlight reaching the cloud relative to the sun's colour at the zenith:
    /// 1 for the gradient sky; for Hosek–Wilkie, the clear atmosphere's transmittance along the
    /// air mass at the sun's elevation (Kasten–Young) over that at the zenith — golden at a
    /// low sun.
    pub fn sun_tint(sky: &Sky, sun: &Sun) -> Vec3 {
        let Sky::HosekWilkie { turbidity, .. } = *sky else {
            return Vec3::ONE;
        };
        let el = sun.elevation().max(0.0);
        let air_mass = 1.0 / (el.to_radians().sin() + 0.50572 * (el + 6.07995).powf(-1.6364));
        let aerosol = (turbidity.clamp(1.0, 10.0) - 1.0).max(0.0);
        let depth = |c: usize| RAYLEIGH_DEPTH[c] + aerosol * AEROSOL_DEPTH[c];
        Vec3::new(
            (-depth(0) * (air_mass - 1.0)).exp(),
            (-depth(1) * (air_mass - 1.0)).exp(),
            (-depth(2) * (air_mass - 1.0)).exp(),
        )
    }
}

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
    /// Sky light from above (before occlusion), for the multiple-scattering octaves.
    pub sky_up: Vec3A,
    /// Ground light from below (before occlusion), for the multiple-scattering octaves.
    pub sky_down: Vec3A,
    /// The sky's single scattering, per cell.
    pub sky: SkyLight,
    /// `b^(octaves−1)`: the last octave's contribution weight.
    ms_weight_last: f32,
}

/// Upper bound on the multiple-scattering octaves.
pub const MAX_OCTAVES: u32 = 6;

/// What a ray's direction fixes for all its samples: the phase weights toward the eye.
#[derive(Clone, Debug)]
pub struct RayWeights {
    /// `b^i · p(μ, c^i g)` of each octave for the sun.
    pub sun: [f32; MAX_OCTAVES as usize],
    /// RGB weight of each sky cell's transmittance (single scattering).
    pub sky: [Vec3A; SKY_DIRECTIONS],
}

impl Shading {
    /// Constants for `settings` (a zero sun direction falls back to straight down; without
    /// `cloud.multiple_scattering` one octave: single scattering).
    pub fn new(settings: &RenderSettings) -> Shading {
        let sun = &settings.sun;
        let dome = SkyDome::new(&settings.sky, sun);
        let tint = SkyDome::sun_tint(&settings.sky, sun);
        let octaves = if settings.cloud.multiple_scattering {
            settings.quality.ms_octaves.clamp(1, MAX_OCTAVES)
        } else {
            1
        };
        let g = settings.cloud.phase_g.clamp(-0.99, 0.99);
        Shading {
            sun_dir: Vec3A::from(sun.travel_dir()),
            sun_radiance: Vec3A::from(sun.color * sun.intensity * tint),
            albedo: settings.cloud.albedo.clamp(0.0, 1.0),
            g,
            octaves,
            sky_up: Vec3A::from(dome.upper_mean()),
            sky_down: Vec3A::from(dome.lower_mean()),
            sky: SkyLight::new(&dome, g),
            ms_weight_last: (1..octaves).fold(1.0, |b, _| b * MS_CONTRIBUTION),
        }
    }

    /// Phase weights for a ray with unit direction `dir`.
    #[inline]
    pub fn ray_weights(&self, dir: Vec3A) -> RayWeights {
        // Scattered toward the eye: the outgoing direction is −dir.
        let mu = -self.sun_dir.dot(dir);
        let mut sun = [0.0; MAX_OCTAVES as usize];
        let (mut b, mut g) = (1.0, self.g);
        for wi in sun.iter_mut().take(self.octaves as usize) {
            *wi = b * cloud_phase(mu, g);
            b *= MS_CONTRIBUTION;
            g *= MS_ANISOTROPY;
        }
        RayWeights {
            sun,
            sky: self.sky.ray_weights(dir),
        }
    }

    /// Radiance a whole ray scatters straight on from the sky behind it (the delta part of
    /// the phase function, [`SkyLight`]): `albedo · delta · L_sky(dir) · τ · e^{−τ}` for the
    /// ray's optical depth `tau` through the cloud.
    #[inline]
    pub fn forward_sky(&self, dir: Vec3A, tau: f32) -> Vec3A {
        let k = self.albedo * self.sky.delta() * tau * (-tau).exp();
        if k <= 0.0 {
            return Vec3A::ZERO;
        }
        self.sky.forward_radiance(dir) * k
    }

    /// In-scattered radiance per unit scattering coefficient at a point with optical depths
    /// `tau`, for a ray with weights `w`.
    ///
    /// Single scattering: the sun through its phase weight and each sky cell through its
    /// weight and depth. Octave `i ≥ 1` of the multiple-scattering approximation sees the
    /// extinction scaled by `a^i` (`a = ½`) and contributes with `b^i` ([`MS_CONTRIBUTION`]):
    /// the sun through its phase weight, the sky isotropically — half the sphere's light from
    /// the sky above through the upward depth, half from the ground below through the downward.
    #[inline]
    pub fn in_scattered(&self, w: &RayWeights, tau: &LightDepths) -> Vec3A {
        let mut sky = Vec3A::ZERO;
        for (wk, &t) in w.sky.iter().zip(&tau.sky) {
            sky += *wk * (-t).exp();
        }
        let n = self.octaves as usize;
        if n == 1 {
            return self.sun_radiance * (w.sun[0] * tau.sun_transmittance) + sky;
        }
        // exp(−τ·2^−i) for i = n−1 first, then squared down to i = 0: one exp per depth.
        let first = 1.0 / (1u32 << (n - 1)) as f32;
        let (mut ts, mut tu, mut td) = (
            (-tau.sun * first).exp(),
            (-tau.sky[UP] * first).exp(),
            (-tau.sky[DOWN] * first).exp(),
        );
        let (mut sun, mut up, mut down) = (0.0, 0.0, 0.0);
        let mut b = self.ms_weight_last;
        for i in (0..n).rev() {
            // Single scattering from the transmittance itself (exact where it is known).
            sun += w.sun[i] * if i == 0 { tau.sun_transmittance } else { ts };
            if i > 0 {
                up += b * tu;
                down += b * td;
            }
            b /= MS_CONTRIBUTION;
            ts *= ts;
            tu *= tu;
            td *= td;
        }
        self.sun_radiance * sun
            + sky
            + (self.sky_up * up + self.sky_down * down) * (0.5 * SKY_PHASE)
    }
}

/// Share of the isotropic sky estimate that the multiple-scattering octaves turn toward the
/// eye. Calibrated against Mitsuba's full transport of the same sky (README).
pub const SKY_PHASE: f32 = 0.64;

/// Contribution factor `b` of each further multiple-scattering octave (Wrenninge et al.);
/// fitted with [`MS_ANISOTROPY`] against Mitsuba's full transport of a side-lit and a backlit
/// shot together (README, `tests/mitsuba.rs`).
pub const MS_CONTRIBUTION: f32 = 0.85;
/// Anisotropy factor `c` of each further octave. Multiply scattered light in a forward-peaked
/// cloud stays forward-peaked: with `c = ½` a backlit cloud came out 21 % too dark.
pub const MS_ANISOTROPY: f32 = 0.7;

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
