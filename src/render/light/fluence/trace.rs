//! Light paths from the sun and the sky through the cells ([`Cells`]), and what they leave:
//! the track-length estimate of the fluence `φ = ∫L dω` and the flux `F = ∫L ω dω` of light
//! that has scattered at least once, summed per cell.
//!
//! A photon starts on a square facing its light that covers the cells' bounding sphere (the
//! sun: one direction; the sky: a stratum of directions, [`SkySources`]), its first collision
//! forced (its weight × the probability `1 − e^{−τ}` that the line collides at all, the point
//! sampled in `[0, τ]`: a photon never misses the cloud for nothing), then scatters by the
//! cloud's phase function (sampled exactly, both lobes) with its weight × the albedo at each
//! collision, ending by Russian roulette or when it leaves the box. Each flight after a
//! collision adds `weight × length` to the cells it crosses (φ, RGB) and `luminance × length ×
//! direction` (F) — a sun photon's luminance × length also to a value of its own, the sun's
//! share —, except a sun photon's first flight after its first collision, which adds its
//! luminance × length and luminance × length × direction to values of their own: sunlight
//! scattered once keeps the phase function's two-lobe shape, which one lobe about the mean
//! flux of all orders would blur, and its own flux says how far it still follows the sun.
//! Free flights are analytic cell by cell (piecewise-constant extinction).
//!
//! Determinism: every photon draws from its own generator (`rng::item_rng`, the scene seed,
//! [`Stream::Photons`], the photon index), and the sums are fixed-point integers
//! ([`SCALE`]), whose addition does not depend on order: the grid is bit-identical at any
//! thread count however the photons are split among threads.

use std::f32::consts::PI;

use glam::Vec3A;

use crate::render::surfaces::Surfaces;
use rand::RngExt;
use rand_pcg::Pcg64Mcg;
use rayon::prelude::*;

use crate::render::light::fluence::cells::Cells;
use crate::render::light::phase::{self, basis};
use crate::rng::{Stream, item_rng};

/// Values summed per cell: φ (R, G, B) and F (x, y, z) of the light scattered at least once
/// (but sunlight scattered exactly once), then from [`ONCE`] the fluence and the flux (x, y, z)
/// of sunlight scattered exactly once (luminance), then at [`SUN_MULTIPLE`] the sun's share
/// of the first φ (luminance).
pub(crate) const PER_CELL: usize = 11;

/// Where the once-scattered sunlight's values start in a cell's [`PER_CELL`].
pub(crate) const ONCE: usize = 6;

/// Where a cell's [`PER_CELL`] keeps the fluence (luminance) of sunlight scattered twice or
/// more: the part of φ that the sun's sub-cell detail modulates
/// ([`crate::render::light::fluence::sun_detail`]).
pub(crate) const SUN_MULTIPLE: usize = 10;

/// Fixed-point scale of the sums: a deposit of `weight × length` (weights relative to the
/// largest photon weight, lengths in cells) is stored as that × 2²⁴, truncated. A cell's sum
/// stays below 2⁶³ for over 10⁸ photons of a thousand cells each.
pub(crate) const SCALE: f32 = (1u32 << 24) as f32;

/// Collisions a path follows at most (at albedo 0.95 a path's weight falls below the
/// roulette's threshold after about 30).
const MAX_COLLISIONS: u32 = 512;

/// Russian roulette below this weight (relative to the path's start).
const ROULETTE: f32 = 0.1;

/// Sky strata in `y` (uniform: equal solid angles) and in azimuth.
pub(crate) const SKY_ROWS: usize = 16;
/// See [`SKY_ROWS`].
pub(crate) const SKY_COLUMNS: usize = 32;
/// Sky strata.
pub(crate) const SKY_STRATA: usize = SKY_ROWS * SKY_COLUMNS;

