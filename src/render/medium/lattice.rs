//! Regular lattices over a medium and the rays that sample it: the one place where a medium's
//! extinction is sampled onto nodes, for the light grid ([`crate::render::light::grid`], world-aligned
//! rows; [`crate::render::light::sun_depth`]) and the volume export (`crate::export::grid`, voxel columns).
//!
//! In: a [`Medium`] and a bundle of parallel columns. Out: per column, the medium prepared for
//! that ray ([`Medium::begin_ray`]: its intervals known), after one [`Medium::begin_tile`] for
//! the whole bundle with a conservative frustum ([`Columns::frustum`]), so a medium culls its
//! pieces once per bundle as it does once per image tile. The caller evaluates the nodes it
//! needs inside the intervals; sampling along columns visits only where the medium can be.
//!
//! Also the node grid [`GridShape`] and its [`trilinear`] lookup.

use std::ops::Range;

use glam::{DVec3, Vec3A};

use crate::render::camera::{Frustum, Ray};
use crate::render::medium::Medium;

/// Regular node grid: node `(i, j, k)` sits at `origin + h·(i, j, k)`, flat index
/// `i + nx·(j + ny·k)`.
#[derive(Clone, Debug, Default)]
pub(crate) struct GridShape {
    /// Position of node (0, 0, 0).
    pub origin: Vec3A,
    /// Node spacing (cubic cells).
    pub h: f32,
    /// Node counts along x, y, z (each ≥ 2).
    pub dims: [usize; 3],
}

impl GridShape {
    /// A grid covering `[lo, hi]` padded by one cell on every side, with about `res` cells on
    /// the longest side (`res ≥ 2`).
    pub(crate) fn covering(lo: Vec3A, hi: Vec3A, res: u32) -> GridShape {
        let size = (hi - lo).max(Vec3A::splat(1e-6));
        let h = size.max_element() / res.max(2) as f32;
        let origin = lo - Vec3A::splat(h);
        let n = |s: f32| (s / h).ceil() as usize + 3;
        GridShape {
            origin,
            h,
            dims: [n(size.x), n(size.y), n(size.z)],
        }
    }

    /// Number of nodes.
    pub(crate) fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// World position of node `(i, j, k)`.
    pub(crate) fn node(&self, i: usize, j: usize, k: usize) -> Vec3A {
        self.origin + Vec3A::new(i as f32, j as f32, k as f32) * self.h
    }
}

/// Trilinear interpolation at `x` of `C` values per node of `shape` (`inv_h = 1 / shape.h`),
/// accumulated into `out`. The values may be stored narrower than `f32` (e.g. quantized `u16`,
/// which the caller scales).
#[inline]
pub(crate) fn trilinear<const C: usize, T: Copy + Into<f32>>(
    shape: &GridShape,
    inv_h: f32,
    v: &[T],
    x: Vec3A,
    out: &mut [f32; C],
) {
    let [nx, ny, nz] = shape.dims;
    let g = ((x - shape.origin) * inv_h).clamp(
        Vec3A::ZERO,
        Vec3A::new(nx as f32 - 1.001, ny as f32 - 1.001, nz as f32 - 1.001),
    );
    let f = g.floor();
    let w = g - f;
    let i00 = f.x as usize + nx * (f.y as usize + ny * f.z as usize);
    let (sy, sz) = (nx, nx * ny);
    let corners = [
        (i00, (1.0 - w.x) * (1.0 - w.y) * (1.0 - w.z)),
        (i00 + 1, w.x * (1.0 - w.y) * (1.0 - w.z)),
        (i00 + sy, (1.0 - w.x) * w.y * (1.0 - w.z)),
        (i00 + sy + 1, w.x * w.y * (1.0 - w.z)),
        (i00 + sz, (1.0 - w.x) * (1.0 - w.y) * w.z),
        (i00 + sz + 1, w.x * (1.0 - w.y) * w.z),
        (i00 + sy + sz, (1.0 - w.x) * w.y * w.z),
        (i00 + sy + sz + 1, w.x * w.y * w.z),
    ];
    for (node, wc) in corners {
        for (a, &t) in out.iter_mut().zip(&v[node * C..(node + 1) * C]) {
            *a += wc * t.into();
        }
    }
}

/// A family of parallel columns: column `(a, b)` starts at `start + h·(a·u + b·v)` and runs
/// `length` along `dir` (`u`, `v`, `dir` orthonormal). In f64 so that the nearly parallel side
/// planes of [`Columns::frustum`] are accurate.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Columns {
    /// Start of column `(0, 0)`.
    pub start: DVec3,
    /// Unit step between columns `a` and `a + 1` (over `h`).
    pub u: DVec3,
    /// Unit step between columns `b` and `b + 1` (over `h`).
    pub v: DVec3,
    /// Unit direction of the columns.
    pub dir: DVec3,
    /// Column spacing.
    pub h: f64,
    /// Length of every column.
    pub length: f64,
}

impl Columns {
    /// A conservative frustum around the columns `a × b`, padded by half a spacing so that
    /// rounding cannot cull a piece at an edge: a pyramid whose sides pass through the padded
    /// rectangle's edges at the columns' start, with its apex `64·length` behind, so it is
    /// almost a prism (1.6 % wider at the far end) and culls nearly as tightly as the bundle.
    pub(crate) fn frustum(&self, a: Range<usize>, b: Range<usize>) -> Frustum {
        let (a0, a1) = (a.start as f64 - 0.5, a.end as f64 - 0.5);
        let (b0, b1) = (b.start as f64 - 0.5, b.end as f64 - 0.5);
        let at = |a: f64, b: f64| self.start + (self.u * a + self.v * b) * self.h;
        let apex = at(0.5 * (a0 + a1), 0.5 * (b0 + b1)) - self.dir * (64.0 * self.length);
        let c = [at(a0, b0), at(a1, b0), at(a1, b1), at(a0, b1)].map(|p| p - apex);
        let mut planes = [Vec3A::ZERO; 4];
        for (e, plane) in planes.iter_mut().enumerate() {
            let n = c[e].cross(c[(e + 1) % 4]).normalize_or_zero();
            // Inward: the pyramid opens along `dir`, so its inward normals lean toward it.
            let n = if n.dot(self.dir) < 0.0 { -n } else { n };
            *plane = n.as_vec3a();
        }
        Frustum {
            apex: apex.as_vec3a(),
            forward: self.dir.as_vec3a(),
            planes,
        }
    }
}

/// Sample `medium` through the bundle `a × b` of `columns`: one [`Medium::begin_tile`] with
/// the bundle's frustum, then per column its ray `ray(a, b)` (the caller's, so the caller owns
/// its rounding; it must lie inside the bundle) through [`Medium::begin_ray`], then
/// `visit(scratch, a, b, ray)`, which reads the intervals and evaluates what it needs.
pub(crate) fn sample_bundle<M: Medium>(
    medium: &M,
    scratch: &mut M::Scratch,
    columns: &Columns,
    a: Range<usize>,
    b: Range<usize>,
    ray: impl Fn(usize, usize) -> Ray,
    mut visit: impl FnMut(&mut M::Scratch, usize, usize, &Ray),
) {
    medium.begin_tile(&columns.frustum(a.clone(), b.clone()), scratch);
    for ib in b {
        for ia in a.clone() {
            let r = ray(ia, ib);
            medium.begin_ray(&r, scratch);
            visit(scratch, ia, ib, &r);
        }
    }
}
