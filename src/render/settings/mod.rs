//! What a frame is rendered with: camera, sun, sky, cloud material, film and quality.
//! The serde types here are read directly from scene files (unknown fields are errors; every
//! field has a default, documented in `scenes/README.md`).

mod checks;

pub use checks::InvalidField;

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;

use crate::render::camera::Camera;
use crate::render::light::envmap::{EnvMap, MapSun, to_world};
use serde::{Deserialize, Serialize};

/// The sun: a directional light, given by a direction or by its position in the sky.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sun {
    /// Direction the light travels (from the sun toward the scene); need not be unit length.
    /// Ignored when `elevation_deg` is given.
    pub direction: Vec3,
    /// Height of the sun above the horizon in degrees (`0..=90`); when given, the sun's
    /// direction comes from it and `azimuth_deg`, and a [`Sky::HosekWilkie`] sky follows it.
    pub elevation_deg: Option<f32>,
    /// Where the sun stands around +Y in degrees, with the camera's convention (0 = toward +Z,
    /// 90 = toward +X); used with `elevation_deg`.
    pub azimuth_deg: f32,
    /// Linear RGB colour (at the zenith: a [`Sky::HosekWilkie`] sky reddens a low sun).
    pub color: Vec3,
    /// Irradiance scale.
    pub intensity: f32,
}

impl Default for Sun {
    fn default() -> Self {
        Sun {
            // From the upper left of the builtin scenes' cameras (azimuth 20–35°), 32° high:
            // side light, so the billows model each other with light and shadow.
            direction: Vec3::new(0.9, -0.6, -0.3),
            elevation_deg: None,
            azimuth_deg: 0.0,
            color: Vec3::new(1.0, 0.95, 0.85),
            intensity: 12.0,
        }
    }
}

impl Sun {
    /// Unit direction the light travels (straight down when the direction is zero).
    pub fn travel_dir(&self) -> Vec3 {
        match self.elevation_deg {
            Some(el) => {
                let (el, az) = (el.to_radians(), self.azimuth_deg.to_radians());
                -Vec3::new(az.sin() * el.cos(), el.sin(), az.cos() * el.cos())
            }
            None => self.direction.try_normalize().unwrap_or(Vec3::NEG_Y),
        }
    }

    /// Elevation of the sun above the horizon in degrees (from the direction when not given).
    pub fn elevation(&self) -> f32 {
        (-self.travel_dir().y).clamp(-1.0, 1.0).asin().to_degrees()
    }
}

/// Sky dome: the background and the ambient light on the cloud.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Sky {
    /// Vertical gradient from the horizon colour to the zenith colour (linear RGB).
    Gradient {
        /// Colour straight up.
        zenith: Vec3,
        /// Colour at the horizon.
        horizon: Vec3,
    },
    /// Hosek–Wilkie physically based clear sky (2012) for the sun's elevation, scaled to the
    /// sun's intensity; the sun is reddened by the air mass it shines through.
    HosekWilkie {
        /// Atmospheric turbidity, `1..=10` (2 = very clear, 3 = clear, 6+ = hazy).
        turbidity: f32,
        /// Ground albedo, `0..=1`.
        ground_albedo: f32,
    },
    /// The same radiance from every direction, ground included (an overcast sky's ambient
    /// light; what a constant [`Sky::Environment`] map equals).
    Uniform {
        /// Linear RGB radiance.
        color: Vec3,
    },
    /// The plate's light: a lat-long (equirectangular) EXR, in Mitsuba's `envmap` convention
    /// (`crate::render::light::envmap`), lights the cloud through the sky cells and is the
    /// background. The scene's `sun` stays a light of its own.
    Environment(Environment),
}

/// A lat-long EXR as the sky (`sky: Environment((file: "plate.exr"))`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Environment {
    /// The EXR (relative paths resolve against the scene file's folder; the loaded scene holds
    /// it resolved).
    pub file: String,
    /// Degrees the map is turned about +Y, right-handed (counter-clockwise seen from above):
    /// at 90 what the file shows toward +Z is seen toward +X.
    pub rotate_deg: f32,
    /// Scale of the map's radiance.
    pub intensity: f32,
    /// Split the map's brightest region off as the sun ([`EnvMap::split_sun`]): it replaces
    /// the scene's `sun` (direction and irradiance from the map; none when no region stands
    /// out), and the sky cells light with the rest. The background still shows the whole map.
    pub sun_from_map: bool,
    /// The map, read when the scene is loaded (not written in scene files; `None` renders a
    /// black sky).
    #[serde(skip)]
    pub map: Option<Arc<EnvMap>>,
    /// With `sun_from_map`: the map without its sun (what the sky cells light with) and the
    /// sun, in the map's frame (`None` when no region stands out as a sun).
    #[serde(skip)]
    pub split: Option<(Arc<EnvMap>, MapSun)>,
}

