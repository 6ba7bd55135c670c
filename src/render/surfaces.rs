//! The shot's opaque surfaces that are not cloud: **holdouts** (the plate's own geometry, a hill
//! or a building, that hides the cloud behind it) and the **ground plane** that catches the
//! cloud's shadow (the `shadow` pass).
//!
//! In: the holdouts' triangles (already placed in the shot) and the ground's height. Out: ray
//! casts through one BVH per role ([`Surfaces::holdout_hit`], the camera's; the shadow casters'
//! for the light grid, [`Surfaces::caster_hit`]), never a loop over the triangles
//! ([`crate::render::bvh`]).
//!
//! What the integrator does with them (`integrator/surface_rays.rs`): a camera ray's march stops
//! at its holdout hit (the cloud in front is kept; the holdout adds nothing: colour and alpha 0
//! behind it; no sky light straight through); a pixel whose corners disagree on the holdout
//! traces more rays (its edge anti-aliased); the `holdout` layer is the fraction of a
//! pixel's rays that hit one. With the shadow pass, the nearest surface a ray sees (a holdout
//! or the ground plane) gets one shadow ray toward the sun through the medium. Holdouts with
//! `shadows` are baked into the light grid (`light/grid.rs`): a node they hide from the sun or
//! from a sky cell gets no light from it.

use std::sync::Arc;

use glam::{DVec3, Vec3A};

use crate::render::bvh::TriangleBvh;
use crate::render::camera::{Frustum, Ray};

/// One holdout's triangles in the shot's coordinates, and whether it shadows the cloud.
#[derive(Clone, Debug, Default)]
pub struct HoldoutMesh {
    /// Vertices, world units.
    pub positions: Vec<DVec3>,
    /// Triangles (indices into `positions`).
    pub triangles: Vec<[u32; 3]>,
    /// Whether it shadows the cloud from the sun and the sky (baked into the light grid).
    pub shadows: bool,
}

/// The ground plane `y = height` (world units), a shadow catcher.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ground {
    /// Height of the plane.
    pub height: f32,
}

/// A BVH over triangles and the ball that bounds them (the tile cull).
#[derive(Clone)]
struct Bvh {
    mesh: Arc<TriangleBvh>,
    center: Vec3A,
    radius: f32,
}

impl Bvh {
    fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Result<Option<Bvh>, String> {
        if triangles.is_empty() {
            return Ok(None);
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let mesh = TriangleBvh::new(&positions, &triangles);
        let center = 0.5 * (lo + hi);
        Ok(Some(Bvh {
            mesh: Arc::new(mesh),
            center: center.as_vec3a(),
            radius: (0.5 * (hi - lo).length() * (1.0 + 1e-6) + 1e-6) as f32,
        }))
    }

    /// Distance along `ray` (unit direction) to the nearest triangle in `(0, max]`.
    #[inline]
    fn hit(&self, origin: Vec3A, dir: Vec3A, max: f32) -> Option<f32> {
        // The ball first: most rays of a frame miss a holdout's box.
        let oc = origin - self.center;
        let b = oc.dot(dir);
        let c = oc.length_squared() - self.radius * self.radius;
        if c > 0.0 && (b > 0.0 || b * b < c) {
            return None;
        }
        self.mesh.hit(origin, dir, max)
    }

    /// [`Bvh::hit`] with the unit normal of the triangle hit, facing against `dir`.
    #[inline]
    fn hit_normal(&self, origin: Vec3A, dir: Vec3A, max: f32) -> Option<(f32, Vec3A)> {
        let oc = origin - self.center;
        let b = oc.dot(dir);
        let c = oc.length_squared() - self.radius * self.radius;
        if c > 0.0 && (b > 0.0 || b * b < c) {
            return None;
        }
        self.mesh.hit_normal(origin, dir, max)
    }

    /// Whether any triangle lies on the ray within `max` (the ball first, as [`Bvh::hit`]).
    #[inline]
    fn occluded(&self, origin: Vec3A, dir: Vec3A, max: f32) -> bool {
        let oc = origin - self.center;
        let b = oc.dot(dir);
        let c = oc.length_squared() - self.radius * self.radius;
        if c > 0.0 && (b > 0.0 || b * b < c) {
            return false;
        }
        self.mesh.occluded(origin, dir, max)
    }
}

/// The shot's holdouts and ground plane (see the module doc). Two are equal when their `key`
/// is (the scene's hash of the meshes, their transforms and flags, and the ground).
#[derive(Clone)]
pub struct Surfaces {
    key: u64,
    /// Every holdout: what the camera's rays stop at.
    camera: Option<Bvh>,
    /// The holdouts with `shadows`.
    casters: Option<Bvh>,
    ground: Option<Ground>,
    shadow_pass: bool,
}

impl std::fmt::Debug for Surfaces {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Surfaces")
            .field("key", &self.key)
            .field(
                "holdout_triangles",
                &self.camera.as_ref().map_or(0, |b| b.mesh.len()),
            )
            .field(
                "caster_triangles",
                &self.casters.as_ref().map_or(0, |b| b.mesh.len()),
            )
            .field("ground", &self.ground)
            .field("shadow_pass", &self.shadow_pass)
            .finish()
    }
}

impl PartialEq for Surfaces {
    fn eq(&self, other: &Surfaces) -> bool {
        self.key == other.key
    }
}

/// Optical depth a light-grid node hidden by a shadow-casting holdout gets: the sky's stored
/// depths saturate there (`u16::MAX` steps of 1/512), and `e^{−128/8}` is 10⁻⁷ even for the
/// weakest multiple-scattering octave.
pub(crate) const BLOCKED_DEPTH: f32 = 128.0;

