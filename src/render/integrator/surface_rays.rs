//! What the camera's rays ask of the shot's surfaces ([`crate::render::Surfaces`]): where a ray
//! stops at a holdout ([`stop`]), whether a pixel lies on a holdout's edge (its corners
//! disagree: [`TileHoldouts::pixel`]; it then traces [`HOLDOUT_EDGE_RAYS`] more rays), and the
//! shadow pass's values for a ray ([`shadow`]: the sun's `shadow`, and `shadow_total` with the
//! sky's share, `shadow_total/`); [`mark`] puts them on a ray's result.
//!
//! A tile whose frustum misses every holdout's bounding ball casts nothing: its pixels are
//! marched exactly as without holdouts (the same bits). Inside an active tile the pixel
//! corners' hits are cast once per tile, `(TILE + 1)²` rays shared by neighbouring pixels.

use glam::Vec3A;
use rand_pcg::Pcg64Mcg;

use crate::render::camera::{CameraRays, Frustum, Ray};
use crate::render::integrator::PixelResult;
use crate::render::integrator::march::optical_depth;
use crate::render::integrator::shadow_total::ShadowTotal;
use crate::render::medium::Medium;
use crate::render::output::film::Region;
use crate::render::surfaces::Surfaces;

/// More rays a pixel on a holdout's edge traces (stratified inside it, besides its first) when
/// the quality gives a pixel one ray: its coverage then comes in ninths.
pub(crate) const HOLDOUT_EDGE_RAYS: u32 = 8;

/// What a pixel's corners see of the holdouts ([`TileHoldouts::pixel`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Corners {
    /// No corner sees a holdout: the pixel is marched as without holdouts (no ray cast; a
    /// holdout thinner than the pixel between its corners is not seen).
    None,
    /// Every corner sees one: its rays stop at their casts.
    All,
    /// Some do: the holdout's edge crosses the pixel (more rays, each cast).
    Some,
}

/// One tile's view of the holdouts: whether any may be inside it, and its pixel corners' hits.
#[derive(Clone, Debug, Default)]
pub(crate) struct TileHoldouts {
    active: bool,
    x0: u32,
    y0: u32,
    stride: usize,
    corners: Vec<bool>,
}

impl TileHoldouts {
    /// Begin the tile `whole` (its pixels) of frustum `frustum`: nothing to do when no holdout
    /// may be inside it; else its pixel corners' rays cast.
    pub(crate) fn begin(
        &mut self,
        surfaces: Option<&Surfaces>,
        cam: &CameraRays,
        whole: &Region,
        frustum: &Frustum,
    ) {
        self.active = surfaces.is_some_and(|s| s.may_hold_out(frustum));
        let Some(s) = surfaces.filter(|_| self.active) else {
            return;
        };
        self.x0 = whole.x0;
        self.y0 = whole.y0;
        self.stride = (whole.width() + 1) as usize;
        self.corners.clear();
        for y in whole.y0..=whole.y1 {
            for x in whole.x0..=whole.x1 {
                self.corners
                    .push(s.holdout_seen(&cam.ray(x as f32, y as f32)));
            }
        }
        if !self.corners.iter().any(|&c| c) {
            // No corner of the tile sees a holdout: none of its pixels is touched.
            self.active = false;
        }
    }

    /// What pixel `(x, y)`'s four corners see.
    #[inline]
    pub(crate) fn pixel(&self, x: u32, y: u32) -> Corners {
        if !self.active {
            return Corners::None;
        }
        let i = (y - self.y0) as usize * self.stride + (x - self.x0) as usize;
        let c = &self.corners;
        let hits = [c[i], c[i + 1], c[i + self.stride], c[i + self.stride + 1]]
            .iter()
            .filter(|&&h| h)
            .count();
        match hits {
            0 => Corners::None,
            4 => Corners::All,
            _ => Corners::Some,
        }
    }
}