impl Default for Environment {
    fn default() -> Self {
        Environment {
            file: String::new(),
            rotate_deg: 0.0,
            intensity: 1.0,
            sun_from_map: false,
            map: None,
            split: None,
        }
    }
}

impl Environment {
    /// The EXR at `path` as the sky, turned by `rotate_deg` and scaled by `intensity`; the
    /// error names the file and says what is wrong.
    pub fn open(
        path: &Path,
        rotate_deg: f32,
        intensity: f32,
        sun_from_map: bool,
    ) -> Result<Environment, String> {
        let mut env = Environment {
            file: path.to_string_lossy().into_owned(),
            rotate_deg,
            intensity,
            sun_from_map,
            map: None,
            split: None,
        };
        env.load(Path::new(""))?;
        Ok(env)
    }

    /// Read `file` (resolved against `base`, and kept resolved): the error names the file and
    /// says what is wrong.
    pub fn load(&mut self, base: &Path) -> Result<(), String> {
        let full = base.join(&self.file);
        let map = EnvMap::read_exr(&full).map_err(|e| format!("{}: {e}", full.display()))?;
        self.split = if self.sun_from_map {
            map.split_sun().map(|(rest, sun)| (Arc::new(rest), sun))
        } else {
            None
        };
        self.map = Some(Arc::new(map));
        self.file = full.to_string_lossy().into_owned();
        Ok(())
    }

    /// With `sun_from_map`, the sun the map holds, turned and scaled as the map is (intensity 0
    /// when it holds none); `None` without `sun_from_map`.
    pub fn map_sun(&self) -> Option<Sun> {
        if !self.sun_from_map {
            return None;
        }
        let (dir, irradiance) = match &self.split {
            Some((_, sun)) => (
                to_world(sun.to_sun, self.rotate_deg),
                sun.irradiance * self.intensity,
            ),
            None => (Vec3::Y, Vec3::ZERO),
        };
        let intensity = irradiance.max_element().max(0.0);
        Some(Sun {
            direction: -dir,
            elevation_deg: None,
            azimuth_deg: 0.0,
            color: if intensity > 0.0 {
                irradiance / intensity
            } else {
                Vec3::ONE
            },
            intensity,
        })
    }
}

impl Default for Sky {
    fn default() -> Self {
        Sky::Gradient {
            zenith: Vec3::new(0.08, 0.2, 0.55),
            horizon: Vec3::new(0.36, 0.5, 0.72),
        }
    }
}

/// The settings of the cumulus billows that displace the cloud's surface, anchored to the blobs
/// (the scene file's `cloud.noise`; the billows themselves are `Billows` in
/// `medium/noise.rs`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Noise", deny_unknown_fields, default)]
pub struct NoiseSettings {
    /// Depth of each octave of billows as a fraction of its wavelength (self-similar: the same
    /// at every scale); the surface is pushed out by up to half of it on a billow's top and cut
    /// in by up to half in a crease (0 = smooth blobs).
    pub amplitude: f32,
    /// Frequency of the largest billows in cycles per bounding-box diagonal of the target
    /// (each further octave is about twice as fine; an octave appears only on parts at least
    /// as large as its wavelength).
    pub frequency: f32,
    /// Most octaves (at most [`NoiseSettings::MAX_OCTAVES`]); octaves finer than three pixels of the frame are left out
    /// (`FINEST_BILLOW_PIXELS`) (0 = smooth blobs).
    pub octaves: u32,
    /// Slow evolution of the noise, in cycles per second (0 = frozen; the noise then only
    /// moves with the blobs).
    pub evolve: f32,
}

impl NoiseSettings {
    /// Most octaves the billows hold (the noise's own arrays are this long).
    pub const MAX_OCTAVES: usize = 8;
}