/// Rec. 709 luminance.
#[inline]
pub(crate) fn luminance(c: Vec3A) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// The direction toward the sky at the stratum `s` of [`SKY_STRATA`], at `(u, v) ∈ [0, 1)²`
/// inside it (uniform in solid angle).
pub(crate) fn sky_direction(s: usize, u: f32, v: f32) -> Vec3A {
    let (row, col) = (s / SKY_COLUMNS, s % SKY_COLUMNS);
    let y = -1.0 + 2.0 * (row as f32 + u) / SKY_ROWS as f32;
    let phi = 2.0 * PI * (col as f32 + v) / SKY_COLUMNS as f32;
    let r = (1.0 - y * y).max(0.0).sqrt();
    Vec3A::new(r * phi.cos(), y, r * phi.sin())
}

/// Where the photons come from, in the cells' grid coordinates.
#[derive(Clone, Debug)]
pub(crate) struct Sources {
    /// Centre and radius of a sphere holding the cells.
    pub centre: Vec3A,
    /// See `centre`.
    pub radius: f32,
    /// Unit direction the sunlight travels.
    pub sun_dir: Vec3A,
    /// The sun's irradiance (RGB, normal to it).
    pub sun: Vec3A,
    /// Each sky stratum's radiance (RGB; [`sky_direction`] at its centre).
    pub sky: Vec<Vec3A>,
    /// Photons from the sun.
    pub sun_photons: u32,
    /// Photons from the sky (a multiple of [`SKY_STRATA`]).
    pub sky_photons: u32,
}

impl Sources {
    /// `photons` split between the sun and the sky by their power (each at least an eighth
    /// when it shines at all), the sky's rounded down to whole rounds of its strata.
    pub(crate) fn split(
        centre: Vec3A,
        radius: f32,
        sun_dir: Vec3A,
        sun: Vec3A,
        sky: Vec<Vec3A>,
        photons: u32,
    ) -> Sources {
        let omega = 4.0 * PI / SKY_STRATA as f32;
        let p_sun = luminance(sun).max(0.0);
        let p_sky: f32 = sky.iter().map(|&l| luminance(l).max(0.0) * omega).sum();
        let n = photons as f32;
        let sun_share = if p_sky <= 0.0 {
            1.0
        } else if p_sun <= 0.0 {
            0.0
        } else {
            (p_sun / (p_sun + p_sky)).clamp(0.125, 0.875)
        };
        let sun_photons = (n * sun_share) as u32;
        let sky_photons = (photons - sun_photons) / SKY_STRATA as u32 * SKY_STRATA as u32;
        Sources {
            centre,
            radius,
            sun_dir,
            sun,
            sky,
            sun_photons,
            sky_photons,
        }
    }

    /// All photons.
    pub(crate) fn photons(&self) -> u32 {
        self.sun_photons + self.sky_photons
    }

    /// Starting power of each sun photon and each sky stratum's, per unit fluence in the cells
    /// (`E · (2R)² / n`: the square's area in cells shared among its photons; a cell's volume
    /// and length unit cancel).
    fn weights(&self) -> (Vec3A, Vec<Vec3A>) {
        let area = (2.0 * self.radius).powi(2);
        let sun = if self.sun_photons > 0 {
            self.sun * (area / self.sun_photons as f32)
        } else {
            Vec3A::ZERO
        };
        let per_stratum = (self.sky_photons as usize / SKY_STRATA).max(1) as f32;
        let omega = 4.0 * PI / SKY_STRATA as f32;
        let sky = self
            .sky
            .iter()
            .map(|&l| l * (omega * area / per_stratum))
            .collect();
        (sun, sky)
    }
}

/// The point `k` of the R₂ low-discrepancy sequence in `[0, 1)²` (Roberts 2018): the photons
/// of one light cover its square evenly.
#[inline]
fn r2(k: u32) -> (f32, f32) {
    const A1: f64 = 0.754_877_666_246_692_8;
    const A2: f64 = 0.569_840_290_998_053_3;
    let k = k as f64;
    ((0.5 + A1 * k).fract() as f32, (0.5 + A2 * k).fract() as f32)
}

