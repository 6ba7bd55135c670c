//! The shader: how much sunlight and skylight a cloud sample scatters toward the eye, given
//! the optical depths toward the lights at that sample (from the light grid,
//! [`crate::render::light::grid`], or any other [`crate::render::light::ShadowDepths`]).
//!
//! In: [`RenderSettings`]. Out: [`Shading`], which the integrator evaluates per ray (phase
//! weights, which depend only on the ray direction) and per sample ([`InScattered`]: the sun's
//! single scattering, the sky cells' single scattering of [`crate::render::light::sky_cells`] and the
//! multiple-scattering octaves, kept apart so that render passes can write them separately).
//!
//! Multiple scattering comes one of two ways. The physically based estimate (`Final`,
//! `Production`): the fluence grid's light scattered at least once
//! ([`crate::render::light::fluence`]) scattered once more toward the eye
//! ([`Shading::fluence_in`]). The octaves (`Preview`):
//!
//! - Wrenninge, Kulla & Lundqvist (2013), "Oz: the great and volumetric", SIGGRAPH Talks: the
//!   multiple-scattering approximation, a sum of octaves with extinction, contribution and
//!   anisotropy scaled by `a^i, b^i, c^i` (here a = ½, b = [`MS_CONTRIBUTION`], c =
//!   [`MS_ANISOTROPY`]).

use glam::Vec3A;

use crate::render::fast_exp::{exp_neg, exp_neg_all};
use crate::render::light::fluence::{luminance, sun_detail};
use crate::render::light::phase::{
    BACK_LOBE_RATIO, BACK_LOBE_WEIGHT, cloud_phase, cloud_phase_within, henyey_greenstein,
};
use crate::render::light::sky_cells::{DOWN, SKY_DIRECTIONS, SkyLight, UP};
use crate::render::light::sky_dome::SkyDome;
use crate::render::light::{LightDepths, MultipleLight};
use crate::render::settings::RenderSettings;

/// Radiance in-scattered toward the eye per unit scattering coefficient at one sample, by
/// component: [`InScattered::sun`] + [`InScattered::sky`] + [`InScattered::multiple`] =
/// [`InScattered::total`] (up to rounding: `total` keeps the summation order the renderer has
/// always used, so frames do not change bits).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct InScattered {
    /// The sun's colour × intensity, common to both sun terms.
    sun_radiance: Vec3A,
    /// Single scattering of sunlight (a scalar weight of `sun_radiance`).
    sun_single: f32,
    /// The multiple-scattering octaves of sunlight (a scalar weight of `sun_radiance`).
    sun_multiple: f32,
    /// Single scattering of the sky cells (RGB).
    sky: Vec3A,
    /// The multiple-scattering octaves of sky and ground light, or the fluence grid's
    /// multiple scattering of sun and sky together (RGB).
    sky_multiple: Vec3A,
}

impl InScattered {
    /// Sunlight scattered once.
    #[inline]
    pub(crate) fn sun(&self) -> Vec3A {
        self.sun_radiance * self.sun_single
    }

    /// Sky light scattered once (through the sky cells).
    #[inline]
    pub(crate) fn sky(&self) -> Vec3A {
        self.sky
    }

    /// The multiple-scattering approximation: the sun's and the sky's octaves beyond the first.
    #[inline]
    pub(crate) fn multiple(&self) -> Vec3A {
        self.sun_radiance * self.sun_multiple + self.sky_multiple
    }

    /// The same single scattering with `multiple` (RGB: the fluence grid's estimate) as the
    /// multiple scattering.
    #[inline]
    pub(crate) fn with_multiple(self, multiple: Vec3A) -> InScattered {
        InScattered {
            sun_multiple: 0.0,
            sky_multiple: multiple,
            ..self
        }
    }

    /// All of it.
    #[inline]
    pub(crate) fn total(&self) -> Vec3A {
        self.sun_radiance * (self.sun_multiple + self.sun_single) + self.sky + self.sky_multiple
    }
}