impl Default for NoiseSettings {
    fn default() -> Self {
        NoiseSettings {
            amplitude: 0.5,
            frequency: 5.0,
            octaves: 8,
            evolve: 0.0,
        }
    }
}

/// A cumulus's flat base: below it the cloud thins out over `softness`, so its underside is
/// flat and, shadowed by the cloud above, darker (cumulus above its condensation level). Both
/// values are fractions of the target's height, measured from its bottom (world +Y is up).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CumulusBase {
    /// Height of the base above the target's bottom, fraction of the target's height.
    pub height: f32,
    /// Thickness of the fade below the base, fraction of the target's height (0 = a hard cut).
    pub softness: f32,
}

/// A [`CumulusBase`] in world units: the density is `σ·ramp((y − (y_base − softness)) /
/// softness)` below `y_base`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasePlane {
    /// World height of the base.
    pub y: f32,
    /// World thickness of the fade below it.
    pub softness: f32,
}

impl BasePlane {
    /// Density factor at world height `y`: 1 at and above the base, fading linearly to 0 at
    /// `softness` below it.
    #[inline]
    pub(crate) fn factor(&self, y: f32) -> f32 {
        if y >= self.y {
            1.0
        } else if self.softness > 0.0 {
            ((y - (self.y - self.softness)) / self.softness).clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

/// The cloud's participating medium.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CloudMaterial {
    /// Extinction inside the cloud, per bounding-box diagonal of the target (so it does not
    /// depend on the model's units).
    pub density: f32,
    /// Width of the soft edge (a linear density ramp) as a fraction of the bounding-box
    /// diagonal (0 = hard edge). The default, 0.008, is a thin fringe under the billows: four
    /// voxels of the default volume export (`D / 512`), so an exported grid still holds the
    /// ramp (on the smooth density it was 0.02; the billows now carry the cloud's outline).
    pub edge: f32,
    /// Single-scattering albedo.
    pub albedo: f32,
    /// Henyey–Greenstein asymmetry (forward scattering > 0).
    pub phase_g: f32,
    /// Add multiple scattering to single scattering (false = single scattering only): the
    /// physically based fluence estimate at `Final` and `Production`, the octaves at `Preview`
    /// (`Quality::ms_photons`).
    pub multiple_scattering: bool,
    /// Artistic contrast of the multiple scattering (0, the default: the physical estimate
    /// untouched): the scattered light × `(φ/φ̄)^ms_contrast`, `φ̄` the cloud's mean fluence, so
    /// positive values brighten the bright parts and darken the dim ones, negative even them
    /// out. In `-1..=2`; the fluence estimate only (not the octaves).
    pub ms_contrast: f32,
    /// The billows.
    pub noise: NoiseSettings,
    /// A flat cumulus base (`None`, the default: shapes keep their underside).
    pub base: Option<CumulusBase>,
}

impl Default for CloudMaterial {
    fn default() -> Self {
        CloudMaterial {
            density: 40.0,
            edge: 0.008,
            albedo: 0.95,
            phase_g: 0.75,
            multiple_scattering: true,
            ms_contrast: 0.0,
            noise: NoiseSettings::default(),
            base: None,
        }
    }
}

/// The scene's quality preset (maps to a [`Quality`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum QualityPreset {
    /// Fast and rough, for looking at motion.
    Preview,
    /// The default: clean frames at one sample per pixel.
    #[default]
    Final,
    /// A light grid twice as fine, finer steps, and the cloud's edge anti-aliased (8 more rays
    /// at each partly covered pixel): for backlit shots, whose silver lining is sub-pixel detail
    /// against a bright sky. About 5–8× `Final` (`scenes/README.md`).
    Production,
    /// A path tracer through the same density ([`PathTracing`], `integrator/reference/`): full
    /// transport, no approximation, converging to a physically based renderer's image; slow
    /// and noisy at few samples. For checking a shot's light against the fast march.
    Reference,
}

/// The path tracer of `quality: Reference` (`crate::render::integrator::reference`): samples
/// per pixel and the longest path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PathTracing {
    /// Paths per pixel (each through a random point of the pixel: a box filter).
    pub samples: u32,
    /// Longest path, in Mitsuba's count: scattering orders up to `max_depth − 1` (2 = single
    /// scattering only).
    pub max_depth: u32,
    /// Which paths (mixed with the scene's seed, which also places the billows): a render at
    /// a second `seed` measures the reference's own noise.
    pub seed: u64,
}

