//! Optical depth toward each sky cell ([`crate::render::light::sky_cells`]) on a world grid
//! [`SKY_SPACING`] times as coarse as the light grid's, for [`crate::render::LightGrid`].
//!
//! Each sky depth is built by one sweep through the grid along the light's dominant axis: a node's
//! depth is the depth of the point one slice back toward the light (bilinear in that slice: the
//! fractional offset is the same for every node) plus the trapezoid of `σ_t` over the step.
//! (The 26 cells' directions are lattice directions: the offset is whole, and the sweep is exact
//! along the lattice's lines.) Each depth is stored as its cube root ([`quantize_depth`]), so
//! that the lookup's trilinear interpolation does not make the cloud's lit side too dark.
//!
//! In: the light grid's world lattice and the sun grid's extinction samples (the medium is
//! sampled once a frame, for the sun). Out: [`SKY_DIRECTIONS`] quantized depths per coarse
//! node (`sky_depths`).

use glam::Vec3A;
use rayon::prelude::*;

use crate::render::light::sky_cells::{SKY_DIRECTIONS, directions};
use crate::render::light::sun_depth::SunGrid;
use crate::render::medium::lattice::GridShape;
use crate::render::surfaces::Surfaces;

/// The sky build's working buffers: the coarse grid's extinction and one depth buffer per sweep
/// running at once.
#[derive(Clone, Debug, Default)]
pub(crate) struct SkyWork {
    pub(crate) coarse: Vec<f32>,
    pub(crate) sweeps: Vec<Sweep>,
}

/// One sweep's buffers: its depths, already quantized ([`quantize_depth`]), and the `f32` depths
/// of the slice it last swept and of the one it sweeps (all the recurrence reads).
#[derive(Clone, Debug, Default)]
pub(crate) struct Sweep {
    pub(crate) depths: Vec<u16>,
    pub(crate) slices: [Vec<f32>; 2],
}

/// Sky sweeps whose buffers exist at once (the rest wait): bounds the build's memory.
const SWEEPS_AT_ONCE: usize = 7;

/// Resolution of the stored sky depths' cube roots (`∛τ` per `u16` step; a power of two, so
/// the scaling is exact): 2⁻¹³, up to a depth of 512 (`∛τ` 8), far past where even the weakest
/// multiple-scattering octave's transmittance (`e^{−τ/8}` with four octaves) is 10⁻⁷. Half the
/// memory of `f32` (the sky's 26 depths a node were the light grid's largest buffer); the depth
/// error, `3∛τ²` times half a step, is 2·10⁻⁴ at `τ` 1 and 10⁻³ at 4 (a transmittance error
/// below 0.1 % where any light gets through).
pub(crate) const SKY_ROOT_STEP: f32 = 1.0 / 8192.0;

/// `τ ≥ 0` stored as `∛τ` in steps of [`SKY_ROOT_STEP`], rounded, saturating at the largest
/// step (`as` saturates; no call to `round`, which is a library call without SSE4.1);
/// [`depth_of`] takes it back.
///
/// Why the cube root: a sky depth is 0 outside the cloud and grows inside, and the lookup
/// interpolates it trilinearly over a sky cell three light-grid cells wide, so between a node
/// outside and one inside it reads the depth too deep (up to `σ·h/4` at the surface, `h` a cell
/// of the sky's grid): the cloud's lit side came out too dark. Interpolated as `∛τ` the
/// kink at the surface is mostly gone, and deep inside (`τ` slowly varying over a cell) the
/// root's interpolation is as good as the depth's. It replaces the shift of the stored depths
/// toward the light that made up for it before (`SURFACE_SHIFT`, one light-grid cell), which
/// also made the depths everywhere else too shallow, by `σ` times that cell. Measured against Mitsuba 3
/// (docs/MEASUREMENTS.md, "The plate's light"; `environment_single_scattering_matches_mitsuba`,
/// 640×360): the march on Mitsuba's grid 8.6 % → 6.6 % per pixel (mean 1.042 → 1.011), end to
/// end 10.0 % → 7.5 % (1.041 → 1.008); with the depths marched exactly it reads 5.6 % at
/// 160×90, where the root reads 5.8 % (the shift 7.1 %). Square roots (6.7 %, 8.0 % at
/// 640×360) leave more of the bias, the shift halved (7.7 %, 9.4 %) more still.
#[inline]
pub(crate) fn quantize_depth(tau: f32) -> u16 {
    (tau.cbrt() * (1.0 / SKY_ROOT_STEP) + 0.5) as u16
}

/// The depth of an interpolated stored value `q` (in steps of [`SKY_ROOT_STEP`] of `∛τ`,
/// [`quantize_depth`]).
#[inline]
pub(crate) fn depth_of(q: f32) -> f32 {
    let r = q * SKY_ROOT_STEP;
    r * r * r
}

