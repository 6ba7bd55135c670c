//! What a frame is rendered with: camera, sun, sky, cloud material, film and quality.
//! The serde types here are read directly from scene files (unknown fields are errors; every
//! field has a default, documented in `scenes/README.md`).

use glam::Vec3;
use serde::{Deserialize, Serialize};

/// A pinhole camera in world space (the model's units), +Y up.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Point the camera looks at.
    pub look_at: Vec3,
    /// Up hint (need not be orthogonal to the view direction).
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub fov_deg: f32,
}

/// The sun: a directional light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sun {
    /// Direction the light travels (from the sun toward the scene); need not be unit length.
    pub direction: Vec3,
    /// Linear RGB colour.
    pub color: Vec3,
    /// Radiance scale.
    pub intensity: f32,
}

impl Default for Sun {
    fn default() -> Self {
        Sun {
            direction: Vec3::new(-0.4, -0.8, -0.3),
            color: Vec3::new(1.0, 0.95, 0.85),
            intensity: 12.0,
        }
    }
}

/// Sky dome: the background and the ambient light on the cloud.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Sky {
    /// Vertical gradient from the horizon colour to the zenith colour (linear RGB).
    Gradient {
        /// Colour straight up.
        zenith: Vec3,
        /// Colour at the horizon.
        horizon: Vec3,
    },
}

impl Default for Sky {
    fn default() -> Self {
        Sky::Gradient {
            zenith: Vec3::new(0.08, 0.2, 0.55),
            horizon: Vec3::new(0.36, 0.5, 0.72),
        }
    }
}

/// Fractal noise that breaks up the cloud's density, anchored to the blobs.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Noise {
    /// Strength relative to the iso-level (0 = smooth blobs).
    pub amplitude: f32,
    /// Base frequency in cycles per bounding-box diagonal of the target.
    pub frequency: f32,
    /// Number of fBm octaves.
    pub octaves: u32,
}

impl Default for Noise {
    fn default() -> Self {
        Noise {
            amplitude: 1.5,
            frequency: 5.0,
            octaves: 4,
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
    /// Width of the soft edge around the iso-level, in field units (0 = hard edge).
    pub edge: f32,
    /// Single-scattering albedo.
    pub albedo: f32,
    /// Henyey–Greenstein asymmetry (forward scattering > 0).
    pub phase_g: f32,
    /// Density noise.
    pub noise: Noise,
}

impl Default for CloudMaterial {
    fn default() -> Self {
        CloudMaterial {
            density: 40.0,
            edge: 0.25,
            albedo: 0.95,
            phase_g: 0.75,
            noise: Noise::default(),
        }
    }
}

/// Speed/quality trade-offs of the ray marcher.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    /// Coarse march step (through the empty parts of the blob supports) as a fraction of the
    /// median blob's support radius (clamped by the renderer to `[L/2000, L/16]`).
    pub step_scale: f32,
    /// Resolution of the light-transmittance grid along its longest side.
    pub shadow_grid: u32,
    /// Scattering octaves of the multiple-scattering approximation (1 = single scattering
    /// only; at most 6).
    pub ms_octaves: u32,
    /// Largest optical thickness `σ·h` of one march step inside the cloud (smaller = less
    /// grain at the sunlit surface, slower).
    pub optical_step: f32,
}

impl Quality {
    /// Full quality for final frames.
    pub fn final_frame() -> Quality {
        Quality {
            step_scale: 0.25,
            shadow_grid: 128,
            ms_octaves: 3,
            optical_step: 0.25,
        }
    }

    /// Fast, rough quality for previews.
    pub fn preview() -> Quality {
        Quality {
            step_scale: 0.6,
            shadow_grid: 48,
            ms_octaves: 2,
            optical_step: 0.5,
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
    /// March quality.
    pub quality: Quality,
}
