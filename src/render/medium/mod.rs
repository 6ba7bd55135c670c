//! What the integrator marches through: the [`Medium`] contract (extinction along rays, as
//! pbrt's `Medium`; the phase function is the cloud material's, [`crate::render::light::phase`]), and
//! [`Homogeneous`], an analytic constant-density ball or slab used to check the integrator
//! against closed forms.
//!
//! A medium knows its density only: the light reaching a sample comes from a separate
//! [`crate::render::light::ShadowDepths`] (the light grid, built from any medium by
//! [`crate::render::light::grid::LightGrid::build`]), so one medium can be lit by another's grid.
//!
//! The blob cloud ([`crate::render::medium::blobs::BlobMedium`]) is the production medium. `Medium` is a trait
//! (not an enum) so that the integrator is monomorphised per medium with no dispatch in the
//! per-sample loop; it is on the public front so that a medium of one's own (the Mitsuba
//! comparison's dense grid, `tests/it/mitsuba_support/grid_medium.rs`) goes through the same
//! integrator ([`crate::render::render_medium`]).

pub(crate) mod blobs;
pub(crate) mod density;
pub(crate) mod lattice;
pub(crate) mod noise;

use glam::{Mat3A, Vec3A};

use crate::render::camera::{Frustum, Ray, ray_ellipsoid};

/// No piece of the medium (where no blob's field reaches: the ID mattes' empty rank).
pub const NO_PIECE: u32 = u32::MAX;

/// A participating medium as the integrator sees it.
///
/// Calling protocol per thread: [`Medium::begin_tile`] once per tile, then per ray
/// [`Medium::begin_ray`], then [`Medium::extinction`] at increasing `t` inside
/// [`Medium::intervals`].
pub trait Medium: Sync {
    /// Per-thread scratch, reused across tiles and rays (no allocation per ray once warm).
    type Scratch: Send;

    /// Fresh scratch for one thread.
    fn scratch(&self) -> Self::Scratch;

    /// Prepare for the rays inside `frustum` (e.g. cull the medium's pieces once per tile).
    fn begin_tile(&self, frustum: &Frustum, scratch: &mut Self::Scratch);

    /// Prepare for `ray` (which lies inside the last tile's frustum).
    fn begin_ray(&self, ray: &Ray, scratch: &mut Self::Scratch);

    /// Show the following rays the medium `dt` seconds after the time it stands for (motion
    /// blur inside one time sample; `integrator/motion_blur.rs`). Default: the medium does not move.
    #[inline]
    fn set_time_offset(&self, _scratch: &mut Self::Scratch, _dt: f32) {}

    /// Sorted, disjoint `[t0, t1]` (`0 ≤ t0 < t1`) outside which the last ray's extinction is
    /// zero.
    fn intervals<'s>(&self, scratch: &'s Self::Scratch) -> &'s [[f32; 2]];

    /// Extinction `σ_t ≥ 0` (per unit length) at `x = ray.at(t)`, `t` inside the intervals.
    /// Cheapest when a ray's `t` grow from call to call (a medium may drop what the ray has
    /// left); any order is correct.
    fn extinction(&self, scratch: &mut Self::Scratch, t: f32, x: Vec3A) -> f32;

    /// Extinction at `t` and whether `x` lies inside the medium's shape even where the
    /// extinction is zero (e.g. an eroded crease inside a cloud). The integrator marches finely
    /// from the first such point, so thin structures between coarse samples are not skipped.
    /// Default: inside exactly where the extinction is positive.
    #[inline]
    fn sample(&self, scratch: &mut Self::Scratch, t: f32, x: Vec3A) -> (f32, bool) {
        let sigma = self.extinction(scratch, t, x);
        (sigma, sigma > 0.0)
    }

    /// Which piece of the medium dominates the extinction at `t`, the last `t` sampled (for the
    /// ID mattes): for the blob cloud the index, in the frame's blob list, of the blob whose
    /// field term is largest there; [`NO_PIECE`] where none. Default: one piece, 0.
    #[inline]
    fn label(&self, _scratch: &mut Self::Scratch, _t: f32) -> u32 {
        0
    }

    /// A box `(lo, hi)` outside which the extinction is zero; `None` when the medium is empty
    /// or unbounded.
    fn bounds(&self) -> Option<(Vec3A, Vec3A)>;

    /// A box outside which the extinction is zero, in the rotated coordinates `frame · x`
    /// (`frame` a rotation); `None` as for [`Medium::bounds`]. Default: the box of
    /// [`Medium::bounds`]' rotated corners; a medium may give a tighter one.
    fn bounds_in(&self, frame: Mat3A) -> Option<(Vec3A, Vec3A)> {
        let (lo, hi) = self.bounds()?;
        let (mut a, mut b) = (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN));
        for c in 0..8 {
            let corner = Vec3A::select(
                glam::BVec3A::new(c & 1 != 0, c & 2 != 0, c & 4 != 0),
                hi,
                lo,
            );
            let p = frame * corner;
            a = a.min(p);
            b = b.max(p);
        }
        Some((a, b))
    }

    /// Coarse march step through empty parts of the intervals (world units).
    fn step(&self) -> f32;

    /// Upper bound of the extinction (sets the fine step inside the medium).
    fn max_extinction(&self) -> f32;

    /// Stride (world units) the march may take, before the ray has met any density, from an
    /// empty sample where [`Medium::sample`] said density may lie; where a stride finds density
    /// the march goes back to the empty sample and steps finely over the stride. It may step
    /// over a sliver of density thinner than the stride. Default 0: the fine step everywhere.
    fn empty_stride(&self) -> f32 {
        0.0
    }

    /// True when no ray of the last tile ([`Medium::begin_tile`]) can meet the medium (its
    /// intervals are then empty): a pixel a holdout covers there needs no cast for where its
    /// ray stops. Default false (not known).
    fn tile_is_empty(&self, _scratch: &Self::Scratch) -> bool {
        false
    }
}

