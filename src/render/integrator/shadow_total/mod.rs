//! The shadow pass's sky share: the `shadow_total` layer, the shadow catcher a compositor
//! multiplies the plate by when the plate is lit by the sun **and** the sky,
//!
//! ```text
//!               T_sun·E_sun·cos θ_sun + ∫ T(ω)·L_sky(ω)·cos θ_ω dω
//! shadow_total = ─────────────────────────────────────────────────   (per RGB channel)
//!                     E_sun·cos θ_sun + ∫ L_sky(ω)·cos θ_ω dω
//! ```
//!
//! over the hemisphere above the surface point's normal (the ground's `+Y`, a holdout's hit
//! normal facing the camera), `T(ω)` the cloud's transmittance from the point toward `ω`.
//!
//! - The denominator is known without the cloud: `E_sun` is the sunlight the cloud is lit by
//!   (colour × intensity × the atmosphere's tint), the sky's irradiance `∫ L cos θ dω` a
//!   quadrature of the same sky ([`SkyDome::light_radiance`]; an environment map's box-filtered
//!   table) — for the ground's normal exactly, for a holdout's from a table over normals
//!   ([`NORMAL_ROWS`] × [`NORMAL_COLS`], bilinear: irradiance is smooth).
//! - The numerator is the denominator less what the cloud takes: `(1 − T_sun)·E_sun·cos θ_sun`
//!   (the `shadow` layer's own `T_sun`) and `∫ (1 − T(ω))·L cos θ dω`, which is zero outside
//!   the cone of directions toward the cloud's bounding sphere (analytically: `T = 1` there).
//!   Inside it, 64 ([`SIDE`]²) directions stratified in solid angle (uniform in `cos` about the
//!   cone's axis and in azimuth, one random point per stratum from the pixel's own generator,
//!   `Stream::SkyShadow`), each marched through the cloud's extinction sampled once a frame at
//!   the nodes of a lattice of [`CELLS`] cells on its longest side (trilinear, one sample per
//!   cell-long step: the sky's shadow is as soft as the cloud is wide). A point inside the
//!   sphere samples its whole hemisphere.
//! - On the ground plane (seen from above) that integral comes from a table over the plane
//!   ([`GroundTable`]: polar about the point under the cloud, each node with 16 × 16
//!   directions, bilinear between nodes), built once a frame: the sky's shadow on the ground
//!   is smooth, and per ground pixel 64 directions cost 2.5× the frame (measured on a
//!   640×360 `Final` frame) and were noisy. A holdout's point samples its own directions.
//!
//! Holdouts: a direction whose way to the cloud a holdout blocks adds nothing (the plate's
//! own geometry shadows it already), as the sun's does for `shadow`; the sky the holdouts hide
//! is not taken out of the denominator (the plate's own ambient occlusion is in the plate).
//! An empty cloud has nothing to march: `T(ω) = 1`, only the sun's share.

use std::f32::consts::PI;

use glam::{Vec3, Vec3A};
use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use crate::render::camera::{Frustum, Ray};
use crate::render::light::phase::basis;
use crate::render::light::sky_dome::SkyDome;
use crate::render::light::sky_view::table_dir;
use crate::render::medium::Medium;
use crate::render::medium::lattice::{GridShape, trilinear};
use crate::render::settings::RenderSettings;
use crate::render::surfaces::Surfaces;

mod ground_table;
use ground_table::GroundTable;

/// Strata a side of the directions a holdout's point marches toward the cloud: an 8 × 8 grid
/// over the cone, 64 directions.
const SIDE: u32 = 8;

/// Cells on the longest side of the extinction lattice the directions are marched through.
pub(crate) const CELLS: u32 = 32;

/// Optical depth past which a direction is dark (`e^{−7}` ≈ 10⁻³): its march stops.
const DARK_DEPTH: f32 = 7.0;

/// Rows and columns of the holdouts' irradiance table over normals (lat-long, poles on its
/// first and last rows).
const NORMAL_ROWS: usize = 17;
const NORMAL_COLS: usize = 32;

/// Rows (uniform in `y`) and columns (azimuth) of the quadrature of an analytic sky.
const SKY_ROWS: usize = 64;
const SKY_COLS: usize = 128;