impl Surfaces {
    /// The surfaces of a shot: `holdouts` (placed), the `ground` plane, whether the frame gets
    /// the `shadow` pass; `key` identifies them all (frames are reused only under equal keys).
    /// An error says why a holdout's triangles cannot be indexed (its index in the list).
    pub fn new(
        key: u64,
        holdouts: Vec<HoldoutMesh>,
        ground: Option<Ground>,
        shadow_pass: bool,
    ) -> Result<Surfaces, String> {
        let merge = |only_casters: bool| {
            let (mut p, mut t) = (Vec::new(), Vec::new());
            for h in holdouts.iter().filter(|h| h.shadows || !only_casters) {
                let base = p.len() as u32;
                p.extend_from_slice(&h.positions);
                t.extend(h.triangles.iter().map(|tri| tri.map(|i| i + base)));
            }
            (p, t)
        };
        for (i, h) in holdouts.iter().enumerate() {
            let n = h.positions.len();
            if let Some(bad) = h.triangles.iter().flatten().find(|&&v| v as usize >= n) {
                return Err(format!("holdout {i}: vertex index {bad} of {n} vertices"));
            }
            if !h.positions.iter().all(|p| p.is_finite()) {
                return Err(format!("holdout {i}: a vertex is not finite"));
            }
        }
        let (p, t) = merge(false);
        let camera = Bvh::new(p, t)?;
        let casters = if holdouts.iter().all(|h| h.shadows) {
            camera.clone()
        } else if holdouts.iter().any(|h| h.shadows) {
            let (p, t) = merge(true);
            Bvh::new(p, t)?
        } else {
            None
        };
        Ok(Surfaces {
            key,
            camera,
            casters,
            ground,
            shadow_pass: shadow_pass && ground.is_some(),
        })
    }

    /// What identifies them (the scene's hash).
    pub fn key(&self) -> u64 {
        self.key
    }

    /// Whether there are holdouts (the frame then has a `holdout` layer).
    pub fn has_holdouts(&self) -> bool {
        self.camera.is_some()
    }

    /// Whether some holdout shadows the cloud (baked into the light grid).
    pub fn casts_shadows(&self) -> bool {
        self.casters.is_some()
    }

    /// The ground plane, if any.
    pub(crate) fn ground(&self) -> Option<Ground> {
        self.ground
    }

    /// Whether the frame gets the `shadow` pass.
    pub fn shadow_pass(&self) -> bool {
        self.shadow_pass
    }

    /// False only when no holdout can be inside `frustum` (a tile's).
    #[inline]
    pub(crate) fn may_hold_out(&self, frustum: &Frustum) -> bool {
        self.camera
            .as_ref()
            .is_some_and(|b| frustum.may_contain_ball(b.center, b.radius))
    }

    /// Distance along the camera ray to the nearest holdout, infinity when it meets none.
    #[inline]
    pub(crate) fn holdout_hit(&self, ray: &Ray) -> f32 {
        self.camera
            .as_ref()
            .and_then(|b| b.hit(ray.origin, ray.dir, f32::MAX))
            .unwrap_or(f32::INFINITY)
    }

    /// The unit normal, facing the camera, of the holdout the camera ray meets first (the
    /// shadow pass's surface point; `None`: it meets none).
    #[inline]
    pub(crate) fn holdout_normal(&self, ray: &Ray) -> Option<Vec3A> {
        self.camera
            .as_ref()
            .and_then(|b| b.hit_normal(ray.origin, ray.dir, f32::MAX))
            .map(|(_, n)| n)
    }

    /// Whether the camera ray meets a holdout (any hit: the pixel corners' test).
    #[inline]
    pub(crate) fn holdout_seen(&self, ray: &Ray) -> bool {
        self.camera
            .as_ref()
            .is_some_and(|b| b.occluded(ray.origin, ray.dir, f32::MAX))
    }

    /// Distance along `ray` to the ground plane, infinity when it does not meet it ahead.
    #[inline]
    pub(crate) fn ground_hit(&self, ray: &Ray) -> f32 {
        match self.ground {
            Some(g) if ray.dir.y != 0.0 => {
                let t = (g.height - ray.origin.y) / ray.dir.y;
                if t > 0.0 { t } else { f32::INFINITY }
            }
            _ => f32::INFINITY,
        }
    }

    /// Distance from `origin` along unit `dir` to the nearest shadow-casting holdout within
    /// `max` (`None`: none).
    #[inline]
    pub(crate) fn caster_hit(&self, origin: Vec3A, dir: Vec3A, max: f32) -> Option<f32> {
        self.casters.as_ref().and_then(|b| b.hit(origin, dir, max))
    }

    /// Whether a shadow-casting holdout lies on the way from `origin` along unit `dir`.
    #[inline]
    pub(crate) fn caster_occludes(&self, origin: Vec3A, dir: Vec3A) -> bool {
        self.casters
            .as_ref()
            .is_some_and(|b| b.occluded(origin, dir, f32::MAX))
    }

    /// Whether any holdout lies on the way from `origin` along unit `dir` (a shadow ray
    /// toward the sun from a surface point: where the plate's own geometry shadows it, the
    /// cloud's shadow darkens nothing more).
    #[inline]
    pub(crate) fn any_holdout_on(&self, origin: Vec3A, dir: Vec3A) -> bool {
        self.camera
            .as_ref()
            .is_some_and(|b| b.occluded(origin, dir, f32::MAX))
    }
}
