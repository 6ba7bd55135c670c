//! The sky dome: the radiance arriving from each direction of the sky and the ground, and the
//! sun's colour after the clear atmosphere.
//!
//! In: [`Sky`] and [`Sun`] settings. Out: [`SkyDome`] (radiance per direction, hemisphere
//! means, the sun's tint), which the sky cells ([`crate::render::light::sky_cells`]), the shader's
//! multiple-scattering octaves ([`crate::render::light::shading`]) and the background of the output use.

use std::f32::consts::PI;
use std::sync::Arc;

use glam::Vec3;

use crate::render::light::envmap::{EnvIntegrals, EnvMap, to_map};
use crate::render::settings::{Sky, Sun};

/// Fraction of the horizon colour seen below the horizon (a dim ground; gradient sky).
const GROUND: f32 = 0.35;

/// Height of the haze band below the horizon (Hosek–Wilkie ground): the ground's own shade is
/// `1 − e^(−|y|/HAZE)` of what is seen in direction `(x, y, z)`, the horizon's colour the rest,
/// so the ground fades into haze toward the horizon (aerial perspective, a thin atmosphere
/// layer seen at a grazing angle).
const HAZE: f32 = 0.08;

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
        /// Radiance scale (the sun's intensity × `HW_SCALE`).
        scale: f32,
        /// Radiance of the ground: a Lambertian plane of the ground albedo lit by the sun and
        /// the sky, `ρ/π·(E_sun + E_sky)`.
        ground: Vec3,
    },
    /// [`Sky::Uniform`].
    Uniform {
        /// The radiance from every direction.
        color: Vec3,
    },
    /// [`Sky::Environment`]: the map, turned and scaled.
    Environment {
        /// The map (`None`: not read, a black sky).
        map: Option<Arc<EnvMap>>,
        /// What lights the cloud through the sky cells: the map, or the map without the sun
        /// split off it (`sun_from_map`).
        light: Option<Arc<EnvMap>>,
        /// Degrees it is turned about +Y (right-handed).
        rotate_deg: f32,
        /// Scale of its radiance.
        intensity: f32,
    },
}

impl SkyDome {
    /// The dome of `sky` under `sun`. A Hosek–Wilkie sky with the sun below the horizon uses
    /// the model at elevation 0 (the model's range); inputs are validated by the scene file.
    pub fn new(sky: &Sky, sun: &Sun) -> SkyDome {
        match sky {
            &Sky::Uniform { color } => SkyDome::Uniform { color },
            Sky::Environment(env) => SkyDome::Environment {
                map: env.map.clone(),
                light: match &env.split {
                    Some((rest, _)) => Some(Arc::clone(rest)),
                    None => env.map.clone(),
                },
                rotate_deg: env.rotate_deg,
                intensity: env.intensity,
            },
            &Sky::Gradient { zenith, horizon } => SkyDome::Gradient { zenith, horizon },
            &Sky::HosekWilkie {
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
                let mut dome = SkyDome::HosekWilkie {
                    state: Box::new(state),
                    to_sun: Vec3::new(to_sun.x, to_sun.y.max(0.0), to_sun.z).normalize(),
                    scale: sun.intensity.max(0.0) * HW_SCALE,
                    ground: Vec3::ZERO,
                };
                // The ground: irradiance from the sun (its intensity is the irradiance normal
                // to it, tinted by the air mass) and from the sky above (∫ L cos θ dω).
                let e_sun = SkyDome::sun_tint(sky, sun)
                    * sun.color
                    * (sun.intensity.max(0.0) * to_sun.y.max(0.0));
                let e_sky = dome.irradiance_from_above();
                let shade = (e_sun + e_sky) * (ground_albedo.clamp(0.0, 1.0) / PI);
                if let SkyDome::HosekWilkie { ground, .. } = &mut dome {
                    *ground = shade;
                }
                dome
            }
        }
    }