/// The frame's constants of the `shadow_total` layer (see the module doc).
#[derive(Clone, Debug)]
pub(crate) struct ShadowTotal {
    /// The sky as it lights the cloud.
    dome: SkyDome,
    /// The sun's irradiance normal to it (RGB) and the unit direction toward it.
    sun: Vec3A,
    to_sun: Vec3A,
    /// The sky's irradiance on a plane facing `+Y` and `−Y` (the ground, seen from above or
    /// below).
    up: Vec3A,
    down: Vec3A,
    /// The sky's irradiance over normals, for the holdouts (`None` without holdouts).
    normals: Option<Vec<Vec3A>>,
    /// The cloud's extinction (`None`: nothing to march).
    cloud: Option<Extinction>,
    /// The sky's share the cloud takes on the ground plane, tabulated (`None`: no ground, or
    /// no cloud).
    ground: Option<GroundTable>,
}

/// The cloud's prefiltered extinction on a coarse lattice, and its bounds.
#[derive(Clone, Debug)]
struct Extinction {
    shape: GridShape,
    inv_h: f32,
    sigma: Vec<f32>,
    /// The box of its nodes with extinction (one node wider).
    lo: Vec3A,
    hi: Vec3A,
    /// Its bounding sphere.
    center: Vec3A,
    radius: f32,
}

impl ShadowTotal {
    /// The constants for `settings`, whose sun is lit at `sun` (colour × intensity × tint), the
    /// cloud's extinction sampled from `medium`.
    pub(crate) fn new<M: Medium>(settings: &RenderSettings, sun: Vec3A, medium: &M) -> ShadowTotal {
        let dome = SkyDome::new(&settings.sky, &settings.sun);
        let quadrature = sky_quadrature(&dome);
        let irradiance = |n: Vec3A| {
            quadrature
                .iter()
                .fold(Vec3A::ZERO, |e, (d, l)| e + *l * n.dot(*d).max(0.0))
        };
        let normals = settings
            .surfaces
            .as_ref()
            .is_some_and(|s| s.has_holdouts())
            .then(|| {
                (0..NORMAL_ROWS * NORMAL_COLS)
                    .map(|k| irradiance(normal_dir(k / NORMAL_COLS, k % NORMAL_COLS)))
                    .collect()
            });
        let mut total = ShadowTotal {
            up: irradiance(Vec3A::Y),
            down: irradiance(Vec3A::NEG_Y),
            normals,
            sun,
            to_sun: -Vec3A::from(settings.sun.travel_dir()),
            cloud: Extinction::sample(medium),
            dome,
            ground: None,
        };
        let plane = settings
            .surfaces
            .as_ref()
            .and_then(|s| s.ground().zip(Some(s)));
        if let (Some(cloud), Some((g, surfaces))) = (&total.cloud, plane) {
            total.ground = Some(GroundTable::build(
                &total,
                cloud,
                surfaces,
                g.height,
                settings.seed,
            ));
        }
        total
    }