impl Default for PathTracing {
    fn default() -> Self {
        PathTracing {
            samples: 64,
            max_depth: 64,
            seed: 0,
        }
    }
}

impl PathTracing {
    /// At least one path a pixel and a depth of at least 2 (single scattering).
    pub fn validate(&self) -> Result<(), InvalidField> {
        if self.samples == 0 {
            return Err(InvalidField::new(
                "reference.samples",
                "must be at least 1".to_string(),
            ));
        }
        if self.max_depth < 2 {
            return Err(InvalidField::new(
                "reference.max_depth",
                format!(
                    "must be at least 2 (single scattering), got {}",
                    self.max_depth
                ),
            ));
        }
        Ok(())
    }
}

/// A pixel's first ray is at the cloud's edge when its coverage `1 − T` lies strictly inside
/// these bounds ([`Quality::edge_samples`]): past the upper one the march stopped in the
/// opaque body, below the lower one it met no cloud worth resolving.
pub(crate) const EDGE_COVERAGE: (f32, f32) = (1e-3, 0.999);

/// Fewest cells [`RenderSettings::light_grid_cells`] gives a light grid (a cloud a few pixels
/// wide still gets a shadowed side).
pub(crate) const MIN_LIGHT_GRID_CELLS: u32 = 24;

/// Light paths a `Final` frame traces for its multiple scattering (docs/MEASUREMENTS.md,
/// "Multiple scattering: the fluence grid").
pub(crate) const FINAL_PHOTONS: u32 = 1 << 20;
/// The same at `Production`.
pub(crate) const PRODUCTION_PHOTONS: u32 = 1 << 20;

/// Speed/quality trade-offs of the ray marcher.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    /// Coarse march step (through the empty parts of the blob supports) as a fraction of the
    /// median blob's support radius (clamped by the renderer to `[L/2000, L/16]`).
    pub step_scale: f32,
    /// Resolution of the light-transmittance grid along its longest side (toward the sun; the
    /// sky's depths use a third of it).
    pub shadow_grid: u32,
    /// Smallest light-grid cell, in pixels of the frame at the camera's look-at distance: a
    /// cloud small on screen (a diffusion's first second) gets fewer than `shadow_grid` cells,
    /// since shadow detail finer than a pixel cannot show (`RenderSettings::light_grid_cells`).
    pub shadow_cell_pixels: f32,
    /// Scattering octaves of the multiple-scattering approximation (1 = single scattering
    /// only; at most 6), when `ms_photons` is 0.
    pub ms_octaves: u32,
    /// Light paths traced per frame for the physically based multiple scattering (the
    /// fluence grid, `render::light::fluence`); 0: the octaves instead.
    pub ms_photons: u32,
    /// Optical thickness `σ·h` of a march step inside the cloud where the ray enters it; deeper
    /// in, steps grow as the transmittance falls (each absorbs about this much of the pixel's
    /// light), up to an optical thickness of 1. Smaller = less grain at the sunlit surface,
    /// slower.
    pub optical_step: f32,
    /// Rays per pixel (stratified inside the pixel; 1 = through the pixel centre).
    pub samples: u32,
    /// Adaptive anti-aliasing of the cloud's edge: with one ray a pixel, a pixel whose ray's
    /// coverage is partial (between `EDGE_COVERAGE`'s bounds) traces this many more,
    /// stratified inside it, and averages all of them. The silhouette against a bright sky (a
    /// backlit cloud's silver lining) then costs its edge pixels' rays only, not every
    /// pixel's. 0 or 1: off.
    pub edge_samples: u32,
    /// Time samples across an open shutter (`shot.shutter > 0`; motion blur): a pixel then
    /// traces `max(samples, time_samples)` rays, each at its own time stratum. Unused when the
    /// shutter is closed.
    pub time_samples: u32,
    /// Path trace instead of marching (`quality: Reference`; `None`: the march).
    pub reference: Option<PathTracing>,
}