    /// Sky radiance seen in direction `dir` (unit; linear RGB). Gradient: horizon → zenith
    /// above the horizon (square-root ramp in `dir.y`), horizon → dim ground below.
    /// Hosek–Wilkie: the model above the horizon; below, the ground lit by the sun and the sky
    /// (albedo `ground_albedo`), fading into the horizon's haze within `HAZE` of it.
    ///
    /// Uniform: its colour. Environment: the map's texels interpolated bilinearly, in
    /// Mitsuba's `envmap` convention (`light/envmap.rs`), times the intensity.
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        match self {
            SkyDome::Uniform { color } => *color,
            SkyDome::Environment {
                map,
                rotate_deg,
                intensity,
                ..
            } => map.as_ref().map_or(Vec3::ZERO, |m| {
                m.lookup(to_map(dir, *rotate_deg)) * *intensity
            }),
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
                    c.lerp(*ground, 1.0 - (dir.y / HAZE).exp())
                }
            }
        }
    }

    /// Radiance lighting the cloud from direction `dir`: [`SkyDome::radiance`], except that an
    /// environment map whose sun was split off (`sun_from_map`) lights without it (the sun is
    /// a light of its own then).
    pub(crate) fn light_radiance(&self, dir: Vec3) -> Vec3 {
        match self {
            SkyDome::Environment {
                light,
                rotate_deg,
                intensity,
                ..
            } => light.as_ref().map_or(Vec3::ZERO, |m| {
                m.lookup(to_map(dir, *rotate_deg)) * *intensity
            }),
            _ => self.radiance(dir),
        }
    }

    /// Mean radiance of the upper hemisphere (cosine-free average), the ambient light from
    /// above.
    pub(crate) fn upper_mean(&self) -> Vec3 {
        match self {
            // ∫ √y dy over [0, 1] = 2/3 (uniform solid angle in the upper hemisphere is uniform y).
            SkyDome::Gradient { zenith, horizon } => horizon.lerp(*zenith, 2.0 / 3.0),
            SkyDome::HosekWilkie { .. } => self.hemisphere_mean(1.0),
            SkyDome::Uniform { color } => *color,
            SkyDome::Environment { .. } => self
                .environment()
                .map_or(Vec3::ZERO, |(i, k)| i.upper_mean * k),
        }
    }

    /// Mean radiance of the lower hemisphere (the ground).
    pub(crate) fn lower_mean(&self) -> Vec3 {
        match self {
            SkyDome::Gradient { horizon, .. } => horizon.lerp(*horizon * GROUND, 2.0 / 3.0),
            SkyDome::HosekWilkie { .. } => self.hemisphere_mean(-1.0),
            SkyDome::Uniform { color } => *color,
            SkyDome::Environment { .. } => self
                .environment()
                .map_or(Vec3::ZERO, |(i, k)| i.lower_mean * k),
        }
    }

    /// An environment map's integrals for its rotation (at intensity 1) and its intensity;
    /// `None` for the analytic skies (and a map not read).
    pub(crate) fn environment(&self) -> Option<(Arc<EnvIntegrals>, f32)> {
        match self {
            SkyDome::Environment {
                light: Some(light),
                rotate_deg,
                intensity,
                ..
            } => Some((light.integrals(*rotate_deg), *intensity)),
            _ => None,
        }
    }

    /// Irradiance on a horizontal plane from the sky above, `∫ L cos θ dω`
    /// (`2π × ` the mean of `L·y` over uniform solid angle).
    fn irradiance_from_above(&self) -> Vec3 {
        self.hemisphere_average(1.0, |y| y) * (2.0 * PI)
    }

    /// Mean radiance over the hemisphere `sign·y > 0` (uniform solid angle).
    fn hemisphere_mean(&self, sign: f32) -> Vec3 {
        self.hemisphere_average(sign, |_| 1.0)
    }

    /// Mean of `radiance · weight(|y|)` over the hemisphere `sign·y > 0`, uniform in `y` and
    /// azimuth (uniform solid angle), by the midpoint rule on a 16 × 32 grid.
    fn hemisphere_average(&self, sign: f32, weight: impl Fn(f32) -> f32) -> Vec3 {
        let (ny, nphi) = (16, 32);
        let mut sum = Vec3::ZERO;
        for i in 0..ny {
            let y = (i as f32 + 0.5) / ny as f32;
            let r = (1.0 - y * y).sqrt();
            for j in 0..nphi {
                let phi = 2.0 * PI * (j as f32 + 0.5) / nphi as f32;
                sum += self.radiance(Vec3::new(r * phi.cos(), sign * y, r * phi.sin())) * weight(y);
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