/// A new travel direction after scattering from `d` by the cloud's two-lobe phase function
/// (`phase::cloud_phase` with asymmetry `g`), sampled exactly.
#[inline]
fn scatter(d: Vec3A, g: f32, rng: &mut Pcg64Mcg) -> Vec3A {
    phase::sample_cloud_phase(d, g, [rng.random(), rng.random(), rng.random()]).0
}

/// Trace every photon of `sources` through `cells` with single-scattering `albedo` and phase
/// asymmetry `g`, seeded by `seed`: per cell, φ (RGB) and F, fixed-point ([`SCALE`]) in units
/// of the returned weight (multiply a sum by it / [`SCALE`] for the fluence).
pub(crate) fn trace(
    cells: &Cells,
    sources: &Sources,
    albedo: f32,
    g: f32,
    seed: u64,
    casters: Option<&Casters<'_>>,
) -> (Vec<i64>, f32) {
    let (sun_w, sky_w) = sources.weights();
    let unit = sky_w
        .iter()
        .fold(sun_w.max_element(), |m, w| m.max(w.max_element()))
        .max(f32::MIN_POSITIVE);
    let (sun_w, sky_w): (Vec3A, Vec<Vec3A>) =
        (sun_w / unit, sky_w.iter().map(|w| *w / unit).collect());
    let n = sources.photons() as usize;
    // Threads each sum into a grid of their own; integers make the total independent of how
    // the photons were shared out.
    let groups = rayon::current_num_threads().clamp(1, 8);
    let len = cells.len() * PER_CELL;
    let sums = (0..groups)
        .into_par_iter()
        .map(|t| {
            let mut acc = vec![0i64; len];
            for i in (t..n).step_by(groups) {
                let mut rng = item_rng(seed, Stream::Photons, i as u64);
                let (origin, dir, w) = emit(sources, &sun_w, &sky_w, i as u32, &mut rng);
                if w.max_element() > 0.0 {
                    let sun = (i as u32) < sources.sun_photons;
                    let photon = Photon {
                        origin,
                        dir,
                        w,
                        sun,
                    };
                    path(cells, photon, albedo, g, casters, &mut rng, &mut acc);
                }
            }
            acc
        })
        .reduce_with(|mut a, b| {
            for (x, y) in a.iter_mut().zip(&b) {
                *x = x.wrapping_add(*y);
            }
            a
        })
        .unwrap_or_else(|| vec![0; len]);
    (sums, unit)
}

/// Photon `i`'s start (grid coordinates, outside the cells' sphere), direction of travel and
/// weight (relative).
#[inline]
fn emit(
    s: &Sources,
    sun_w: &Vec3A,
    sky_w: &[Vec3A],
    i: u32,
    rng: &mut Pcg64Mcg,
) -> (Vec3A, Vec3A, Vec3A) {
    let (dir, w, k) = if i < s.sun_photons {
        (s.sun_dir, *sun_w, i)
    } else {
        let j = (i - s.sun_photons) as usize;
        let stratum = j % SKY_STRATA;
        let (u, v): (f32, f32) = (rng.random(), rng.random());
        (
            -sky_direction(stratum, u, v),
            sky_w[stratum],
            (j / SKY_STRATA) as u32,
        )
    };
    let (a, b) = r2(k);
    let (e1, e2) = basis(dir);
    let r = s.radius;
    let origin =
        s.centre - dir * (1.01 * r) + e1 * ((2.0 * a - 1.0) * r) + e2 * ((2.0 * b - 1.0) * r);
    (origin, dir, w)
}

/// The shadow-casting holdouts the photons' first collisions are checked against, and where
/// the cells lie in the world (cell `(i, j, k)` centred on `origin + (i, j, k)·h`).
pub(crate) struct Casters<'a> {
    /// The holdouts that cast shadows.
    pub surfaces: &'a Surfaces,
    /// World position of node `(0, 0, 0)`.
    pub origin: Vec3A,
    /// Cell side in world units.
    pub h: f32,
}