/// Per-frame shading constants.
#[derive(Clone, Debug)]
pub(crate) struct Shading {
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
    /// Multiple scattering from the fluence grid ([`Shading::fluence_in`]) instead of the
    /// octaves (which are then 1).
    pub fluence: bool,
    /// The sun's colour at unit luminance (the fluence grid keeps its once-scattered light as
    /// a luminance).
    sun_colour: Vec3A,
    /// The albedo × the sun's luminance: sunlight scattered once along the sun's own line
    /// through a point of sun depth `τ` has the fluence this × `τ e^{−τ}`.
    sun_forward: f32,
    /// The share of the phase function within [`FORWARD_CONE_DEG`] of the forward direction.
    forward_cone: f32,

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
pub(crate) const MAX_OCTAVES: u32 = 6;

/// Half-angle of the cone about the sun's direction in which the once-scattered sunlight's
/// amount is taken from the march's own sun depth rather than the fluence grid
/// ([`Shading::fluence_in`]); with the cloud's phase function (`g` 0.75) the cone holds 34 %
/// of the scattering. Measured against Mitsuba's full transport and the path-traced
/// reference (docs/MEASUREMENTS.md, "The forward cone"): cones of 15°, 18°, 20.5°, 23.5° read
/// the golden hour 9.2, 8.5, 7.9, 7.4 % per pixel, the side-lit shots unchanged. At 20° the
/// backlit rims' second scattering is within 4 % of the reference's; wider cones brighten
/// the rims past it and darken the body seen through them (already 22 % low at 20°).
pub(crate) const FORWARD_CONE_DEG: f32 = 20.0;

/// What a ray's direction fixes for all its samples: the phase weights toward the eye.
#[derive(Clone, Debug)]
pub(crate) struct RayWeights {
    /// `b^i · p(μ, c^i g)` of each octave for the sun.
    pub sun: [f32; MAX_OCTAVES as usize],
    /// RGB weight of each sky cell's transmittance (single scattering).
    pub sky: [Vec3A; SKY_DIRECTIONS],
}

impl Shading {
    /// Constants for `settings` (a zero sun direction falls back to straight down; without
    /// `cloud.multiple_scattering` one octave: single scattering).
    pub(crate) fn new(settings: &RenderSettings) -> Shading {
        let sun = &settings.sun;
        let dome = SkyDome::new(&settings.sky, sun);
        let tint = SkyDome::sun_tint(&settings.sky, sun);
        let fluence = settings.cloud.multiple_scattering && settings.quality.ms_photons > 0;
        let octaves = if settings.cloud.multiple_scattering && !fluence {
            settings.quality.ms_octaves.clamp(1, MAX_OCTAVES)
        } else {
            1
        };
        let g = settings.cloud.phase_g.clamp(-0.99, 0.99);
        let sun_radiance = Vec3A::from(sun.color * sun.intensity * tint);
        let albedo = settings.cloud.albedo.clamp(0.0, 1.0);
        Shading {
            sun_dir: Vec3A::from(sun.travel_dir()),
            sun_radiance,
            albedo,
            g,
            octaves,
            fluence,
            sun_colour: {
                let c = Vec3A::from(sun.color * tint);
                let l = luminance(c);
                if l > 0.0 { c / l } else { Vec3A::ZERO }
            },
            sun_forward: albedo * luminance(sun_radiance),
            forward_cone: cloud_phase_within(FORWARD_CONE_DEG.to_radians().cos(), g),
            sky_up: Vec3A::from(dome.upper_mean()),
            sky_down: Vec3A::from(dome.lower_mean()),
            sky: SkyLight::new(&dome, g),
            ms_weight_last: (1..octaves).fold(1.0, |b, _| b * MS_CONTRIBUTION),
        }
    }

