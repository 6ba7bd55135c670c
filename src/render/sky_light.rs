//! Single scattering of sky light: the sky dome split into [`SKY_DIRECTIONS`] cells, each lit
//! through the cloud along its own direction (optical depths from the light grid), weighted by
//! the phase function toward the eye.
//!
//! The cloud's forward lobe (`g ≈ 0.75`) is far narrower than a cell, so it is split off as in
//! the delta-Eddington approximation (Joseph, Wiscombe & Weinman 1976): `HG(g) ≈ f·δ + (1 − f)·
//! HG(g/(1 + g))` with `f = g²`. The smooth remainder is sampled on the cells; the delta part
//! is sky light from straight behind the sample scattered straight on, which along a whole ray
//! sums to `L_sky(v)·τ·T` (`τ` the ray's optical depth through the cloud, `T = e^{−τ}`): the
//! integrator adds it once per ray ([`SkyLight::forward`]).
//!
//! In: the [`SkyDome`] and the phase asymmetry. Out: per-frame cell directions and radiances;
//! per ray, the RGB weight of each cell ([`SkyLight::ray_weights`]).

use std::f32::consts::PI;

use glam::{Vec3, Vec3A};

use super::shading::{BACK_LOBE_RATIO, BACK_LOBE_WEIGHT, SkyDome, henyey_greenstein};

/// Number of sky cells: the 26 directions from a cube's centre to its face centres, edge
/// midpoints and corners (all of them at least 35° apart).
pub const SKY_DIRECTIONS: usize = 26;

/// Index of straight up (+Y) in [`directions`].
pub const UP: usize = 2;
/// Index of straight down (−Y) in [`directions`].
pub const DOWN: usize = 3;

/// The unit cell directions (pointing from the cloud toward the sky): faces first (`±X, ±Y,
/// ±Z`), then edges, then corners.
pub fn directions() -> [Vec3A; SKY_DIRECTIONS] {
    let mut out = [Vec3A::ZERO; SKY_DIRECTIONS];
    let faces = [
        Vec3A::X,
        Vec3A::NEG_X,
        Vec3A::Y,
        Vec3A::NEG_Y,
        Vec3A::Z,
        Vec3A::NEG_Z,
    ];
    out[..6].copy_from_slice(&faces);
    let mut n = 6;
    // Edges: two non-zero coordinates; corners: three.
    for zeros in [1, 0] {
        for x in [-1i32, 0, 1] {
            for y in [-1i32, 0, 1] {
                for z in [-1i32, 0, 1] {
                    let nz = [x, y, z].iter().filter(|&&c| c == 0).count();
                    if nz == zeros {
                        out[n] = Vec3A::new(x as f32, y as f32, z as f32).normalize();
                        n += 1;
                    }
                }
            }
        }
    }
    out
}

/// The sky as single scattering sees it for one frame.
#[derive(Clone, Debug)]
pub struct SkyLight {
    dirs: [Vec3A; SKY_DIRECTIONS],
    /// Mean radiance of each cell times its solid angle (linear RGB).
    cell_power: [Vec3A; SKY_DIRECTIONS],
    /// Solid angle of each cell.
    omega: [f32; SKY_DIRECTIONS],
    /// Forward lobe's HG asymmetry after the delta part is split off, and the lobe weights:
    /// `[smooth forward, back]`.
    g_smooth: f32,
    g_back: f32,
    weights: [f32; 2],
    /// Weight of the delta part in the phase function.
    delta: f32,
}

impl SkyLight {
    /// Cells of `dome` for a cloud with phase asymmetry `g` (the two-lobe
    /// [`super::shading::cloud_phase`]).
    pub fn new(dome: &SkyDome, g: f32) -> SkyLight {
        let dirs = directions();
        // Bin a uniform sampling of the sphere (uniform in y and azimuth) into the nearest cell.
        let (ny, nphi) = (48, 96);
        let mut sum = [Vec3::ZERO; SKY_DIRECTIONS];
        let mut count = [0u32; SKY_DIRECTIONS];
        for i in 0..ny {
            let y = -1.0 + 2.0 * (i as f32 + 0.5) / ny as f32;
            let r = (1.0 - y * y).max(0.0).sqrt();
            for j in 0..nphi {
                let phi = 2.0 * PI * (j as f32 + 0.5) / nphi as f32;
                let d = Vec3::new(r * phi.cos(), y, r * phi.sin());
                let k = nearest(&dirs, d.into());
                sum[k] += dome.radiance(d);
                count[k] += 1;
            }
        }
        let per_sample = 4.0 * PI / (ny * nphi) as f32;
        let cell_power = std::array::from_fn(|k| Vec3A::from(sum[k] * per_sample));
        let omega = std::array::from_fn(|k| count[k] as f32 * per_sample);
        let f = g * g;
        SkyLight {
            dirs,
            cell_power,
            omega,
            g_smooth: g / (1.0 + g),
            g_back: BACK_LOBE_RATIO * g,
            weights: [(1.0 - BACK_LOBE_WEIGHT) * (1.0 - f), BACK_LOBE_WEIGHT],
            delta: (1.0 - BACK_LOBE_WEIGHT) * f,
        }
    }

    /// RGB weight of each cell's transmittance `e^{−τ_k}` for a ray with unit direction `dir`:
    /// the smooth part of the phase function at the cell's direction, normalised over the
    /// cells so that an unshadowed sample receives the whole smooth part of the sky.
    pub fn ray_weights(&self, dir: Vec3A) -> [Vec3A; SKY_DIRECTIONS] {
        // Light from cell direction ω travels along −ω and leaves toward the eye along −dir.
        let mut p = [0.0f32; SKY_DIRECTIONS];
        let mut total = 0.0;
        for ((pk, d), omega) in p.iter_mut().zip(&self.dirs).zip(&self.omega) {
            let mu = d.dot(dir);
            *pk = self.weights[0] * henyey_greenstein(mu, self.g_smooth)
                + self.weights[1] * henyey_greenstein(mu, self.g_back);
            total += *pk * omega;
        }
        // The normalisation keeps the smooth part's share `1 − delta` of the phase function
        // whatever the discretisation.
        let scale = (1.0 - self.delta) / total.max(1e-12);
        std::array::from_fn(|k| self.cell_power[k] * (p[k] * scale))
    }

    /// Weight of the phase function's delta (straight-on) part.
    pub fn delta(&self) -> f32 {
        self.delta
    }

    /// The unit cell directions.
    pub fn dirs(&self) -> &[Vec3A; SKY_DIRECTIONS] {
        &self.dirs
    }
}

/// Index of the direction in `dirs` closest to `d`.
fn nearest(dirs: &[Vec3A; SKY_DIRECTIONS], d: Vec3A) -> usize {
    let mut best = (f32::NEG_INFINITY, 0);
    for (k, c) in dirs.iter().enumerate() {
        let dot = c.dot(d);
        if dot > best.0 {
            best = (dot, k);
        }
    }
    best.1
}
