//! Single scattering of sky light: the sky dome split into [`SKY_DIRECTIONS`] cells, each lit
//! through the cloud along its own direction (optical depths from the light grid), weighted by
//! the phase function toward the eye.
//!
//! The cloud's forward lobe (`g ≈ 0.75`) is far narrower than a cell, so it is split off as in
//! the delta-Eddington approximation (Joseph, Wiscombe & Weinman 1976): `HG(g) ≈ f·δ + (1 − f)·
//! HG(g/(1 + g))` with `f = g²`. The smooth remainder is sampled on the cells; the delta part
//! is sky light from straight behind the sample scattered straight on, which along a whole ray
//! sums to `L_sky(v)·τ·T` (`τ` the ray's optical depth through the cloud, `T = e^{−τ}`): the
//! integrator adds it once per ray ([`SkyLight::forward_radiance`], through
//! [`crate::render::light::shading::Shading::forward_sky`]). The plate's skies (`Uniform`,
//! `Environment`) instead weight the cells by the whole phase function integrated over each
//! cell's texels, per view direction ([`crate::render::light::sky_view`]): the forward peak's
//! light is then shadowed by the depths of the cells it comes through at each sample — closer
//! to Mitsuba at sky-lit rims and across the body; kept from the analytic skies so that their
//! frames keep their bits.
//!
//! In: the [`SkyDome`] and the phase asymmetry. Out: per-frame cell directions and radiances;
//! per ray, the RGB weight of each cell ([`SkyLight::ray_weights`]).

use std::f32::consts::PI;
use std::sync::Arc;

use glam::{Vec3, Vec3A};

use crate::render::light::envmap::{TABLE_COLS, TABLE_ROWS};
use crate::render::light::phase::{BACK_LOBE_RATIO, BACK_LOBE_WEIGHT, henyey_greenstein};
use crate::render::light::sky_dome::SkyDome;
use crate::render::light::sky_view::{ViewWeights, table_dir};

/// Number of sky cells: the 26 directions from a cube's centre to its face centres, edge
/// midpoints and corners (all of them at least 35° apart).
pub const SKY_DIRECTIONS: usize = 26;

/// Index of straight up (+Y) in [`directions`].
pub(crate) const UP: usize = 2;
/// Index of straight down (−Y) in [`directions`].
pub(crate) const DOWN: usize = 3;

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
pub(crate) struct SkyLight {
    dirs: [Vec3A; SKY_DIRECTIONS],
    /// Mean radiance of each cell times its solid angle (linear RGB).
    cell_power: [Vec3A; SKY_DIRECTIONS],
    /// Forward lobe's HG asymmetry after the delta part is split off, and the lobe weights:
    /// `[smooth forward, back]`.
    g_smooth: f32,
    g_back: f32,
    weights: [f32; 2],
    /// Weight of the delta part in the phase function.
    delta: f32,
    /// The sky seen through the forward lobe, for the delta part ([`PrefilteredSky`]).
    forward: PrefilteredSky,
    /// The sky seen through the smooth part of the phase function (normalised): what the
    /// cells add up to when nothing is in the way.
    smooth: PrefilteredSky,
    /// The plate's skies: every cell's weight per view direction, the delta part included
    /// ([`ViewWeights`], a map's kept across frames at intensity 1), and the scale to apply
    /// (the map's intensity); `None` for the analytic skies.
    view: Option<(Arc<ViewWeights>, f32)>,
}

impl SkyLight {
    /// Cells of `dome` for a cloud with phase asymmetry `g` (the two-lobe
    /// [`crate::render::light::phase::cloud_phase`]).
    pub(crate) fn new(dome: &SkyDome, g: f32) -> SkyLight {
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
        let cell_power = match dome.environment() {
            // A map: its texels' light summed per cell, by solid angle (`light/envmap.rs`).
            Some((env, k)) => std::array::from_fn(|c| Vec3A::from(env.cells[c] * k)),
            None => std::array::from_fn(|k| Vec3A::from(sum[k] * per_sample)),
        };
        let f = g * g;
        let (g_smooth, g_back) = (g / (1.0 + g), BACK_LOBE_RATIO * g);
        let weights = [(1.0 - BACK_LOBE_WEIGHT) * (1.0 - f), BACK_LOBE_WEIGHT];
        let smooth = move |mu: f32| {
            weights[0] * henyey_greenstein(mu, g_smooth)
                + weights[1] * henyey_greenstein(mu, g_back)
        };
        SkyLight {
            dirs,
            cell_power,
            g_smooth,
            g_back,
            weights,
            delta: (1.0 - BACK_LOBE_WEIGHT) * f,
            // The forward lobe less its smooth part: with it the two parts add up to the
            // phase function exactly (it dips slightly below 0 backward, where its weight is
            // negligible).
            forward: PrefilteredSky::new(dome, |mu| {
                (henyey_greenstein(mu, g) - (1.0 - f) * henyey_greenstein(mu, g_smooth)) / f
            }),
            smooth: PrefilteredSky::new(dome, smooth),
            view: match (dome, dome.environment()) {
                (_, Some((env, k))) => Some((env.view_weights(g), k)),
                (SkyDome::Uniform { .. } | SkyDome::Environment { .. }, None) => Some((
                    Arc::new(ViewWeights::new(&cell_texels(dome, &dirs), g)),
                    1.0,
                )),
                _ => None,
            },
        }
    }