    /// Phase weights for a ray with unit direction `dir`.
    #[inline]
    pub(crate) fn ray_weights(&self, dir: Vec3A) -> RayWeights {
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
    pub(crate) fn forward_sky(&self, dir: Vec3A, tau: f32) -> Vec3A {
        let k = self.albedo * self.sky.delta() * tau * (-tau).exp();
        if k <= 0.0 {
            return Vec3A::ZERO;
        }
        self.sky.forward_radiance(dir) * k
    }

    /// Radiance per unit scattering coefficient that light already scattered at least once
    /// (`m`, from the fluence grid) scatters toward the eye along a ray of unit direction
    /// `dir`: the orders ≥ 2.
    ///
    /// The light's angular spread is closed by a Henyey–Greenstein lobe about its flux: the
    /// radiance `L(ω) = φ · HG(ω·F̂, f)` with `f = |F|/φ` has the fluence and flux found (its
    /// first two moments), and turned by the cloud's phase function it is exactly
    /// `φ · p(μ, f·g)` (two HG lobes convolve to one with the product of their asymmetries),
    /// `μ` the cosine between the flux and the way to the eye: positive everywhere, isotropic
    /// deep inside, forward-peaked where the light still streams (a backlit rim).
    ///
    /// Sunlight scattered once (`m.sun_once`, flux `m.sun_once_flux`) keeps the phase
    /// function's two-lobe shape, which one HG lobe would blur: it is closed by that shape
    /// about its own flux, the first scattering's asymmetries scaled so that the lobe's mean
    /// cosine is `|F₁|/φ₁` (at most the phase function's own). Scattered once more it is
    /// `φ₁ · (p_s ∗ p)(μ₁)`, `μ₁` the cosine between that flux and the way to the eye: where
    /// the sunlight has just scattered (a thin or sunlit part) exactly the phase function
    /// twice about the sun, deeper in (where the once-scattered light arrives from all
    /// sides) broader, as the sum of all orders' lobe is.
    ///
    /// The forward cone: once-scattered sunlight arriving from direction `ω` is `p(ω·ŝ) A(ω)`,
    /// `A(ω)` the sunlight scattered along the line back from the point in that direction.
    /// The closure takes `A` the same all round (`φ₁`); but along the sun's own line it is
    /// exactly `a E τ e^{−τ}` (`τ` the point's sun depth from the light grid, at the march's
    /// resolution, not the fluence grid's), and seen toward the sun the second scattering
    /// comes mostly from there. So within the cone of [`FORWARD_CONE_DEG`] about the sun
    /// `A` is that: the second scattering gains `P_c · (a E τ e^{−τ} − φ₁) · p(μ_s)` (`P_c`
    /// the phase function's share in the cone, `μ_s` the cosine between the sun's direction
    /// and the way to the eye; the sum kept ≥ 0). A backlit rim, which the fluence grid's
    /// cells blur with the empty space beside it, gets its forward light; seen from the side
    /// (`p(μ_s)` small) it changes little. Where the grid has no once-scattered light (or
    /// there is no grid) nothing is added.
    ///
    /// The sun's detail: the sun's share of the orders ≥ 3 (`m.sun_multiple`, in the sun's
    /// colour) is multiplied by [`sun_detail`] at the point's sun depth over its mean over the
    /// grid's cell (`m.sun_detail_mean`): creases that another part of the cloud shades darken,
    /// sunlit bulges brighten, below the grid's resolution.
    ///
    /// `sun_phase` is the ray's phase weight from the sun to the eye, `p(μ_s)`
    /// ([`RayWeights::sun`]`[0]`, the same for all the ray's samples).
    #[inline]
    pub(crate) fn fluence_in(
        &self,
        m: &MultipleLight,
        dir: Vec3A,
        tau_sun: f32,
        sun_phase: f32,
    ) -> Vec3A {
        // The sun's transmittance here, for the forward cone and the sun's detail.
        let t_sun = exp_neg(tau_sun);
        let once = if m.sun_once > 0.0 {
            let forward =
                self.forward_cone * (self.sun_forward * tau_sun * t_sun - m.sun_once) * sun_phase;
            // Its lobe: the phase function's shape about its flux, the first scattering's
            // asymmetry scaled so the lobe's mean cosine is the flux's `|F₁|/φ₁` (the phase
            // function's own mean cosine is `g (1 − w + w r)`).
            let len = m.sun_once_flux.length();
            let (mu, s) = if len > 0.0 && self.g > 0.0 {
                (
                    -dir.dot(m.sun_once_flux) / len,
                    (len / m.sun_once / (PHASE_MEAN_COSINE * self.g)).min(1.0),
                )
            } else {
                // No net flux: isotropic.
                (0.0, 0.0)
            };
            self.sun_colour * (m.sun_once * self.twice_scattered(mu, s) + forward).max(0.0)
        } else {
            // No fluence here (or no grid at all): nothing to correct.
            Vec3A::ZERO
        };
        let phi = luminance(m.fluence);
        if !(phi > 0.0) {
            return once;
        }
        // The sun's sub-cell detail on the sun's share of the fluence (in the sun's colour;
        // the sky's share is left as it is), kept ≥ 0.
        let fluence = if m.sun_detail_mean > 0.0 {
            let change = m.sun_multiple.min(phi) * (sun_detail(t_sun) / m.sun_detail_mean - 1.0);
            (m.fluence + self.sun_colour * change).max(Vec3A::ZERO)
        } else {
            m.fluence
        };
        let f2 = m.flux.length_squared();
        let (mu, f) = if f2 > 0.0 {
            let len = f2.sqrt();
            (-dir.dot(m.flux) / len, (len / phi).min(0.99))
        } else {
            (0.0, 0.0)
        };
        once + fluence * cloud_phase(mu, self.g * f)
    }

    /// Light scattered twice at cosine `mu` to its lobe's axis: the cloud's phase function
    /// convolved with itself, the first scattering's asymmetries scaled by `s` (1: exactly the
    /// phase function twice, about the sun). Per pair of HG lobes one HG lobe of the product
    /// of their asymmetries.
    #[inline]
    fn twice_scattered(&self, mu: f32, s: f32) -> f32 {
        let (w, r) = (BACK_LOBE_WEIGHT, BACK_LOBE_RATIO);
        let g = self.g;
        let g1 = (s * g).min(0.99);
        (1.0 - w) * (1.0 - w) * henyey_greenstein(mu, g1 * g)
            + 2.0 * w * (1.0 - w) * henyey_greenstein(mu, g1 * g * r)
            + w * w * henyey_greenstein(mu, g1 * g * r * r)
    }

    /// In-scattered radiance per unit scattering coefficient at a point with optical depths
    /// `tau`, for a ray with weights `w`, by component.
    ///
    /// Single scattering: the sun through its phase weight and each sky cell through its
    /// weight and depth. Octave `i ≥ 1` of the multiple-scattering approximation sees the
    /// extinction scaled by `a^i` (`a = ½`) and contributes with `b^i` ([`MS_CONTRIBUTION`]):
    /// the sun through its phase weight, the sky isotropically — half the sphere's light from
    /// the sky above through the upward depth, half from the ground below through the downward.
    #[inline]
    pub(crate) fn in_scattered(&self, w: &RayWeights, tau: &LightDepths) -> InScattered {
        let mut sky = Vec3A::ZERO;
        for (wk, t) in w.sky.iter().zip(exp_neg_all(&tau.sky)) {
            sky += *wk * t;
        }
        let n = self.octaves as usize;
        if n == 1 {
            return InScattered {
                sun_radiance: self.sun_radiance,
                sun_single: w.sun[0] * exp_neg(tau.sun),
                sun_multiple: 0.0,
                sky,
                sky_multiple: Vec3A::ZERO,
            };
        }
        // exp(−τ·2^−i) for i = n−1 first, then squared down to i = 0: one exp per depth.
        let first = 1.0 / (1u32 << (n - 1)) as f32;
        let (mut ts, mut tu, mut td) = (
            exp_neg(tau.sun * first),
            exp_neg(tau.sky[UP] * first),
            exp_neg(tau.sky[DOWN] * first),
        );
        let (mut sun, mut up, mut down) = (0.0, 0.0, 0.0);
        let mut b = self.ms_weight_last;
        for i in (1..n).rev() {
            sun += w.sun[i] * ts;
            up += b * tu;
            down += b * td;
            b /= MS_CONTRIBUTION;
            ts *= ts;
            tu *= tu;
            td *= td;
        }
        InScattered {
            sun_radiance: self.sun_radiance,
            // Squared n − 1 times, `ts` is now `e^{−τ}`: single scattering's transmittance.
            sun_single: w.sun[0] * ts,
            sun_multiple: sun,
            sky,
            sky_multiple: (self.sky_up * up + self.sky_down * down) * (0.5 * SKY_PHASE),
        }
    }
}

/// The mean cosine of [`cloud_phase`] per unit asymmetry: `1 − w + w r` (each HG lobe's mean
/// cosine is its asymmetry).
const PHASE_MEAN_COSINE: f32 = 1.0 - BACK_LOBE_WEIGHT + BACK_LOBE_WEIGHT * BACK_LOBE_RATIO;

/// Share of the isotropic sky estimate that the multiple-scattering octaves turn toward the
/// eye. Calibrated against Mitsuba's full transport of the same sky (docs/MEASUREMENTS.md,
/// "Checked against Mitsuba 3").
pub(crate) const SKY_PHASE: f32 = 0.64;

/// Contribution factor `b` of each further multiple-scattering octave (Wrenninge et al.);
/// fitted with [`MS_ANISOTROPY`] against Mitsuba's full transport of a side-lit and a backlit
/// shot together (docs/MEASUREMENTS.md, "Checked against Mitsuba 3"; `tests/it/mitsuba.rs`).
pub(crate) const MS_CONTRIBUTION: f32 = 0.85;
/// Anisotropy factor `c` of each further octave. Multiply scattered light in a forward-peaked
/// cloud stays forward-peaked: with `c = ½` a backlit cloud came out 21 % too dark.
pub(crate) const MS_ANISOTROPY: f32 = 0.7;
