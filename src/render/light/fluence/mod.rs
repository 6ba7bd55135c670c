//! The physically based multiple-scattering estimate: a fluence grid filled once per frame by
//! tracing light paths from the sun and the sky through the cloud, looked up by the march.
//!
//! In: the light grid's coarse lattice and its extinction (the medium sampled once a frame,
//! [`crate::render::light::grid::LightGrid`]) and [`FluenceSettings`]. Out: [`FluenceGrid`],
//! the fluence `φ` (RGB) and flux `F` of light scattered at least once (and apart from them the
//! fluence and flux of sunlight scattered exactly once), per node, smoothed,
//! trilinear anywhere ([`FluenceGrid::lookup`]); the shader turns them into the radiance the
//! orders ≥ 2 scatter toward the eye ([`crate::render::light::shading::Shading::fluence_in`]).
//!
//! - Jensen & Christensen (1998), "Efficient simulation of light transport in scenes with
//!   participating media using photon maps"; Elek et al. (2012), "Interactive cloud rendering
//!   using temporally coherent photon mapping": photons from the lights, gathered on a grid.
//! - Zhou et al. (2008), "Compensated ray marching": the low-frequency multiple scattering on a
//!   coarse grid, the detail (single scattering, the fine density) in the march.
//! - The track-length estimator (Spanier 1966): each flight adds its length to the cells it
//!   crosses: every photon informs every cell on its way, not only where it collides.
//!
//! How the grid's sizes were chosen: docs/MEASUREMENTS.md, "Multiple scattering: the fluence
//! grid".

mod cells;
mod trace;

use glam::Vec3A;
use rayon::prelude::*;

use crate::render::fast_exp::exp_neg;
use crate::render::light::MultipleLight;
use crate::render::light::sky_dome::SkyDome;
use crate::render::light::sun_depth::SunGrid;
use crate::render::medium::lattice::{GridShape, trilinear};
use crate::render::settings::RenderSettings;

use crate::render::surfaces::Surfaces;
use cells::Cells;
pub(crate) use trace::luminance;
use trace::{Casters, ONCE, PER_CELL, SCALE, SKY_STRATA, SUN_MULTIPLE, Sources, sky_direction};

/// Most cells on the fluence grid's longest side: the light grid's coarse (sky) lattice is
/// coarsened by whole factors until it fits.
pub(crate) const MAX_FLUENCE_CELLS: usize = 40;

/// Passes of the `[1 2 1] / 4` filter along each axis over the summed grid (the photons'
/// noise).
pub(crate) const SMOOTHING_PASSES: usize = 1;

/// Values stored a node: the [`PER_CELL`] sums, then the mean of the sun's sub-cell detail
/// over the node's cell ([`DETAIL`]), each times the node's lookup weight
/// ([`lookup_weights`]), then that weight ([`WEIGHT`]).
const STORED: usize = PER_CELL + 2;
/// Where a node keeps the mean of [`sun_detail`] over its cell.
const DETAIL: usize = PER_CELL;
/// Where a node keeps its lookup weight.
const WEIGHT: usize = PER_CELL + 1;

/// The floor `ε` of [`sun_detail`].
pub(crate) const SUN_DETAIL_FLOOR: f32 = 0.05;
/// The power `p` of [`sun_detail`].
pub(crate) const SUN_DETAIL_POWER: f32 = 0.3;