    /// Sky radiance behind a ray with unit direction `dir`, as the delta part scatters it
    /// on: the sky averaged over the forward lobe around `dir`. Zero for the plate's skies,
    /// whose delta part is in the cells' weights ([`SkyLight::ray_weights`]).
    #[inline]
    pub(crate) fn forward_radiance(&self, dir: Vec3A) -> Vec3A {
        if self.view.is_some() {
            return Vec3A::ZERO;
        }
        self.forward.lookup(dir)
    }

    /// RGB weight of each cell's transmittance `e^{−τ_k}` for a ray with unit direction `dir`:
    /// the smooth part of the phase function at the cell's direction times the cell's light,
    /// scaled so that the weights add up to the smooth part's exact share of the whole sky
    /// (prefiltered): an unshadowed sample receives exactly what the sky sends, and shadows
    /// only redistribute it by cell.
    ///
    /// For the plate's skies (`Uniform`, `Environment`) the weights come from the per-view
    /// table ([`ViewWeights`]), the whole phase function integrated over each cell's texels:
    /// the forward peak's light is shadowed by the depths of the cells it comes through at each
    /// sample, not by the ray's own depth (at a rim the peak, about 15° wide, brings light from
    /// outside the cloud where the ray's own path runs through it). The analytic skies keep the
    /// ray's depth: their frames are pinned (a change of the render version).
    pub(crate) fn ray_weights(&self, dir: Vec3A) -> [Vec3A; SKY_DIRECTIONS] {
        if let Some((view, k)) = &self.view {
            return view.lookup(dir).map(|w| w * *k);
        }
        // Light from cell direction ω travels along −ω and leaves toward the eye along −dir.
        let mut w = [Vec3A::ZERO; SKY_DIRECTIONS];
        let mut total = Vec3A::ZERO;
        for ((wk, d), power) in w.iter_mut().zip(&self.dirs).zip(&self.cell_power) {
            let mu = d.dot(dir);
            let p = self.weights[0] * henyey_greenstein(mu, self.g_smooth)
                + self.weights[1] * henyey_greenstein(mu, self.g_back);
            *wk = *power * p;
            total += *wk;
        }
        let target = self.smooth.lookup(dir) * (1.0 - self.delta);
        let scale = target / total.max(Vec3A::splat(1e-12));
        for wk in &mut w {
            *wk *= scale;
        }
        w
    }

    /// Weight of the phase function's delta (straight-on) part.
    pub(crate) fn delta(&self) -> f32 {
        self.delta
    }
}

/// The sky convolved with a phase-function kernel on a small latitude–longitude table (rows
/// uniform in `y`, so texels have equal solid angle), looked up bilinearly.
///
/// For the delta part the kernel is the forward lobe `HG(g)` less its smooth remainder, about
/// `1 − g` radians wide: the light it scatters on comes from the sky around the ray's
/// direction, not from the one point straight behind (at the horizon the two differ by the
/// ground's darkness).
#[derive(Clone, Debug)]
struct PrefilteredSky {
    /// `ROWS × COLS` texels, row-major, rows from `y = −1` up.
    texels: Vec<Vec3A>,
}

const ROWS: usize = 16;
const COLS: usize = 32;