/// A photon as emitted: start and direction (grid coordinates), weight, from the sun or not.
struct Photon {
    origin: Vec3A,
    dir: Vec3A,
    w: Vec3A,
    sun: bool,
}

/// One photon's path: the forced first collision (dropped where a shadow-casting holdout lies
/// between it and the light: the roof over the cloud darkens its multiple scattering too; the
/// later flights do not see holdouts), then flights that deposit into `acc` (a `sun` photon's
/// first one apart).
#[inline]
fn path(
    cells: &Cells,
    photon: Photon,
    albedo: f32,
    g: f32,
    casters: Option<&Casters<'_>>,
    rng: &mut Pcg64Mcg,
    acc: &mut [i64],
) {
    let Photon {
        origin,
        dir,
        mut w,
        sun,
    } = photon;
    let Some(start) = cells.entry(origin, dir) else {
        return;
    };
    let mut tau = 0.0f32;
    cells.walk(start, dir, |c, l| {
        tau += cells.tau[c] * l;
        None
    });
    if tau <= 1e-6 {
        return;
    }
    let hit = 1.0 - (-tau).exp();
    w *= hit;
    let u: f32 = rng.random();
    let Some(mut pos) = flight(cells, start, dir, -(1.0 - u * hit).ln(), |_, _| {}) else {
        return;
    };
    if let Some(c) = casters {
        let world = c.origin + (pos - Vec3A::splat(0.5)) * c.h;
        if c.surfaces.caster_occludes(world, -dir) {
            return;
        }
    }
    let w0 = w.max_element();
    let mut d = dir;
    for n in 0..MAX_COLLISIONS {
        w *= albedo;
        let m = w.max_element();
        if m < ROULETTE * w0 {
            let survive = m / (ROULETTE * w0);
            if rng.random::<f32>() >= survive {
                return;
            }
            w /= survive;
        }
        d = scatter(d, g, rng);
        let u: f32 = rng.random();
        let (wr, wl) = (w * SCALE, luminance(w) * SCALE);
        let tau = -(1.0 - u).ln();
        let flux = d * wl;
        let next = if sun && n == 0 {
            flight(cells, pos, d, tau, |c: usize, l: f32| {
                let a = &mut acc[c * PER_CELL + ONCE..c * PER_CELL + ONCE + 4];
                a[0] += (wl * l) as i64;
                a[1] += (flux.x * l) as i64;
                a[2] += (flux.y * l) as i64;
                a[3] += (flux.z * l) as i64;
            })
        } else {
            flight(cells, pos, d, tau, |c: usize, l: f32| {
                if sun {
                    acc[c * PER_CELL + SUN_MULTIPLE] += (wl * l) as i64;
                }
                let a = &mut acc[c * PER_CELL..c * PER_CELL + ONCE];
                a[0] += (wr.x * l) as i64;
                a[1] += (wr.y * l) as i64;
                a[2] += (wr.z * l) as i64;
                a[3] += (flux.x * l) as i64;
                a[4] += (flux.y * l) as i64;
                a[5] += (flux.z * l) as i64;
            })
        };
        match next {
            Some(p) => pos = p,
            None => return,
        }
    }
}

/// A free flight from `p` along `d` through optical depth `tau` (or out of the box: `None`),
/// calling `deposit(cell, length)` for each piece of it.
#[inline]
fn flight(
    cells: &Cells,
    p: Vec3A,
    d: Vec3A,
    tau: f32,
    mut deposit: impl FnMut(usize, f32),
) -> Option<Vec3A> {
    let mut left = tau;
    cells.walk(p, d, |c, l| {
        let t = cells.tau[c];
        if t * l > left {
            let stop = left / t;
            deposit(c, stop);
            Some(stop)
        } else {
            left -= t * l;
            deposit(c, l);
            None
        }
    })
}