/// Where a ray of a pixel whose corners see `corners` stops: its holdout hit, infinity when it
/// meets none (no cast where no corner sees a holdout).
#[inline]
pub(crate) fn stop(surfaces: Option<&Surfaces>, corners: Corners, ray: &Ray) -> f32 {
    match surfaces {
        Some(s) if corners != Corners::None => s.holdout_hit(ray),
        _ => f32::INFINITY,
    }
}

/// The shadow pass's state for one pixel's rays: the medium's scratch for the sun's ray (begun
/// on [`Frustum::EVERYTHING`]), the frame's constants of `shadow_total` and the pixel's
/// generator for its directions toward the cloud (`Stream::SkyShadow`).
pub(crate) struct ShadowRays<'a, S> {
    pub(crate) scratch: &'a mut S,
    pub(crate) total: &'a ShadowTotal,
    pub(crate) rng: &'a mut Pcg64Mcg,
}

/// What the surfaces add to camera `ray`'s result `r`: the `holdout` layer's share (1 when a
/// holdout stopped the ray at `t_hold`) and, with the shadow pass (`pass`), its `shadow` value
/// ([`shadow`]); returns the ray's `shadow_total` (1 without the pass). The one rule for a
/// still and a blurred frame's rays.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn mark<M: Medium>(
    r: &mut PixelResult,
    surfaces: Option<&Surfaces>,
    medium: &M,
    pass: Option<ShadowRays<'_, M::Scratch>>,
    ray: &Ray,
    t_hold: f32,
    to_sun: Vec3A,
    jitter: f32,
) -> Vec3A {
    if t_hold < f32::INFINITY {
        r.holdout = 1.0;
    }
    match (surfaces, pass) {
        (Some(s), Some(pass)) => {
            let (sun, total) = shadow(s, medium, pass, ray, t_hold, to_sun, jitter);
            r.shadow = sun;
            total
        }
        _ => Vec3A::ONE,
    }
}

/// The shadow pass's values for a camera `ray` stopped by a holdout at `t_hold` (infinity:
/// none), `shadow` and `shadow_total`. Where it sees a surface — the nearer of the holdout and
/// the ground plane — `shadow` is the sun's transmittance `exp(−∫σ dt)` from that point toward
/// the sun (`to_sun`, unit) through `medium` (marched by `pass.scratch`); 1 where it sees no
/// surface, and where a holdout lies between the point and the sun (the plate's own geometry
/// shadows it already: the cloud darkens it no further). `shadow_total` adds the sky's share
/// ([`ShadowTotal::value`], at the surface's normal facing the camera).
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn shadow<M: Medium>(
    surfaces: &Surfaces,
    medium: &M,
    pass: ShadowRays<'_, M::Scratch>,
    ray: &Ray,
    t_hold: f32,
    to_sun: Vec3A,
    jitter: f32,
) -> (f32, Vec3A) {
    let t_ground = surfaces.ground_hit(ray);
    let t = t_hold.min(t_ground);
    if !t.is_finite() {
        return (1.0, Vec3A::ONE);
    }
    let p = ray.at(t);
    let normal = if t_hold < t_ground {
        surfaces.holdout_normal(ray).unwrap_or(-ray.dir)
    } else if ray.dir.y < 0.0 {
        Vec3A::Y
    } else {
        Vec3A::NEG_Y
    };
    // Off the surface, so that the shadow ray does not find the triangle it starts on.
    let origin = p + to_sun * (1e-4 * (1.0 + p.abs().max_element()));
    let seen = !surfaces.any_holdout_on(origin, to_sun);
    let sun = if seen {
        let shadow_ray = Ray {
            origin,
            dir: to_sun,
        };
        (-optical_depth(medium, pass.scratch, &shadow_ray, jitter)).exp()
    } else {
        1.0
    };
    let on_ground = t_hold >= t_ground;
    let total = pass
        .total
        .value(surfaces, p, normal, on_ground, sun, seen, pass.rng);
    (sun, total)
}
