//! The plate's skies' cell weights per view direction: for each direction a camera ray may
//! take, how much of each sky cell's light ([`crate::render::light::sky_cells`]) the whole
//! phase function scatters toward the eye, integrated over the cell's own texels.
//!
//! The analytic skies weight a cell by the phase function at its centre and send the forward
//! peak (the delta part) along the ray. For a plate's light the table integrates the two-lobe
//! phase function over each cell's texels of the sky table (32 × 64 equal-solid-angle texels,
//! each bringing its own radiance): the forward peak, about 15° wide, lands in the cells it
//! covers, a bright patch weighs by where it lies inside its cell, and every row of weights
//! sums to what the sky sends through the phase function. Against Mitsuba 3's `envmap` on the
//! HDRI-lit duck (same grid) that took the error from 8.6 % to 7.0 % at 160×90 and from 9.4 % to
//! 7.6 % at 640×360 (docs/MEASUREMENTS.md, "The plate's light").
//!
//! In: the sky's texels (radiance, direction), the cell directions, the phase asymmetry. Out:
//! [`ViewWeights::lookup`], bilinear between the table's view directions. `VIEW_ROWS ·
//! VIEW_COLS` views times the texels is about 4 M phase evaluations (a few milliseconds on two
//! cores): a map's table is built once a shot (kept with its integrals,
//! `EnvIntegrals::view_weights`), a uniform sky's once a frame; the analytic skies have none.

use std::f32::consts::PI;

use glam::Vec3A;
use rayon::prelude::*;

use crate::render::light::phase::cloud_phase;
use crate::render::light::sky_cells::SKY_DIRECTIONS;

/// View directions of the table: rows uniform in `y` (equal solid angle), columns in azimuth.
const VIEW_ROWS: usize = 32;
const VIEW_COLS: usize = 64;

/// Per view direction, each sky cell's RGB weight (radiance times solid angle times phase).
#[derive(Clone, Debug)]
pub(crate) struct ViewWeights {
    /// `VIEW_ROWS × VIEW_COLS` rows of weights, rows from `y = −1` up.
    table: Vec<[Vec3A; SKY_DIRECTIONS]>,
}

impl ViewWeights {
    /// The table for a sky given as equal-solid-angle `texels` (unit direction toward the sky,
    /// radiance, index of the cell the texel belongs to) and the phase asymmetry `g`.
    pub(crate) fn new(texels: &[(Vec3A, Vec3A, usize)], g: f32) -> ViewWeights {
        let d_omega = 4.0 * PI / texels.len() as f32;
        let table = (0..VIEW_ROWS * VIEW_COLS)
            .into_par_iter()
            .map(|k| {
                let v = table_dir(k / VIEW_COLS, k % VIEW_COLS, VIEW_ROWS, VIEW_COLS);
                let mut w = [Vec3A::ZERO; SKY_DIRECTIONS];
                let mut psum = 0.0;
                // Light from texel direction ω travels along −ω and leaves toward the eye
                // along −v: the phase function's cosine is ω·v.
                for &(d, l, c) in texels {
                    let p = cloud_phase(d.dot(v), g);
                    w[c] += l * p;
                    psum += p;
                }
                // The texels' sum of the phase function made exactly 1 (its forward peak is
                // only a few texels wide): unshadowed, a row scatters the sky's light in full.
                let norm = 1.0 / (psum * d_omega);
                for wc in &mut w {
                    *wc *= d_omega * norm;
                }
                w
            })
            .collect();
        ViewWeights { table }
    }