/// The sky's depths over the world grid `shape` coarsened [`SKY_SPACING`] times (its extinction
/// from the sun grid's samples): one sweep per sky cell, node-major into `sky`. Returns the
/// coarse grid.
pub(crate) fn sky_depths(
    shape: &GridShape,
    sun: &SunGrid,
    work: &mut SkyWork,
    sky: &mut Vec<u16>,
) -> GridShape {
    let sky_shape = coarse_extinction(shape, sun, &mut work.coarse);
    let n = sky_shape.len();
    // Every value is written below: no clearing.
    sky.resize(n * SKY_DIRECTIONS, 0);
    sky.truncate(n * SKY_DIRECTIONS);
    work.sweeps.resize(SWEEPS_AT_ONCE, Sweep::default());
    let dirs = directions();
    let cells: Vec<usize> = (0..SKY_DIRECTIONS).collect();
    for batch in cells.chunks(SWEEPS_AT_ONCE) {
        // Light from a sky cell travels from the cell's direction.
        let coarse = &work.coarse;
        work.sweeps
            .par_iter_mut()
            .zip(batch)
            .for_each(|(tau, &c)| sweep(&sky_shape, coarse, -dirs[c], tau));
        let sweeps = &work.sweeps[..batch.len()];
        sky.par_chunks_mut(SKY_DIRECTIONS)
            .enumerate()
            .for_each(|(node, out)| {
                for (&c, sweep) in batch.iter().zip(sweeps) {
                    out[c] = sweep.depths[node];
                }
            });
    }
    sky_shape
}

/// The grid of [`SKY_SPACING`] times `shape`'s spacing over the same origin (node `n` at fine
/// node `SKY_SPACING·n`), with each node's extinction the sun grid's prefiltered samples
/// ([`SunGrid::coarse_extinction`], so optical depths through the coarse grid keep their
/// value), into `out`.
fn coarse_extinction(shape: &GridShape, sun: &SunGrid, out: &mut Vec<f32>) -> GridShape {
    let [nx, ny, nz] = shape.dims;
    let c = |n: usize| n.div_ceil(SKY_SPACING) + 1;
    let dims = [c(nx), c(ny), c(nz)];
    let coarse = GridShape {
        origin: shape.origin,
        h: SKY_SPACING as f32 * shape.h,
        dims,
    };
    // Every value is written: no clearing.
    out.resize(coarse.len(), 0.0);
    out.truncate(coarse.len());
    out.par_chunks_mut(dims[0] * dims[1])
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    slice[i + dims[0] * j] = sun.coarse_extinction(coarse.node(i, j, k));
                }
            }
        });
    coarse
}

/// Spacing of the sky's grid in cells of the light grid. Three (not two, as it was) costs a
/// third as many sweep steps; against Mitsuba (the shots of docs/MEASUREMENTS.md, "Checked
/// against Mitsuba 3", 256-spp references) the side-lit duck's single scattering came out
/// 4.93 % (4.95 % at two) and the backlit golden hour 9.30 % (9.38 %), the multiple-scattering
/// means and base/top within 0.001 of two's — with the surface shift (`SURFACE_SHIFT`, since
/// removed) kept in world units. Kept in world units is the point: a shift of one sky cell at
/// three made the duck 2 % too bright (5.9 %). (The shift is gone since the depths are stored
/// as cube roots, [`quantize_depth`]. On the plate's light at 640×360, same grid and end to
/// end, two with square roots stored measured 6.6 % and 7.4 %, against 6.7 % and 8.0 % at
/// three; three with cube roots 6.6 % and 7.5 %: not worth 3.4 times the sweeps' nodes.)
pub(crate) const SKY_SPACING: usize = 3;