/// Shape of a [`Homogeneous`] medium.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A ball.
    Ball {
        /// Centre.
        center: Vec3A,
        /// Radius.
        radius: f32,
    },
    /// The points `x` with `near ≤ normal·x ≤ far`.
    Slab {
        /// Unit normal.
        normal: Vec3A,
        /// Lower offset.
        near: f32,
        /// Upper offset.
        far: f32,
    },
}

impl Shape {
    /// Parameters `[t0, t1]` (`t ≥ 0`) of the ray `origin + t·dir` inside the shape; `None` on a
    /// miss or an empty overlap.
    pub fn interval(&self, origin: Vec3A, dir: Vec3A) -> Option<(f32, f32)> {
        match *self {
            Shape::Ball { center, radius } => {
                let inv = 1.0 / radius;
                ray_ellipsoid((origin - center) * inv, dir * inv)
            }
            Shape::Slab { normal, near, far } => {
                let (o, d) = (normal.dot(origin), normal.dot(dir));
                let (t0, t1) = if d.abs() < 1e-12 {
                    // Parallel to the slab: all or nothing.
                    if (near..=far).contains(&o) {
                        (0.0, f32::INFINITY)
                    } else {
                        return None;
                    }
                } else {
                    let (a, b) = ((near - o) / d, (far - o) / d);
                    (a.min(b), a.max(b))
                };
                let t0 = t0.max(0.0);
                (t1 > t0).then_some((t0, t1))
            }
        }
    }
}

/// Constant extinction inside a [`Shape`]. For tests and calibration (exact light depths through
/// it: [`crate::render::light::HomogeneousLights`]).
#[derive(Clone, Copy, Debug)]
pub struct Homogeneous {
    /// Where the medium is.
    pub shape: Shape,
    /// Extinction per unit length.
    pub sigma_t: f32,
    /// March step.
    pub step: f32,
}

impl Medium for Homogeneous {
    type Scratch = Vec<[f32; 2]>;

    fn scratch(&self) -> Self::Scratch {
        Vec::with_capacity(1)
    }

    fn begin_tile(&self, _: &Frustum, _: &mut Self::Scratch) {}

    fn begin_ray(&self, ray: &Ray, scratch: &mut Self::Scratch) {
        scratch.clear();
        if let Some((t0, t1)) = self.shape.interval(ray.origin, ray.dir) {
            scratch.push([t0, t1]);
        }
    }

    fn intervals<'s>(&self, scratch: &'s Self::Scratch) -> &'s [[f32; 2]] {
        scratch
    }

    fn extinction(&self, _: &mut Self::Scratch, _: f32, _: Vec3A) -> f32 {
        self.sigma_t
    }

    fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        match self.shape {
            Shape::Ball { center, radius } => {
                Some((center - Vec3A::splat(radius), center + Vec3A::splat(radius)))
            }
            Shape::Slab { .. } => None,
        }
    }

    fn step(&self) -> f32 {
        self.step
    }

    fn max_extinction(&self) -> f32 {
        self.sigma_t
    }
}
