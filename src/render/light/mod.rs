//! Optical depths toward the lights: what the shader needs to know about shadowing at a
//! sample, and who can answer it.
//!
//! In: a world point. Out: [`LightDepths`] toward the sun and each sky cell of
//! [`crate::render::light::sky_cells`]. The production answer is the per-frame light grid
//! ([`crate::render::light::grid::LightGrid`], built from any [`crate::render::Medium`]); [`HomogeneousLights`]
//! answers exactly for the analytic test media, [`Unshadowed`] for nothing in the way. Keeping
//! this apart from the medium lets a light grid built from one medium (e.g. the cloud at the
//! frame's time) light the march through another (the cloud at a motion-blur sample time).

pub mod envmap;
pub(crate) mod fluence;
pub(crate) mod grid;
pub mod phase;
pub(crate) mod shading;
pub(crate) mod sky_cells;
pub(crate) mod sky_depth;
pub(crate) mod sky_dome;
pub(crate) mod sky_view;
pub(crate) mod sun_depth;

use glam::Vec3A;

use crate::render::light::sky_cells::{SKY_DIRECTIONS, directions};
use crate::render::medium::Homogeneous;

/// Optical depths from a point toward the lights: the sun, and each sky cell of
/// `light/sky_cells.rs` (in the order of [`directions`], `render::sky_directions`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightDepths {
    /// Toward the sun.
    pub sun: f32,
    /// Toward each sky cell.
    pub sky: [f32; SKY_DIRECTIONS],
}

impl LightDepths {
    /// No medium in the way.
    pub const ZERO: LightDepths = LightDepths {
        sun: 0.0,
        sky: [0.0; SKY_DIRECTIONS],
    };
}

/// Light that has scattered at least once, at a point: its fluence `φ = ∫L dω` (RGB) and flux
/// `F = ∫L ω dω` (luminance; the direction it flows), from the fluence grid
/// ([`crate::render::light::fluence`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MultipleLight {
    /// Fluence, RGB.
    pub fluence: Vec3A,
    /// Net flux (of the luminance), a vector along the light's mean direction of travel.
    pub flux: Vec3A,
    /// Fluence of sunlight scattered exactly once (luminance; the sun's colour), which
    /// `fluence` and `flux` leave out: it keeps the phase function's lobe about the sun.
    pub sun_once: f32,
    /// Net flux of the sunlight scattered exactly once (luminance).
    pub sun_once_flux: Vec3A,
    /// The sun's share of `fluence`: the fluence (luminance) of sunlight scattered twice or
    /// more.
    pub sun_multiple: f32,
    /// The mean of the sun's sub-cell detail ([`crate::render::light::fluence::sun_detail`])
    /// over the fluence grid's cells here, as the grid's values are means over its cells (0:
    /// no grid, no detail).
    pub sun_detail_mean: f32,
}

impl MultipleLight {
    /// No scattered light.
    pub const ZERO: MultipleLight = MultipleLight {
        fluence: Vec3A::ZERO,
        flux: Vec3A::ZERO,
        sun_once: 0.0,
        sun_once_flux: Vec3A::ZERO,
        sun_multiple: 0.0,
        sun_detail_mean: 0.0,
    };
}

/// Something that knows the optical depths toward the lights anywhere in a frame.
pub trait ShadowDepths: Sync {
    /// Optical depths from `x` toward the sun and the sky cells.
    fn depths(&self, x: Vec3A) -> LightDepths;

    /// The light scattered at least once at `x`, for the physically based multiple
    /// scattering (none by default: lights without a fluence grid).
    #[inline]
    fn multiple(&self, _x: Vec3A) -> MultipleLight {
        MultipleLight::ZERO
    }
}

/// Nothing casts a shadow (all depths 0).
#[derive(Clone, Copy, Debug, Default)]
pub struct Unshadowed;

impl ShadowDepths for Unshadowed {
    #[inline]
    fn depths(&self, _: Vec3A) -> LightDepths {
        LightDepths::ZERO
    }
}

/// `None` (e.g. no light grid for an empty cloud) is [`Unshadowed`].
impl<L: ShadowDepths> ShadowDepths for Option<L> {
    #[inline]
    fn depths(&self, x: Vec3A) -> LightDepths {
        self.as_ref().map_or(LightDepths::ZERO, |l| l.depths(x))
    }

    #[inline]
    fn multiple(&self, x: Vec3A) -> MultipleLight {
        self.as_ref().map_or(MultipleLight::ZERO, |l| l.multiple(x))
    }
}

/// Exact depths through a [`Homogeneous`] medium (chords of its shape), for tests and
/// calibration.
#[derive(Clone, Copy, Debug)]
pub struct HomogeneousLights {
    /// The medium casting the shadows.
    pub medium: Homogeneous,
    /// Unit direction the sunlight travels (must match the render settings).
    pub sun_dir: Vec3A,
}

impl ShadowDepths for HomogeneousLights {
    fn depths(&self, x: Vec3A) -> LightDepths {
        let m = &self.medium;
        let depth = |dir: Vec3A| {
            m.shape
                .interval(x, dir)
                .map_or(0.0, |(t0, t1)| m.sigma_t * (t1 - t0))
        };
        let dirs = directions();
        let sun = depth(-self.sun_dir);
        LightDepths {
            sun,
            sky: std::array::from_fn(|k| depth(dirs[k])),
        }
    }
}