    /// The layer's value at surface point `p` of unit normal `n` (facing the camera), where
    /// the `shadow` pass found the sun's transmittance `sun_t` (`sun_seen`: no holdout hides
    /// the sun from `p`). The sky's share from the ground's table where `p` is on the ground
    /// seen from above, else from 64 ([`SIDE`]²) directions with random numbers from `rng`
    /// (the pixel's).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn value(
        &self,
        surfaces: &Surfaces,
        p: Vec3A,
        n: Vec3A,
        on_ground: bool,
        sun_t: f32,
        sun_seen: bool,
        rng: &mut Pcg64Mcg,
    ) -> Vec3A {
        let sun = if sun_seen {
            self.sun * n.dot(self.to_sun).max(0.0)
        } else {
            Vec3A::ZERO
        };
        let sky = if n == Vec3A::Y {
            self.up
        } else if n == Vec3A::NEG_Y {
            self.down
        } else {
            self.irradiance(n)
        };
        let mut taken = sun * (1.0 - sun_t);
        match (&self.ground, &self.cloud) {
            (Some(table), _) if on_ground && n == Vec3A::Y => {
                taken += table.lookup(p);
            }
            (_, Some(cloud)) => taken += self.sky_taken(cloud, surfaces, p, n, SIDE, rng),
            _ => {}
        }
        let lit = sun + sky;
        let ratio = |t: f32, l: f32| {
            if l > 0.0 {
                (1.0 - t / l).clamp(0.0, 1.0)
            } else {
                1.0
            }
        };
        Vec3A::new(
            ratio(taken.x, lit.x),
            ratio(taken.y, lit.y),
            ratio(taken.z, lit.z),
        )
    }

    /// `∫ (1 − T(ω)) L(ω) cos θ dω` over the cone toward the cloud (the module doc).
    fn sky_taken(
        &self,
        cloud: &Extinction,
        surfaces: &Surfaces,
        p: Vec3A,
        n: Vec3A,
        side: u32,
        rng: &mut Pcg64Mcg,
    ) -> Vec3A {
        let to_cloud = cloud.center - p;
        let dist = to_cloud.length();
        // The cone about `axis` out to `cos_max`: the sphere's, or the hemisphere inside it.
        let (axis, cos_max) = if dist > cloud.radius * 1.0001 {
            let s = cloud.radius / dist;
            (to_cloud / dist, (1.0 - s * s).max(0.0).sqrt())
        } else {
            (n, 0.0)
        };
        let (u, v) = basis(axis);
        let omega = 2.0 * PI * (1.0 - cos_max) / (side * side) as f32;
        // Off the surface, so that a holdout's ray does not find its own triangle.
        let origin = p + n * (1e-4 * (1.0 + p.abs().max_element()));
        let holdouts = surfaces.has_holdouts();
        let mut sum = Vec3A::ZERO;
        for k in 0..side * side {
            let (a, b) = ((k % side) as f32, (k / side) as f32);
            let (x1, x2, x3): (f32, f32, f32) = (rng.random(), rng.random(), rng.random());
            let c = 1.0 - (a + x1) / side as f32 * (1.0 - cos_max);
            let s = (1.0 - c * c).max(0.0).sqrt();
            let phi = 2.0 * PI * (b + x2) / side as f32;
            let dir = (u * phi.cos() + v * phi.sin()) * s + axis * c;
            let cos_n = dir.dot(n);
            if cos_n <= 0.0 {
                continue;
            }
            let tau = cloud.depth(origin, dir, x3);
            if tau <= 0.0 || holdouts && surfaces.any_holdout_on(origin, dir) {
                continue;
            }
            let l = Vec3A::from(self.dome.light_radiance(Vec3::from(dir)));
            sum += l * ((1.0 - (-tau).exp()) * cos_n);
        }
        sum * omega
    }

    /// The sky's irradiance on a plane of unit normal `n` (bilinear in the normals' table).
    fn irradiance(&self, n: Vec3A) -> Vec3A {
        let Some(table) = &self.normals else {
            return self.up;
        };
        let theta = n.y.clamp(-1.0, 1.0).acos();
        let phi = n.z.atan2(n.x).rem_euclid(2.0 * PI);
        let fy = theta / PI * (NORMAL_ROWS - 1) as f32;
        let fx = phi / (2.0 * PI) * NORMAL_COLS as f32;
        let (y0, x0) = (
            (fy as usize).min(NORMAL_ROWS - 2),
            fx as usize % NORMAL_COLS,
        );
        let (wy, wx) = (fy - y0 as f32, fx - fx.floor());
        let x1 = (x0 + 1) % NORMAL_COLS;
        let t = |y: usize, x: usize| table[y * NORMAL_COLS + x];
        (t(y0, x0) * (1.0 - wx) + t(y0, x1) * wx) * (1.0 - wy)
            + (t(y0 + 1, x0) * (1.0 - wx) + t(y0 + 1, x1) * wx) * wy
    }
}

/// Normal of row `row`, column `col` of the holdouts' table: `θ` from the pole `+Y` (row 0) to
/// `−Y`, `φ` from `+X` toward `+Z`.
fn normal_dir(row: usize, col: usize) -> Vec3A {
    let theta = PI * row as f32 / (NORMAL_ROWS - 1) as f32;
    let phi = 2.0 * PI * col as f32 / NORMAL_COLS as f32;
    let (s, c) = theta.sin_cos();
    Vec3A::new(s * phi.cos(), c, s * phi.sin())
}