/// The sun's sub-cell detail at a point whose sun transmittance is `t_sun = e^{−τ}`:
/// `(ε + e^{−τ})^p` ([`SUN_DETAIL_FLOOR`], [`SUN_DETAIL_POWER`]).
///
/// Why: the grid's cells (a few mean free paths) hold the fluence's mean over each cell, but
/// sunlight scattered twice or more is brighter than that mean where the cell is sunlit (the
/// bulges facing the sun, thin parts) and darker where another part of the cloud shades it
/// (the creases a head or a ridge shadows): it follows the sun's transmittance, loosely (the
/// orders ≥ 2 have spread over a few mean free paths). The march knows the transmittance at
/// the light grid's resolution, finer than the cells; so the sun's part of the fluence is
/// multiplied by this detail at the point over its mean over the cell
/// ([`crate::render::light::shading::Shading::fluence_in`]). `ε` and `p` say how loosely:
/// measured against Mitsuba's full transport on the README's three shots and against the
/// path-traced reference on a cloud none of it was fitted on (docs/MEASUREMENTS.md, "The
/// sun's detail in the cells").
#[inline]
pub(crate) fn sun_detail(t_sun: f32) -> f32 {
    (SUN_DETAIL_FLOOR + t_sun).powf(SUN_DETAIL_POWER)
}

/// What a frame's fluence grid is made of besides the medium.
#[derive(Clone, Debug)]
pub(crate) struct FluenceSettings {
    /// Unit direction the sunlight travels.
    pub sun_dir: Vec3A,
    /// The sun's irradiance (colour × intensity × the atmosphere's tint).
    pub sun: Vec3A,
    /// Radiance of each sky stratum (`trace::sky_direction` at its centre), the ground below
    /// the horizon included.
    pub sky: Vec<Vec3A>,
    /// Single-scattering albedo.
    pub albedo: f32,
    /// Phase asymmetry.
    pub g: f32,
    /// Photons per frame.
    pub photons: u32,
    /// The scene seed.
    pub seed: u64,
    /// `cloud.ms_contrast` (0: the physical estimate untouched).
    pub contrast: f32,
}

impl FluenceSettings {
    /// The estimate `settings` ask for: `None` without `cloud.multiple_scattering` or when the
    /// quality uses the octaves (`quality.ms_photons` 0).
    pub(crate) fn new(settings: &RenderSettings) -> Option<FluenceSettings> {
        if !settings.cloud.multiple_scattering || settings.quality.ms_photons == 0 {
            return None;
        }
        let sun = &settings.sun;
        let dome = SkyDome::new(&settings.sky, sun);
        let tint = SkyDome::sun_tint(&settings.sky, sun);
        let sky = (0..SKY_STRATA)
            .map(|s| Vec3A::from(dome.light_radiance(sky_direction(s, 0.5, 0.5).into())))
            .collect();
        Some(FluenceSettings {
            sun_dir: Vec3A::from(sun.travel_dir()),
            sun: Vec3A::from(sun.color * sun.intensity * tint),
            sky,
            albedo: settings.cloud.albedo.clamp(0.0, 1.0),
            g: settings.cloud.phase_g.clamp(-0.99, 0.99),
            photons: settings.quality.ms_photons,
            seed: settings.seed,
            contrast: settings.cloud.ms_contrast,
        })
    }
}

/// Fluence `φ` (RGB) and flux `F` of light scattered at least once (sunlight scattered exactly
/// once apart, its fluence and flux), on the nodes of a regular grid (node-major, [`STORED`]
/// values a node: each weighted by the node's extinction, [`lookup_weights`]).
#[derive(Clone, Debug)]
pub(crate) struct FluenceGrid {
    shape: GridShape,
    inv_h: f32,
    values: Vec<f32>,
}