impl PrefilteredSky {
    /// `dome` averaged with the weights `kernel(cos angle)` around each texel's direction.
    fn new(dome: &SkyDome, kernel: impl Fn(f32) -> f32) -> PrefilteredSky {
        let dir = |row: f32, col: f32, rows: usize, cols: usize| {
            let y = -1.0 + 2.0 * (row + 0.5) / rows as f32;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let phi = 2.0 * PI * (col + 0.5) / cols as f32;
            Vec3A::new(r * phi.cos(), y, r * phi.sin())
        };
        // The sky itself on a finer table of equal-solid-angle texels.
        let (sr, sc) = (2 * ROWS, 2 * COLS);
        // A map: each texel's mean over its solid angle (a sunny map's sun is not missed
        // between point samples).
        let env = dome.environment();
        const _: () = assert!(2 * ROWS == TABLE_ROWS && 2 * COLS == TABLE_COLS);
        let source: Vec<(Vec3A, Vec3A)> = (0..sr * sc)
            .map(|k| {
                let d = dir((k / sc) as f32, (k % sc) as f32, sr, sc);
                let l = match &env {
                    Some((env, scale)) => env.table[k] * *scale,
                    None => dome.radiance(d.into()),
                };
                (d, Vec3A::from(l))
            })
            .collect();
        let texels = (0..ROWS * COLS)
            .map(|k| {
                let v = dir((k / COLS) as f32, (k % COLS) as f32, ROWS, COLS);
                let (mut sum, mut wsum) = (Vec3A::ZERO, 0.0);
                for &(d, l) in &source {
                    let w = kernel(d.dot(v));
                    sum += l * w;
                    wsum += w;
                }
                sum / wsum
            })
            .collect();
        PrefilteredSky { texels }
    }

    /// Bilinear lookup for the unit direction `v` (wrapping in azimuth, clamped in `y`).
    fn lookup(&self, v: Vec3A) -> Vec3A {
        let fy = ((v.y + 1.0) * 0.5 * ROWS as f32 - 0.5).clamp(0.0, (ROWS - 1) as f32);
        let phi = v.z.atan2(v.x).rem_euclid(2.0 * PI);
        let fx = phi / (2.0 * PI) * COLS as f32 - 0.5;
        let (y0, wy) = (fy.floor() as usize, fy - fy.floor());
        let y1 = (y0 + 1).min(ROWS - 1);
        let x0f = fx.floor();
        let wx = fx - x0f;
        let x0 = (x0f as i64).rem_euclid(COLS as i64) as usize;
        let x1 = (x0 + 1) % COLS;
        let t = |y: usize, x: usize| self.texels[y * COLS + x];
        (t(y0, x0) * (1.0 - wx) + t(y0, x1) * wx) * (1.0 - wy)
            + (t(y1, x0) * (1.0 - wx) + t(y1, x1) * wx) * wy
    }
}

/// The sky on the equal-solid-angle table `TABLE_ROWS × TABLE_COLS` ([`table_dir`]): per
/// texel its direction, its radiance (a map's mean over the texel, so that a sunny map's sun is
/// not missed between point samples) and the index of its cell in `dirs`.
fn cell_texels(dome: &SkyDome, dirs: &[Vec3A; SKY_DIRECTIONS]) -> Vec<(Vec3A, Vec3A, usize)> {
    let env = dome.environment();
    (0..TABLE_ROWS * TABLE_COLS)
        .map(|k| {
            let d = table_dir(k / TABLE_COLS, k % TABLE_COLS, TABLE_ROWS, TABLE_COLS);
            let l = match &env {
                Some((env, scale)) => env.table[k] * *scale,
                None => dome.radiance(d.into()),
            };
            (d, Vec3A::from(l), nearest(dirs, d))
        })
        .collect()
}