/// The sky as `(direction, radiance × solid angle)` over the sphere, for its irradiance: an
/// environment map's box-filtered table (every texel counted), an analytic sky at the centres
/// of a [`SKY_ROWS`] × [`SKY_COLS`] grid of equal solid angles.
fn sky_quadrature(dome: &SkyDome) -> Vec<(Vec3A, Vec3A)> {
    use crate::render::light::envmap::{TABLE_COLS, TABLE_ROWS};
    if let Some((integrals, intensity)) = dome.environment() {
        let omega = 4.0 * PI / (TABLE_ROWS * TABLE_COLS) as f32;
        return integrals
            .table
            .iter()
            .enumerate()
            .map(|(k, l)| {
                let d = table_dir(k / TABLE_COLS, k % TABLE_COLS, TABLE_ROWS, TABLE_COLS);
                (d, Vec3A::from(*l) * (intensity * omega))
            })
            .collect();
    }
    let omega = 4.0 * PI / (SKY_ROWS * SKY_COLS) as f32;
    (0..SKY_ROWS * SKY_COLS)
        .map(|k| {
            let d = table_dir(k / SKY_COLS, k % SKY_COLS, SKY_ROWS, SKY_COLS);
            (d, Vec3A::from(dome.light_radiance(Vec3::from(d))) * omega)
        })
        .collect()
}

impl Extinction {
    /// `medium`'s extinction at the nodes of a lattice of [`CELLS`] cells on the longest side
    /// of its bounds (point samples, only inside its intervals along each row); `None` when it
    /// is empty.
    fn sample<M: Medium>(medium: &M) -> Option<Extinction> {
        let (lo, hi) = medium.bounds()?;
        let shape = GridShape::covering(lo, hi, CELLS);
        let [nx, ny, nz] = shape.dims;
        let mut sigma = vec![0.0f32; shape.len()];
        let h = shape.h;
        sigma.par_chunks_mut(nx * ny).enumerate().for_each_init(
            || {
                let mut s = medium.scratch();
                medium.begin_tile(&Frustum::EVERYTHING, &mut s);
                s
            },
            |scratch, (k, slab)| {
                for (j, row) in slab.chunks_mut(nx).enumerate() {
                    let ray = Ray {
                        origin: shape.node(0, j, k),
                        dir: Vec3A::X,
                    };
                    medium.begin_ray(&ray, scratch);
                    for n in 0..medium.intervals(scratch).len() {
                        let [a, b] = medium.intervals(scratch)[n];
                        let first = (a.max(0.0) / h).ceil() as usize;
                        let last = ((b / h).floor().max(0.0) as usize).min(nx - 1);
                        for i in first..=last {
                            let t = i as f32 * h;
                            row[i] = medium.extinction(scratch, t, ray.at(t));
                        }
                    }
                }
            },
        );
        // The box of the nodes with extinction, one node wider: the directions' cone and the
        // marches' extent (the bounds' box is loose around a cloud).
        let (mut first, mut last) = ([usize::MAX; 3], [0usize; 3]);
        for (n, _) in sigma.iter().enumerate().filter(|(_, s)| **s > 0.0) {
            let ijk = [n % nx, (n / nx) % ny, n / (nx * ny)];
            for a in 0..3 {
                first[a] = first[a].min(ijk[a]);
                last[a] = last[a].max(ijk[a]);
            }
        }
        if first[0] == usize::MAX {
            return None;
        }
        let node = |ijk: [usize; 3]| shape.node(ijk[0], ijk[1], ijk[2]);
        let lo = node(first.map(|i| i.saturating_sub(1)));
        let hi = node([
            (last[0] + 1).min(nx - 1),
            (last[1] + 1).min(ny - 1),
            (last[2] + 1).min(nz - 1),
        ]);
        Some(Extinction {
            inv_h: 1.0 / h,
            shape,
            sigma,
            lo,
            hi,
            center: 0.5 * (lo + hi),
            radius: 0.5 * (hi - lo).length() * (1.0 + 1e-5),
        })
    }

    /// Optical depth from `origin` along unit `dir` through the lattice's box, one sample per
    /// cell-long step at `jitter` inside it; stops once dark.
    #[inline]
    fn depth(&self, origin: Vec3A, dir: Vec3A, jitter: f32) -> f32 {
        let inv = dir.recip();
        let (t0, t1) = ((self.lo - origin) * inv, (self.hi - origin) * inv);
        let near = t0.min(t1).max_element().max(0.0);
        let far = t0.max(t1).min_element();
        if !(far > near) {
            return 0.0;
        }
        let h = self.shape.h;
        let mut tau = 0.0f32;
        let mut s = near;
        while s < far {
            let len = h.min(far - s);
            let mut out = [0.0f32; 1];
            trilinear::<1, f32>(
                &self.shape,
                self.inv_h,
                &self.sigma,
                origin + dir * (s + jitter * len),
                &mut out,
            );
            tau += out[0] * len;
            if tau > DARK_DEPTH {
                break;
            }
            s += len;
        }
        tau
    }
}