impl FluenceGrid {
    /// The fluence grid of the medium whose extinction `sigma` is given on the nodes of
    /// `shape` (the light grid's coarse lattice), lit as `s` says.
    /// Photons whose first collision a shadow-casting holdout of `casters` hides from the
    /// light are dropped. `sun` gives the sun's depths for each cell's mean [`sun_detail`].
    pub(crate) fn build(
        shape: &GridShape,
        sigma: &[f32],
        s: &FluenceSettings,
        casters: Option<&Surfaces>,
        sun: &SunGrid,
    ) -> FluenceGrid {
        let detail = coarsen(shape, &detail_at_nodes(shape, sun), MAX_FLUENCE_CELLS).1;
        let (shape, sigma) = coarsen(shape, sigma, MAX_FLUENCE_CELLS);
        let cells = Cells::new(&shape, &sigma);
        let d = cells.dims;
        let half = Vec3A::new(d[0] as f32, d[1] as f32, d[2] as f32) * 0.5;
        let sources = Sources::split(
            half,
            half.length(),
            s.sun_dir,
            s.sun,
            s.sky.clone(),
            s.photons,
        );
        let casters = casters
            .filter(|c| c.casts_shadows())
            .map(|surfaces| Casters {
                surfaces,
                origin: shape.origin,
                h: shape.h,
            });
        let (sums, unit) = trace::trace(&cells, &sources, s.albedo, s.g, s.seed, casters.as_ref());
        let k = unit / SCALE;
        let weights = lookup_weights(&sigma);
        let mut values = vec![0.0f32; shape.len() * STORED];
        for (((out, sum), &w), &d) in values
            .chunks_exact_mut(STORED)
            .zip(sums.chunks_exact(PER_CELL))
            .zip(&weights)
            .zip(&detail)
        {
            for (o, &v) in out.iter_mut().zip(sum) {
                *o = v as f32 * k * w;
            }
            out[DETAIL] = d * w;
            out[WEIGHT] = w;
        }
        for _ in 0..SMOOTHING_PASSES {
            smooth(&shape, &mut values);
        }
        if s.contrast != 0.0 {
            contrast(&sigma, &mut values, s.contrast);
        }
        FluenceGrid {
            inv_h: 1.0 / shape.h,
            shape,
            values,
        }
    }

    /// The fluences and fluxes at `x`: trilinear, each node weighed by its [`lookup_weights`]
    /// (clamped to the grid).
    #[inline]
    pub(crate) fn lookup(&self, x: Vec3A) -> MultipleLight {
        let mut v = [0.0f32; STORED];
        trilinear::<STORED, f32>(&self.shape, self.inv_h, &self.values, x, &mut v);
        // The weights are at least 1: no division by zero.
        let k = 1.0 / v[WEIGHT];
        for a in &mut v[..WEIGHT] {
            *a *= k;
        }
        MultipleLight {
            fluence: Vec3A::new(v[0], v[1], v[2]),
            flux: Vec3A::new(v[3], v[4], v[5]),
            sun_once: v[ONCE],
            sun_once_flux: Vec3A::new(v[ONCE + 1], v[ONCE + 2], v[ONCE + 3]),
            sun_multiple: v[SUN_MULTIPLE],
            sun_detail_mean: v[DETAIL],
        }
    }
}

/// Each node's weight in the lookup's interpolation: `1 + σ/σ_max` (`σ` its extinction,
/// `σ_max` the grid's largest; all ones for an empty grid).
///
/// Why: a point of the cloud's thin surface layer lies between nodes inside the cloud and
/// nodes outside it, whose fluence is the light leaving the cloud (and the cell-averaged
/// fluence of a cell the surface only grazes); the scattering there needs the fluence inside
/// the cloud. The extinction-weighted mean (`Σ wσφ / Σ wσ`, what a cell's scattering integral
/// needs) leans fully on the dense nodes and over-brightens the shadowed faces of a thick cloud
/// (their interior's fluence is higher than at their surface); halfway between it and plain
/// trilinear came out best against Mitsuba's full transport on the README's three shots
/// (docs/MEASUREMENTS.md, "Multiple scattering: the fluence grid").
fn lookup_weights(sigma: &[f32]) -> Vec<f32> {
    let max = sigma.iter().fold(0.0f32, |a, &b| a.max(b));
    let inv = if max > 0.0 { 1.0 / max } else { 0.0 };
    sigma.iter().map(|&s| 1.0 + s.max(0.0) * inv).collect()
}

/// [`sun_detail`] at each node of `shape` (world positions), from the sun's depths.
fn detail_at_nodes(shape: &GridShape, sun: &SunGrid) -> Vec<f32> {
    let [nx, ny, _] = shape.dims;
    let mut out = vec![0.0f32; shape.len()];
    out.par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(k, slab)| {
            for j in 0..ny {
                for i in 0..nx {
                    slab[i + nx * j] = sun_detail(exp_neg(sun.lookup(shape.node(i, j, k))));
                }
            }
        });
    out
}