impl Quality {
    /// The settings of a preset.
    pub fn preset(preset: QualityPreset) -> Quality {
        match preset {
            QualityPreset::Preview => Quality::preview(),
            QualityPreset::Final => Quality::final_frame(),
            // Measured on the backlit golden-hour shot against Mitsuba 3 (docs/MEASUREMENTS.md,
            // "Checked against Mitsuba 3"): the light grid's cells and the edge's rays are what
            // bring its silver lining within 5 %; rays in the opaque body and steps finer than
            // 0.04 barely move it. A fourth scattering octave made that shot's multiple
            // scattering 35 % brighter than full transport (three: within 3 %).
            QualityPreset::Production => Quality {
                step_scale: 0.2,
                shadow_grid: 448,
                shadow_cell_pixels: 0.5,
                ms_octaves: 3,
                ms_photons: PRODUCTION_PHOTONS,
                optical_step: 0.04,
                samples: 1,
                edge_samples: 8,
                time_samples: 8,
                reference: None,
            },
            QualityPreset::Reference => Quality {
                reference: Some(PathTracing::default()),
                ..Quality::final_frame()
            },
        }
    }

    /// Full quality for final frames.
    pub fn final_frame() -> Quality {
        Quality {
            step_scale: 0.25,
            shadow_grid: 224,
            shadow_cell_pixels: 1.0,
            ms_octaves: 3,
            ms_photons: FINAL_PHOTONS,
            optical_step: 0.08,
            samples: 1,
            edge_samples: 0,
            time_samples: 4,
            reference: None,
        }
    }

    /// Fast, rough quality for previews.
    pub fn preview() -> Quality {
        Quality {
            step_scale: 0.6,
            shadow_grid: 48,
            shadow_cell_pixels: 1.0,
            ms_octaves: 2,
            ms_photons: 0,
            optical_step: 0.2,
            samples: 1,
            edge_samples: 0,
            time_samples: 2,
            reference: None,
        }
    }
}

/// Everything needed to render one frame besides the blobs.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// The camera for this frame.
    pub camera: Camera,
    /// Sun light.
    pub sun: Sun,
    /// Sky (background and ambient).
    pub sky: Sky,
    /// Cloud medium.
    pub cloud: CloudMaterial,
    /// Exposure in stops applied before tone mapping the PNG (EXR stays linear, unexposed).
    pub exposure: f32,
    /// Length unit for densities and noise frequency: the target's bounding-box diagonal.
    pub length_scale: f32,
    /// Seed for per-pixel jitter and noise offsets.
    pub seed: u64,
    /// Time of the frame in seconds from the start of the shot (drives `cloud.noise.evolve`).
    pub time: f32,
    /// March quality.
    pub quality: Quality,
    /// `cloud.base` resolved against the target's box (`None`: no base).
    pub base: Option<BasePlane>,
    /// The shot's holdouts and ground plane (`None`: none; `crate::render::surfaces`).
    pub surfaces: Option<std::sync::Arc<crate::render::Surfaces>>,
}

impl RenderSettings {
    /// Cells on the longest side of a light grid over a cloud of `bounds` (world box, as
    /// [`crate::render::Medium::bounds`] gives): `quality.shadow_grid`, or fewer where its cells would
    /// be finer than `quality.shadow_cell_pixels` of a pixel ([`RenderSettings::pixel_footprint`]),
    /// and at least [`MIN_LIGHT_GRID_CELLS`].
    pub(crate) fn light_grid_cells(&self, bounds: Option<(glam::Vec3A, glam::Vec3A)>) -> u32 {
        let extent = bounds.map_or(0.0, |(lo, hi)| (hi - lo).max_element());
        let cell = self.quality.shadow_cell_pixels * self.pixel_footprint();
        let res = self.quality.shadow_grid;
        if !(cell > 0.0 && extent > 0.0) {
            return res;
        }
        // `as` saturates: a cloud far wider than the frame's pixels gets `res`.
        (((extent / cell).ceil()) as u32).clamp(MIN_LIGHT_GRID_CELLS.min(res), res)
    }

    /// World size of one pixel at the camera's look-at distance (the scale of the finest detail
    /// the frame resolves).
    pub(crate) fn pixel_footprint(&self) -> f32 {
        let c = &self.camera;
        let dist = (c.look_at - c.position).length();
        let half = (0.5 * c.fov_deg.to_radians()).tan();
        (2.0 * dist * half / self.height.max(1) as f32).max(0.0)
    }
}