    /// The cells' weights for a ray with unit direction `v` (bilinear between view
    /// directions, wrapping in azimuth, clamped in `y`).
    #[inline]
    pub(crate) fn lookup(&self, v: Vec3A) -> [Vec3A; SKY_DIRECTIONS] {
        let fy = ((v.y + 1.0) * 0.5 * VIEW_ROWS as f32 - 0.5).clamp(0.0, (VIEW_ROWS - 1) as f32);
        let phi = v.z.atan2(v.x).rem_euclid(2.0 * PI);
        let fx = phi / (2.0 * PI) * VIEW_COLS as f32 - 0.5;
        let (y0, wy) = (fy.floor() as usize, fy - fy.floor());
        let y1 = (y0 + 1).min(VIEW_ROWS - 1);
        let x0f = fx.floor();
        let wx = fx - x0f;
        let x0 = (x0f as i64).rem_euclid(VIEW_COLS as i64) as usize;
        let x1 = (x0 + 1) % VIEW_COLS;
        let row = |y: usize, x: usize| &self.table[y * VIEW_COLS + x];
        let (a, b, c, d) = (row(y0, x0), row(y0, x1), row(y1, x0), row(y1, x1));
        let (wa, wb) = ((1.0 - wx) * (1.0 - wy), wx * (1.0 - wy));
        let (wc, wd) = ((1.0 - wx) * wy, wx * wy);
        std::array::from_fn(|k| a[k] * wa + b[k] * wb + c[k] * wc + d[k] * wd)
    }
}

/// Unit direction of texel `(row, col)` of a `rows × cols` table whose rows are uniform in `y`
/// from −1 up and whose columns run in azimuth from +X toward +Z.
pub(crate) fn table_dir(row: usize, col: usize, rows: usize, cols: usize) -> Vec3A {
    let y = -1.0 + 2.0 * (row as f32 + 0.5) / rows as f32;
    let r = (1.0 - y * y).max(0.0).sqrt();
    let phi = 2.0 * PI * (col as f32 + 0.5) / cols as f32;
    Vec3A::new(r * phi.cos(), y, r * phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::light::sky_cells::directions;

    /// Under a uniform sky each cell's weight is the phase function integrated over the cell
    /// (a fine quadrature, directions binned to their nearest cell), for view directions on
    /// and between the table's: the forward peak lands in the cells it covers.
    #[test]
    fn a_uniform_skys_weights_are_the_phase_function_integrated_over_each_cell() {
        let dirs = directions();
        let nearest = |d: Vec3A| {
            (0..SKY_DIRECTIONS)
                .max_by(|&a, &b| dirs[a].dot(d).total_cmp(&dirs[b].dot(d)))
                .unwrap()
        };
        let (rows, cols) = (32, 64);
        let texels: Vec<(Vec3A, Vec3A, usize)> = (0..rows * cols)
            .map(|k| {
                let d = table_dir(k / cols, k % cols, rows, cols);
                (d, Vec3A::ONE, nearest(d))
            })
            .collect();
        let g = 0.75;
        let view = ViewWeights::new(&texels, g);
        for v in [
            Vec3A::X,
            Vec3A::new(0.3, -0.4, 0.87).normalize(),
            Vec3A::new(-0.5, 0.7, 0.2).normalize(),
            Vec3A::new(0.577, 0.577, -0.577).normalize(),
        ] {
            let (ny, nphi) = (600, 1200);
            let mut exact = [0.0f32; SKY_DIRECTIONS];
            for i in 0..ny {
                for j in 0..nphi {
                    let d = table_dir(i, j, ny, nphi);
                    exact[nearest(d)] += cloud_phase(d.dot(v), g) * 4.0 * PI / (ny * nphi) as f32;
                }
            }
            let w = view.lookup(v);
            let sum: f32 = w.iter().map(|c| c.x).sum();
            assert!(
                (sum - 1.0).abs() < 1e-4,
                "view {v}: the weights sum to {sum}"
            );
            for (c, (wc, e)) in w.iter().zip(exact).enumerate() {
                assert!(
                    (wc.x - e).abs() < 0.02,
                    "view {v}, cell {c}: {} vs {e}",
                    wc.x
                );
            }
            // The cell around the view direction takes the forward peak: the most light.
            let top = (0..SKY_DIRECTIONS).max_by(|&a, &b| w[a].x.total_cmp(&w[b].x));
            assert_eq!(top, Some(nearest(v)), "view {v}");
        }
    }
}