/// Index of the direction in `dirs` closest to `d`.
pub(crate) fn nearest(dirs: &[Vec3A; SKY_DIRECTIONS], d: Vec3A) -> usize {
    let mut best = (f32::NEG_INFINITY, 0);
    for (k, c) in dirs.iter().enumerate() {
        let dot = c.dot(d);
        if dot > best.0 {
            best = (dot, k);
        }
    }
    best.1
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::light::phase::cloud_phase;
    use crate::render::settings::{Sky, Sun};

    #[test]
    fn directions_are_distinct_unit_vectors_with_up_and_down_where_named() {
        let d = directions();
        assert_eq!(d[UP], Vec3A::Y);
        assert_eq!(d[DOWN], Vec3A::NEG_Y);
        for (i, a) in d.iter().enumerate() {
            assert!((a.length() - 1.0).abs() < 1e-6);
            for b in &d[i + 1..] {
                // At least 35° apart.
                assert!(a.dot(*b) < 0.82, "{a} {b}");
            }
        }
    }

    /// Unshadowed, the cells plus the delta part scatter what the whole sky does through the
    /// phase function (a fine quadrature of `∫ L(ω) p(ω·v) dω`), for any view direction.
    #[test]
    fn unshadowed_sky_matches_a_quadrature_of_the_phase_function() {
        let sky = Sky::Gradient {
            zenith: Vec3::new(0.2, 0.35, 0.7),
            horizon: Vec3::new(0.7, 0.75, 0.8),
        };
        assert_cells_match_quadrature(
            &sky,
            [
                Vec3A::X,
                Vec3A::new(0.3, -0.4, 0.87).normalize(),
                Vec3A::new(-0.5, 0.7, 0.2).normalize(),
                Vec3A::NEG_Y,
            ],
            (800, 800),
        );
    }

    /// The plate's skies carry the delta part in the cells (a uniform sky's weights then sum
    /// to its colour: the phase function integrates to 1); the analytic skies along the ray.
    #[test]
    fn the_plates_skies_carry_the_forward_part_in_the_cells() {
        let color = Vec3::new(0.3, 0.4, 0.6);
        let dome = SkyDome::new(&Sky::Uniform { color }, &Sun::default());
        let light = SkyLight::new(&dome, 0.75);
        for v in [
            Vec3A::X,
            Vec3A::new(0.3, -0.4, 0.87).normalize(),
            Vec3A::NEG_Y,
        ] {
            assert_eq!(light.forward_radiance(v), Vec3A::ZERO);
            let sum: Vec3A = light.ray_weights(v).iter().copied().sum();
            let err = ((sum - Vec3A::from(color)) / Vec3A::from(color))
                .abs()
                .max_element();
            assert!(err < 1e-3, "view {v}: {sum} vs {color}");
            // The forward part goes to the cells facing along the ray: the cell nearest `v`
            // gets more than the one opposite.
            let w = light.ray_weights(v);
            let dirs = directions();
            assert!(w[nearest(&dirs, v)].x > w[nearest(&dirs, -v)].x);
        }
        let gradient = Sky::Gradient {
            zenith: Vec3::new(0.2, 0.35, 0.7),
            horizon: Vec3::new(0.7, 0.75, 0.8),
        };
        let light = SkyLight::new(&SkyDome::new(&gradient, &Sun::default()), 0.75);
        assert!(light.forward_radiance(Vec3A::X).x > 0.0);
    }

    /// Unshadowed, `sky`'s cells plus the delta part scatter what the whole sky does through
    /// the phase function: within 6 % of a `ny × nphi` quadrature of `∫ L(ω) p(ω·v) dω` for
    /// each view direction `v` of `views`.
    fn assert_cells_match_quadrature(sky: &Sky, views: [Vec3A; 4], (ny, nphi): (u32, u32)) {
        let dome = SkyDome::new(sky, &Sun::default());
        let g = 0.75;
        let light = SkyLight::new(&dome, g);
        for v in views {
            let cells: Vec3A = light.ray_weights(v).iter().copied().sum::<Vec3A>()
                + light.forward_radiance(v) * light.delta();
            let mut exact = Vec3A::ZERO;
            for i in 0..ny {
                let y = -1.0 + 2.0 * (i as f32 + 0.5) / ny as f32;
                let r = (1.0 - y * y).sqrt();
                for j in 0..nphi {
                    let phi = 2.0 * PI * (j as f32 + 0.5) / nphi as f32;
                    let w = Vec3A::new(r * phi.cos(), y, r * phi.sin());
                    exact += Vec3A::from(dome.radiance(w.into())) * cloud_phase(w.dot(v), g);
                }
            }
            exact *= 4.0 * PI / (ny * nphi) as f32;
            let err = ((cells - exact) / exact).abs().max_element();
            assert!(err < 0.06, "view {v}: cells {cells} vs quadrature {exact}");
        }
    }

    /// The same for an environment map with a bright patch, turned: its texels' light reaches
    /// the cells and the prefiltered tables by solid angle, so the unshadowed sum is the map's
    /// (a fine quadrature of its bilinear radiance) for any view direction.
    #[test]
    fn unshadowed_environment_matches_a_quadrature_of_the_phase_function() {
        use crate::render::light::envmap::EnvMap;
        use crate::render::settings::Environment;
        let (w, h) = (64, 32);
        let texels = (0..w * h)
            .map(|k| {
                let (x, y) = (k % w, k / w);
                let sky = Vec3::new(0.2, 0.3, 0.6) * (1.0 + y as f32 / h as f32);
                let patch = (10..14).contains(&x) && (9..12).contains(&y);
                sky + if patch { Vec3::splat(30.0) } else { Vec3::ZERO }
            })
            .collect();
        let map = EnvMap::from_texels(w, h, texels).unwrap();
        let sky = Sky::Environment(Environment {
            file: "test".into(),
            rotate_deg: 40.0,
            intensity: 1.5,
            map: Some(std::sync::Arc::new(map)),
            ..Environment::default()
        });
        assert_cells_match_quadrature(
            &sky,
            [
                Vec3A::X,
                Vec3A::new(0.3, -0.4, 0.87).normalize(),
                Vec3A::new(-0.5, 0.7, 0.2).normalize(),
                Vec3A::NEG_Z,
            ],
            (800, 1600),
        );
    }
}