/// `shape` and its node values `sigma` coarsened by the smallest whole factor that brings the
/// longest side to at most `max` nodes: each coarse node the mean of the block of nodes it
/// stands for (and centred on it).
fn coarsen(shape: &GridShape, sigma: &[f32], max: usize) -> (GridShape, Vec<f32>) {
    let f = shape
        .dims
        .iter()
        .max()
        .copied()
        .unwrap_or(1)
        .div_ceil(max.max(2));
    if f <= 1 {
        return (shape.clone(), sigma.to_vec());
    }
    let [nx, ny, nz] = shape.dims;
    let dims = [nx.div_ceil(f), ny.div_ceil(f), nz.div_ceil(f)];
    let coarse = GridShape {
        origin: shape.origin + Vec3A::splat(0.5 * (f - 1) as f32 * shape.h),
        h: f as f32 * shape.h,
        dims,
    };
    let mut out = vec![0.0f32; coarse.len()];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let mut sum = 0.0;
                for c in 0..f {
                    let z = (k * f + c).min(nz - 1);
                    for b in 0..f {
                        let y = (j * f + b).min(ny - 1);
                        let row = nx * (y + ny * z);
                        for a in 0..f {
                            sum += sigma[row + (i * f + a).min(nx - 1)];
                        }
                    }
                }
                out[i + dims[0] * (j + dims[1] * k)] = sum / (f * f * f) as f32;
            }
        }
    }
    (coarse, out)
}

/// One pass of the `[1 2 1] / 4` filter along x, y and z over every value of the grid (edges
/// clamped): the weighted sums and their weights alike, so the lookup's ratio is a weighted
/// smoothing of the fluence.
fn smooth(shape: &GridShape, values: &mut [f32]) {
    let [nx, ny, nz] = shape.dims;
    let stride = [1, nx, nx * ny];
    let n = [nx, ny, nz];
    let mut tmp = values.to_vec();
    for axis in 0..3 {
        let s = stride[axis];
        for node in 0..shape.len() {
            let c = (node / s) % n[axis];
            let lo = if c > 0 { node - s } else { node };
            let hi = if c + 1 < n[axis] { node + s } else { node };
            for v in 0..STORED {
                tmp[node * STORED + v] = 0.25
                    * (values[lo * STORED + v]
                        + 2.0 * values[node * STORED + v]
                        + values[hi * STORED + v]);
            }
        }
        values.copy_from_slice(&tmp);
    }
}

/// The artistic contrast (`cloud.ms_contrast` = `c`): each node's fluence and flux times
/// `(φ/φ̄)^c`, `φ` all the scattered light's fluence (luminance), `φ̄` its extinction-weighted
/// mean over the cloud: the mean stays,
/// bright parts (sunlit tops) brighten and dim ones (bases, the core) darken for `c > 0`,
/// the light evens out for `c < 0` (Wrenninge 2015 keeps such a dial apart from the physics).
fn contrast(sigma: &[f32], values: &mut [f32], c: f32) {
    // The stored values are weighted: divide by the node's weight (the last value).
    let lum =
        |v: &[f32]| (luminance(Vec3A::new(v[0], v[1], v[2])) + v[ONCE]) / v[WEIGHT].max(1e-30);
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (s, v) in sigma.iter().zip(values.chunks(STORED)) {
        num += (*s * lum(v)) as f64;
        den += *s as f64;
    }
    if !(den > 0.0 && num > 0.0) {
        return;
    }
    let mean = (num / den) as f32;
    for v in values.chunks_mut(STORED) {
        let l = lum(v);
        if l > 0.0 {
            let k = (l / mean).powf(c);
            for x in v[..PER_CELL].iter_mut() {
                *x *= k;
            }
        }
    }
}

#[cfg(test)]
mod tests;