/// Optical depth from every node toward the light (light travelling along unit `dir`),
/// quantized ([`quantize_depth`]), into `out.depths`.
fn sweep(shape: &GridShape, sigma: &[f32], dir: Vec3A, out: &mut Sweep) {
    let d = [dir.x, dir.y, dir.z];
    // k: the axis the light moves along fastest; a, b: the other two.
    let k = (0..3)
        .max_by(|&p, &q| d[p].abs().total_cmp(&d[q].abs()))
        .unwrap_or(1);
    // The inner loop runs along the smaller stride of the two (x before y before z).
    let (a, b) = {
        let (p, q) = ((k + 1) % 3, (k + 2) % 3);
        (p.min(q), p.max(q))
    };
    let dk = d[k].abs().max(1e-6);
    // One slice back toward the light, in node units: −dir/|dir_k|.
    let (oa, ob) = (-d[a] / dk, -d[b] / dk);
    let (fa, fb) = (oa.floor(), ob.floor());
    let (wa, wb) = (oa - fa, ob - fb);
    let (fa, fb) = (fa as isize, fb as isize);
    let ds = shape.h / dk;
    let n = shape.dims;
    let stride = [1, n[0], n[0] * n[1]];
    let forward = d[k] > 0.0;
    // A slice's depths by `ia + n[a]·ib`: the recurrence reads only the slice before.
    let Sweep { depths, slices } = out;
    let [back_tau, tau] = slices;
    back_tau.resize(n[a] * n[b], 0.0);
    tau.resize(n[a] * n[b], 0.0);
    // Every node is written, slice by slice toward the light's travel: no clearing.
    depths.resize(sigma.len(), 0);
    depths.truncate(sigma.len());
    for step in 0..n[k] {
        let ik = if forward { step } else { n[k] - 1 - step };
        let prev = if forward {
            ik.checked_sub(1)
        } else {
            Some(ik + 1).filter(|&p| p < n[k])
        };
        let slice = ik * stride[k];
        if let Some(pk) = prev {
            let back = pk * stride[k];
            let w = [
                (1.0 - wa) * (1.0 - wb),
                wa * (1.0 - wb),
                (1.0 - wa) * wb,
                wa * wb,
            ];
            for ib in 0..n[b] {
                let qb = ib as isize + fb;
                let b_inside = qb >= 0 && qb + 1 < n[b] as isize;
                for ia in 0..n[a] {
                    let idx = ia * stride[a] + ib * stride[b] + slice;
                    let qa = ia as isize + fa;
                    let (tq, sq) = if b_inside && qa >= 0 && qa + 1 < n[a] as isize {
                        // All four corners of the back point inside the grid: no checks.
                        let (qa, qb) = (qa as usize, qb as usize);
                        let q = qa * stride[a] + qb * stride[b] + back;
                        let l = qa + n[a] * qb;
                        let c = [
                            (l, q),
                            (l + 1, q + stride[a]),
                            (l + n[a], q + stride[b]),
                            (l + 1 + n[a], q + stride[a] + stride[b]),
                        ];
                        let mut acc = (0.0, 0.0);
                        for ((lc, qc), wc) in c.into_iter().zip(w) {
                            acc.0 += wc * back_tau[lc];
                            acc.1 += wc * sigma[qc];
                        }
                        acc
                    } else {
                        // Bilinear (τ, σ) at the back point; corners outside the grid count as 0.
                        let mut acc = (0.0, 0.0);
                        for (corner, wc) in w.into_iter().enumerate() {
                            let (ca, cb) = ((corner & 1) as isize, (corner >> 1) as isize);
                            let (qa, qb) = (qa + ca, qb + cb);
                            if qa < 0 || qa >= n[a] as isize || qb < 0 || qb >= n[b] as isize {
                                continue;
                            }
                            let (qa, qb) = (qa as usize, qb as usize);
                            let q = qa * stride[a] + qb * stride[b] + back;
                            acc.0 += wc * back_tau[qa + n[a] * qb];
                            acc.1 += wc * sigma[q];
                        }
                        acc
                    };
                    tau[ia + n[a] * ib] = tq + 0.5 * (sigma[idx] + sq) * ds;
                }
            }
        } else {
            for ib in 0..n[b] {
                for ia in 0..n[a] {
                    let idx = ia * stride[a] + ib * stride[b] + slice;
                    tau[ia + n[a] * ib] = 0.5 * sigma[idx] * ds;
                }
            }
        }
        // Stored as cube roots: the lookup's trilinear interpolation of a depth that is 0
        // outside and grows inside reads it too deep near the surface ([`quantize_depth`]).
        for ib in 0..n[b] {
            for ia in 0..n[a] {
                let idx = ia * stride[a] + ib * stride[b] + slice;
                depths[idx] = quantize_depth(tau[ia + n[a] * ib]);
            }
        }
        std::mem::swap(back_tau, tau);
    }
}

/// Take the light of each sky cell from the nodes of the sky's grid (`shape`, depths `sky`
/// node-major) that a shadow-casting holdout hides from it: the depth saturates (`u16::MAX`
/// steps, 128, the same as the sun's [`crate::render::surfaces::BLOCKED_DEPTH`]). Only the
/// nodes the cloud can be looked up between are cast from: those with extinction (`coarse`)
/// within one node; one BVH cast per such node and sky cell.
pub(crate) fn block_sky(shape: &GridShape, coarse: &[f32], surfaces: &Surfaces, sky: &mut [u16]) {
    let [nx, ny, nz] = shape.dims;
    let dirs = directions();
    let near_cloud = |i: usize, j: usize, k: usize| {
        for kk in k.saturating_sub(1)..(k + 2).min(nz) {
            for jj in j.saturating_sub(1)..(j + 2).min(ny) {
                for ii in i.saturating_sub(1)..(i + 2).min(nx) {
                    if coarse
                        .get(ii + nx * (jj + ny * kk))
                        .is_some_and(|&s| s > 0.0)
                    {
                        return true;
                    }
                }
            }
        }
        false
    };
    sky.par_chunks_mut(SKY_DIRECTIONS)
        .enumerate()
        .for_each(|(n, out)| {
            let (i, j, k) = (n % nx, (n / nx) % ny, n / (nx * ny));
            if !near_cloud(i, j, k) {
                return;
            }
            let x = shape.node(i, j, k);
            for (c, d) in out.iter_mut().zip(dirs.iter()) {
                if surfaces.caster_occludes(x, *d) {
                    *c = u16::MAX;
                }
            }
        });
}
