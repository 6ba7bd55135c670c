//! A lat-long (equirectangular) environment map: the plate's HDRI as the sky
//! ([`crate::render::Sky::Environment`]).
//!
//! # Convention (Mitsuba 3's `envmap`, so that one file lights both renderers alike)
//!
//! An image `W × H` (`W = 2H`), row 0 at the top. Image point `(u, v) ∈ [0, 1)²` (`u` across,
//! `v` down) looks along `(sin θ sin φ, cos θ, −sin θ cos φ)` with `φ = 2πu`, `θ = πv`, Y up:
//! the top row is straight up (+Y), the bottom row straight down; the image's left edge
//! (`u = 0`) looks toward −Z, a quarter across (`u = ¼`) toward +X, the middle (`u = ½`) toward
//! +Z, three quarters across toward −X. With the sun's and the camera's azimuth (0 = toward +Z,
//! 90° = toward +X) column `u` is at azimuth `360°·u + 180°`.
//!
//! The radiance toward a direction is the bilinear interpolation of the texels as Mitsuba's
//! `envmap` evaluates it (checked against Mitsuba 3.6.4's `eval`): across, texel `i`'s centre is
//! at `u = (i + ½)/W` and the map wraps around; down, texel row `j` is at `θ = π·j/(H − 1)` (the
//! first and last rows are the poles).
//!
//! `rotate_deg` turns the map about +Y by the right-hand rule (seen from above,
//! counter-clockwise, as the camera's `orbit_deg`): what the file shows toward +Z is seen toward
//! +X at `rotate_deg: 90`. It is Mitsuba's `to_world = rotate([0, 1, 0], rotate_deg)`.
//!
//! # Light per sky cell
//!
//! The sky's single scattering and the multiple-scattering octaves see the map through its
//! integrals ([`EnvIntegrals`]): the radiance times solid angle over a quadrature grid at least
//! as fine as the texels (every texel's light counted once, in the sky cell whose direction is
//! nearest; no random point samples), the mean radiance of each bin of the prefiltered tables
//! (rows uniform in `y`), and the means of the upper and lower hemispheres. They are computed
//! once per map and rotation and kept.

use std::f32::consts::PI;
use std::path::Path;
use std::sync::{Arc, Mutex};

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::render::light::sky_cells::{SKY_DIRECTIONS, directions, nearest};
use crate::render::light::sky_view::{ViewWeights, table_dir};

/// Widest map read (a 8192 × 4096 map is 400 MB of RGB floats); larger maps are refused with a
/// request to scale them down.
pub const MAX_WIDTH: usize = 8192;

/// A lat-long environment map in linear RGB (see the module doc for its convention).
pub struct EnvMap {
    width: usize,
    height: usize,
    /// Row-major, row 0 at the top (straight up).
    texels: Vec<Vec3>,
    /// FNV-1a of the size and texels' bits: what provenance keys the light by.
    hash: u64,
    /// [`EnvIntegrals`] for the last rotation asked (its bits).
    integrals: Mutex<Option<(u32, Arc<EnvIntegrals>)>>,
}

impl std::fmt::Debug for EnvMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EnvMap")
            .field("width", &self.width)
            .field("height", &self.height)
            .field("hash", &format_args!("{:016x}", self.hash))
            .finish()
    }
}

impl PartialEq for EnvMap {
    fn eq(&self, other: &EnvMap) -> bool {
        self.width == other.width && self.height == other.height && self.hash == other.hash
    }
}

/// What the sky's shading needs of a map (at intensity 1), for one rotation.
#[derive(Debug)]
pub(crate) struct EnvIntegrals {
    /// Radiance × solid angle of each sky cell ([`directions`]: the directions nearest the cell's).
    pub cells: [Vec3; SKY_DIRECTIONS],
    /// Mean radiance of each bin of a [`TABLE_ROWS`] × [`TABLE_COLS`] table: rows uniform in `y`
    /// from −1 up, columns uniform in `atan2(z, x)` from 0 (the prefiltered sky's source).
    pub table: Vec<Vec3>,
    /// Mean radiance over the upper hemisphere (uniform solid angle).
    pub upper_mean: Vec3,
    /// Mean radiance over the lower hemisphere.
    pub lower_mean: Vec3,
    /// The cells' weights per view direction for the last phase asymmetry asked
    /// ([`EnvIntegrals::view_weights`]).
    view: Mutex<Option<(u32, Arc<ViewWeights>)>>,
}

impl EnvIntegrals {
    /// The sky cells' weights per view direction for phase asymmetry `g` (at intensity 1;
    /// computed on first use for a `g`, then kept: a shot's frames share them).
    pub(crate) fn view_weights(&self, g: f32) -> Arc<ViewWeights> {
        let key = g.to_bits();
        let mut cached = self.view.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((k, v)) = cached.as_ref()
            && *k == key
        {
            return Arc::clone(v);
        }
        let dirs = directions();
        let texels: Vec<_> = self
            .table
            .iter()
            .enumerate()
            .map(|(k, l)| {
                let d = table_dir(k / TABLE_COLS, k % TABLE_COLS, TABLE_ROWS, TABLE_COLS);
                (d, Vec3A::from(*l), nearest(&dirs, d))
            })
            .collect();
        let v = Arc::new(ViewWeights::new(&texels, g));
        *cached = Some((key, Arc::clone(&v)));
        v
    }
}

/// Rows of [`EnvIntegrals::table`].
pub(crate) const TABLE_ROWS: usize = 32;
/// Columns of [`EnvIntegrals::table`].
pub(crate) const TABLE_COLS: usize = 64;

/// Fewest quadrature columns around the sphere (a small map's texels are split so that each
/// part goes to its own cell).
const MIN_QUAD_COLS: usize = 512;

impl EnvMap {
    /// A map of `width × height` texels (row-major, row 0 at the top): lat-long
    /// (`width = 2 × height`, from 4 × 2 up to [`MAX_WIDTH`]) with finite, non-negative
    /// values, or what is wrong.
    pub fn from_texels(width: usize, height: usize, texels: Vec<Vec3>) -> Result<EnvMap, String> {
        if height < 2 || width != 2 * height {
            return Err(format!(
                "is {width} × {height} texels: a lat-long map is twice as wide as high \
                 (at least 4 × 2)"
            ));
        }
        if width > MAX_WIDTH {
            return Err(format!(
                "is {width} × {height} texels, wider than the {MAX_WIDTH} nephele reads; \
                 scale it down (the sky cells are 35° apart)"
            ));
        }
        assert_eq!(texels.len(), width * height, "texel count");
        if let Some(k) = texels
            .iter()
            .position(|t| !(t.is_finite() && t.min_element() >= 0.0))
        {
            return Err(format!(
                "texel (x {}, y {}) is {:?}: every texel must be finite and not negative",
                k % width,
                k / width,
                texels[k].to_array()
            ));
        }
        let mut h = crate::hash::Fnv1a::new();
        h.write(b"nephele envmap");
        h.write(&(width as u64).to_le_bytes());
        h.write(&(height as u64).to_le_bytes());
        let mut bytes = Vec::with_capacity(12 * width);
        for row in texels.chunks(width) {
            bytes.clear();
            for t in row {
                for c in t.to_array() {
                    bytes.extend_from_slice(&c.to_bits().to_le_bytes());
                }
            }
            h.write(&bytes);
        }
        Ok(EnvMap {
            width,
            height,
            texels,
            hash: h.finish(),
            integrals: Mutex::new(None),
        })
    }

    /// Read an EXR file's first RGB layer (half or float; alpha, if any, is ignored), at most
    /// [`crate::input::Limit::Image`] bytes; the error says what is wrong (without the path).
    pub fn read_exr(path: &Path) -> Result<EnvMap, String> {
        use exr::prelude::*;
        let bytes = crate::input::read(path, crate::input::Limit::Image).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                "does not exist (relative paths resolve against the scene file's folder)"
                    .to_string()
            } else {
                e.to_string()
            }
        })?;
        // The size first, so that a huge data window is refused before it is allocated.
        let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false)
            .map_err(|e| format!("is not a readable EXR file ({e})"))?;
        let size = meta
            .headers
            .first()
            .map(|h| h.layer_size)
            .ok_or("is an EXR file without a layer")?;
        if size.width() > MAX_WIDTH || size.height() > MAX_WIDTH / 2 {
            return Err(format!(
                "is {} × {} texels, larger than the {MAX_WIDTH} × {} nephele reads; scale it down",
                size.width(),
                size.height(),
                MAX_WIDTH / 2
            ));
        }
        let image = read()
            .no_deep_data()
            .largest_resolution_level()
            .rgba_channels(
                |res, _| (res.width(), vec![Vec3::ZERO; res.width() * res.height()]),
                |(w, px): &mut (usize, Vec<Vec3>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                    px[pos.y() * *w + pos.x()] = Vec3::new(r, g, b);
                },
            )
            .first_valid_layer()
            .all_attributes()
            .from_buffered(std::io::Cursor::new(&bytes))
            .map_err(|e| format!("is not an EXR file with R, G and B channels ({e})"))?;
        let layer = image.layer_data;
        let (w, h) = (layer.size.width(), layer.size.height());
        EnvMap::from_texels(w, h, layer.channel_data.pixels.1)
    }

    /// Width in texels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height in texels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The texels, row-major, row 0 at the top.
    pub fn texels(&self) -> &[Vec3] {
        &self.texels
    }

    /// A hash of the map's size and texels (what a frame's provenance keys the sky by).
    pub fn content_hash(&self) -> u64 {
        self.hash
    }

    /// Radiance toward the unit direction `d` of the map's own frame (no rotation): the
    /// texels interpolated bilinearly (the module doc's convention).
    pub fn lookup(&self, d: Vec3) -> Vec3 {
        let (w, h) = (self.width, self.height);
        let phi = d.x.atan2(-d.z).rem_euclid(2.0 * PI);
        let theta = d.y.clamp(-1.0, 1.0).acos();
        let fx = phi / (2.0 * PI) * w as f32 - 0.5;
        let fy = (theta / PI * (h - 1) as f32).clamp(0.0, (h - 1) as f32);
        let x0f = fx.floor();
        let wx = fx - x0f;
        let x0 = (x0f as i64).rem_euclid(w as i64) as usize;
        let x1 = (x0 + 1) % w;
        let y0 = (fy.floor() as usize).min(h - 2);
        let wy = fy - y0 as f32;
        let t = |y: usize, x: usize| self.texels[y * w + x];
        (t(y0, x0) * (1.0 - wx) + t(y0, x1) * wx) * (1.0 - wy)
            + (t(y0 + 1, x0) * (1.0 - wx) + t(y0 + 1, x1) * wx) * wy
    }

    /// The integrals the sky's shading uses, with the map turned by `rotate_deg` about +Y
    /// (computed on first use for a rotation, then kept).
    pub(crate) fn integrals(&self, rotate_deg: f32) -> Arc<EnvIntegrals> {
        let key = rotate_deg.to_bits();
        let mut cached = self.integrals.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((k, i)) = cached.as_ref()
            && *k == key
        {
            return Arc::clone(i);
        }
        let i = Arc::new(self.integrate(rotate_deg));
        *cached = Some((key, Arc::clone(&i)));
        i
    }

    /// A quadrature of the map at least as fine as its texels: columns `N_x = W·s` at the
    /// texel centres' spacing, rows `(H − 1)·s + 1` from pole to pole (at `s = 1` exactly the
    /// texels, each weighted by its solid angle), `s` the least with `N_x ≥` [`MIN_QUAD_COLS`].
    fn integrate(&self, rotate_deg: f32) -> EnvIntegrals {
        let s = MIN_QUAD_COLS.div_ceil(self.width).clamp(1, 64);
        let nx = self.width * s;
        let ny = (self.height - 1) * s + 1;
        let d_theta = PI / (ny - 1) as f32;
        let d_phi = 2.0 * PI / nx as f32;
        let cells = directions();
        /// One row's sums: cells, table bins (sum, solid angle), hemispheres (sum, solid angle).
        struct Sums {
            cells: [Vec3; SKY_DIRECTIONS],
            bins: Vec<(Vec3, f32)>,
            upper: (Vec3, f32),
            lower: (Vec3, f32),
        }
        let rows: Vec<Sums> = (0..ny)
            .into_par_iter()
            .map(|k| {
                let mut out = Sums {
                    cells: [Vec3::ZERO; SKY_DIRECTIONS],
                    bins: vec![(Vec3::ZERO, 0.0); TABLE_ROWS * TABLE_COLS],
                    upper: (Vec3::ZERO, 0.0),
                    lower: (Vec3::ZERO, 0.0),
                };
                let theta = k as f32 * d_theta;
                let lo = (theta - 0.5 * d_theta).max(0.0);
                let hi = (theta + 0.5 * d_theta).min(PI);
                let omega = d_phi * (lo.cos() - hi.cos());
                let (st, ct) = theta.sin_cos();
                for i in 0..nx {
                    let phi = (i as f32 + 0.5) * d_phi;
                    let (sp, cp) = phi.sin_cos();
                    let m = Vec3::new(st * sp, ct, -st * cp);
                    let l = self.lookup(m) * omega;
                    let d = to_world(m, rotate_deg);
                    let mut best = (f32::NEG_INFINITY, 0);
                    for (c, dir) in cells.iter().enumerate() {
                        let dot = Vec3::from(*dir).dot(d);
                        if dot > best.0 {
                            best = (dot, c);
                        }
                    }
                    out.cells[best.1] += l;
                    let row =
                        (((d.y + 1.0) * 0.5 * TABLE_ROWS as f32) as usize).min(TABLE_ROWS - 1);
                    let az = d.z.atan2(d.x).rem_euclid(2.0 * PI);
                    let col = ((az / (2.0 * PI) * TABLE_COLS as f32) as usize).min(TABLE_COLS - 1);
                    let bin = &mut out.bins[row * TABLE_COLS + col];
                    bin.0 += l;
                    bin.1 += omega;
                    // A row on the horizon is half above, half below.
                    let up = if d.y > 0.0 {
                        1.0
                    } else if d.y < 0.0 {
                        0.0
                    } else {
                        0.5
                    };
                    out.upper.0 += l * up;
                    out.upper.1 += omega * up;
                    out.lower.0 += l * (1.0 - up);
                    out.lower.1 += omega * (1.0 - up);
                }
                out
            })
            .collect();
        // Summed in row order: the same bits on every run.
        let mut cell_sum = [Vec3::ZERO; SKY_DIRECTIONS];
        let mut bins = vec![(Vec3::ZERO, 0.0f32); TABLE_ROWS * TABLE_COLS];
        let (mut upper, mut lower) = ((Vec3::ZERO, 0.0f32), (Vec3::ZERO, 0.0f32));
        for r in &rows {
            for (a, b) in cell_sum.iter_mut().zip(&r.cells) {
                *a += *b;
            }
            for (a, b) in bins.iter_mut().zip(&r.bins) {
                a.0 += b.0;
                a.1 += b.1;
            }
            upper = (upper.0 + r.upper.0, upper.1 + r.upper.1);
            lower = (lower.0 + r.lower.0, lower.1 + r.lower.1);
        }
        let table = bins
            .iter()
            .enumerate()
            .map(|(k, &(sum, omega))| {
                if omega > 0.0 {
                    sum / omega
                } else {
                    // No quadrature point in the bin (not with N_x ≥ 512): its centre.
                    let y = -1.0 + 2.0 * ((k / TABLE_COLS) as f32 + 0.5) / TABLE_ROWS as f32;
                    let az = 2.0 * PI * ((k % TABLE_COLS) as f32 + 0.5) / TABLE_COLS as f32;
                    let r = (1.0 - y * y).max(0.0).sqrt();
                    let d = Vec3::new(r * az.cos(), y, r * az.sin());
                    self.lookup(to_map(d, rotate_deg))
                }
            })
            .collect();
        EnvIntegrals {
            cells: cell_sum,
            table,
            upper_mean: upper.0 / upper.1.max(1e-12),
            lower_mean: lower.0 / lower.1.max(1e-12),
            view: Mutex::new(None),
        }
    }
}

/// The sun split off a map ([`EnvMap::split_sun`]), in the map's own frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapSun {
    /// Unit direction toward the sun (power-weighted mean of its texels' directions).
    pub to_sun: Vec3,
    /// Its irradiance normal to that direction (`Σ (L − L_sky)·Ω` over its texels), RGB.
    pub irradiance: Vec3,
    /// Its texels.
    pub texels: usize,
}

/// How far (degrees) from the brightest texel the sun's texels may lie: a sun's disc, its
/// glare and a bright cloud edge around it, not a second bright region elsewhere.
pub const SUN_MAX_RADIUS_DEG: f32 = 30.0;

/// A texel is the sun's when its luminance exceeds this many times the map's median and a
/// tenth of the brightest texel's, and it joins the brightest texel through such texels.
const SUN_OVER_MEDIAN: f32 = 4.0;

fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

impl EnvMap {
    /// Unit direction of texel `(x, y)`'s centre in the map's frame.
    fn texel_dir(&self, x: usize, y: usize) -> Vec3 {
        let theta = PI * y as f32 / (self.height - 1) as f32;
        let phi = 2.0 * PI * (x as f32 + 0.5) / self.width as f32;
        Vec3::new(
            theta.sin() * phi.sin(),
            theta.cos(),
            -theta.sin() * phi.cos(),
        )
    }

    /// Solid angle of texel row `y` (rows are the poles' and the bands between them).
    fn texel_solid_angle(&self, y: usize) -> f32 {
        let d = PI / (self.height - 1) as f32;
        let theta = y as f32 * d;
        let (lo, hi) = ((theta - 0.5 * d).max(0.0), (theta + 0.5 * d).min(PI));
        2.0 * PI / self.width as f32 * (lo.cos() - hi.cos())
    }

    /// The map's sun split off: the region of texels around the brightest one that are far
    /// brighter than the map (over [`SUN_OVER_MEDIAN`] × its median luminance and a tenth of
    /// the brightest texel, joined to it, within [`SUN_MAX_RADIUS_DEG`]) loses what exceeds the
    /// sky around it (the mean of the texels bordering the region, per channel), and that
    /// excess becomes a directional light. Returns the map without it and the sun, or `None`
    /// when no texel stands out so (an overcast map).
    pub fn split_sun(&self) -> Option<(EnvMap, MapSun)> {
        let (w, h) = (self.width, self.height);
        let lum: Vec<f32> = self.texels.iter().map(|&c| luminance(c)).collect();
        let mut sorted = lum.clone();
        let mid = sorted.len() / 2;
        let median = *sorted.select_nth_unstable_by(mid, f32::total_cmp).1;
        let (peak, &peak_lum) = lum.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
        let threshold = (SUN_OVER_MEDIAN * median).max(0.1 * peak_lum);
        if !(peak_lum > threshold && peak_lum > 0.0) {
            return None;
        }
        let center = self.texel_dir(peak % w, peak / w);
        let cos_max = SUN_MAX_RADIUS_DEG.to_radians().cos();
        // Flood fill from the peak (8 neighbours, wrapping across the left and right edges).
        let mut in_sun = vec![false; w * h];
        let mut border = vec![false; w * h];
        let mut stack = vec![peak];
        in_sun[peak] = true;
        while let Some(k) = stack.pop() {
            let (x, y) = ((k % w) as i64, (k / w) as i64);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let ny = y + dy;
                    if ny < 0 || ny >= h as i64 {
                        continue;
                    }
                    let nx = (x + dx).rem_euclid(w as i64);
                    let n = ny as usize * w + nx as usize;
                    if in_sun[n] {
                        continue;
                    }
                    let near = self.texel_dir(nx as usize, ny as usize).dot(center) >= cos_max;
                    if lum[n] > threshold && near {
                        in_sun[n] = true;
                        border[n] = false;
                        stack.push(n);
                    } else {
                        border[n] = true;
                    }
                }
            }
        }
        let (mut sky, mut count) = (Vec3::ZERO, 0usize);
        for (k, &b) in border.iter().enumerate() {
            if b && !in_sun[k] {
                sky += self.texels[k];
                count += 1;
            }
        }
        let sky = if count > 0 {
            sky / count as f32
        } else {
            Vec3::ZERO
        };
        let mut texels = self.texels.clone();
        let (mut irradiance, mut toward, mut n) = (Vec3::ZERO, Vec3::ZERO, 0);
        for (k, t) in texels.iter_mut().enumerate() {
            if !in_sun[k] {
                continue;
            }
            let rest = t.min(sky);
            let excess = (*t - rest) * self.texel_solid_angle(k / w);
            irradiance += excess;
            toward += self.texel_dir(k % w, k / w) * luminance(excess);
            *t = rest;
            n += 1;
        }
        let to_sun = toward.try_normalize()?;
        let rest = EnvMap::from_texels(w, h, texels).ok()?;
        Some((
            rest,
            MapSun {
                to_sun,
                irradiance,
                texels: n,
            },
        ))
    }
}

/// The world direction `d` in the frame of a map turned by `rotate_deg` about +Y:
/// `R_y(−rotate) d`.
pub fn to_map(d: Vec3, rotate_deg: f32) -> Vec3 {
    let (s, c) = rotate_deg.to_radians().sin_cos();
    Vec3::new(d.x * c - d.z * s, d.y, d.x * s + d.z * c)
}

/// The map's direction `m` in the world, the map turned by `rotate_deg` about +Y:
/// `R_y(rotate) m`.
pub fn to_world(m: Vec3, rotate_deg: f32) -> Vec3 {
    let (s, c) = rotate_deg.to_radians().sin_cos();
    Vec3::new(m.x * c + m.z * s, m.y, -m.x * s + m.z * c)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(w: usize, f: impl Fn(usize, usize) -> Vec3) -> EnvMap {
        let h = w / 2;
        EnvMap::from_texels(w, h, (0..w * h).map(|k| f(k % w, k / w)).collect()).unwrap()
    }

    #[test]
    fn lookup_follows_the_mitsuba_convention_and_the_rotation() {
        // Texel value = its column's azimuth marker: column i at u = (i + ½)/W.
        let m = map(16, |x, y| Vec3::new(x as f32, y as f32, 1.0));
        // u = ¼ + ½/16 (column 4's centre) is +X-ish; the equator row is between rows 3 and 4.
        let phi = 2.0 * PI * (4.5 / 16.0);
        let d = Vec3::new(phi.sin(), 0.0, -phi.cos());
        let v = m.lookup(d);
        assert!((v.x - 4.0).abs() < 1e-4 && (v.y - 3.5).abs() < 1e-4, "{v}");
        // Straight up is row 0, straight down row 7.
        assert!(m.lookup(Vec3::Y).y.abs() < 1e-5);
        assert!((m.lookup(Vec3::NEG_Y).y - 7.0).abs() < 1e-5);
        // −Z is the left edge (between the last column and the first).
        assert!((m.lookup(Vec3::NEG_Z).x - 7.5).abs() < 1e-4);
        // Rotated 90°: what the file shows toward +Z is seen toward +X.
        let z = m.lookup(Vec3::Z);
        let x = m.lookup(to_map(Vec3::X, 90.0));
        assert!((z - x).abs().max_element() < 1e-3, "{z} {x}");
    }

    #[test]
    fn integrals_of_a_constant_map_are_its_solid_angles() {
        let c = Vec3::new(0.5, 1.0, 2.0);
        let m = map(8, |_, _| c);
        let i = m.integrals(30.0);
        let total: Vec3 = i.cells.iter().copied().sum();
        assert!(
            (total / (4.0 * PI) - c).abs().max_element() < 1e-4,
            "{total}"
        );
        assert!((i.upper_mean - c).abs().max_element() < 1e-4);
        assert!((i.lower_mean - c).abs().max_element() < 1e-4);
        assert!(i.table.iter().all(|t| (*t - c).abs().max_element() < 1e-4));
        // Face cells hold more solid angle than corners; up and down alike.
        let (up, down) = (i.cells[2].x, i.cells[3].x);
        assert!((up - down).abs() < 1e-3 * up, "{up} {down}");
    }

    #[test]
    fn a_bright_texel_lights_the_cell_it_is_in() {
        // One bright texel toward +X (column W/4, the equator rows): its light goes to the +X
        // cell; rotated by 90° it comes from −Z (R_y(90°) takes +X to −Z).
        let w = 64;
        let m = map(w, |x, y| {
            if x == w / 4 && (y == 15 || y == 16) {
                Vec3::splat(1000.0)
            } else {
                Vec3::ZERO
            }
        });
        let dirs = directions();
        let best = |i: &EnvIntegrals| {
            (0..SKY_DIRECTIONS)
                .max_by(|&a, &b| i.cells[a].x.total_cmp(&i.cells[b].x))
                .unwrap()
        };
        assert_eq!(Vec3::from(dirs[best(&m.integrals(0.0))]), Vec3::X);
        assert_eq!(Vec3::from(dirs[best(&m.integrals(90.0))]), Vec3::NEG_Z);
    }

    #[test]
    fn a_bright_patch_splits_off_as_a_sun_with_its_power_and_direction() {
        // A grey sky with a 10-texel-wide bright patch around +X on the equator.
        let w = 128;
        let base = Vec3::new(0.2, 0.3, 0.5);
        let m = map(w, |x, y| {
            let patch = (28..36).contains(&x) && (28..36).contains(&y);
            base + if patch { Vec3::splat(50.0) } else { Vec3::ZERO }
        });
        let (rest, sun) = m.split_sun().expect("a sun");
        assert_eq!(sun.texels, 64);
        // The sun's power plus the rest's is the whole map's (the rest keeps the sky's level).
        let total = |m: &EnvMap| m.integrals(0.0).cells.iter().copied().sum::<Vec3>();
        let (all, left) = (total(&m), total(&rest));
        let err = ((left + sun.irradiance - all) / all).abs().max_element();
        assert!(err < 0.01, "{all} vs {left} + {}", sun.irradiance);
        assert!(
            rest.texels()
                .iter()
                .all(|t| (*t - base).abs().max_element() < 1e-6)
        );
        // Toward the patch's centre: column 32 (u = ¼, +X), row 31.5 of 63 (the equator).
        assert!(sun.to_sun.dot(Vec3::X) > 0.999, "{}", sun.to_sun);
        // A map without a bright region has no sun.
        assert!(
            map(16, |x, _| base * (1.0 + x as f32 / 16.0))
                .split_sun()
                .is_none()
        );
    }

    #[test]
    fn maps_that_are_not_lat_long_or_hold_bad_texels_are_refused() {
        let e = EnvMap::from_texels(6, 2, vec![Vec3::ONE; 12]).unwrap_err();
        assert!(e.contains("twice as wide"), "{e}");
        let mut t = vec![Vec3::ONE; 8];
        t[5] = Vec3::new(1.0, f32::NAN, 1.0);
        let e = EnvMap::from_texels(4, 2, t.clone()).unwrap_err();
        assert!(e.contains("(x 1, y 1)") && e.contains("finite"), "{e}");
        t[5] = Vec3::new(1.0, -1.0, 1.0);
        assert!(EnvMap::from_texels(4, 2, t).is_err());
    }
}
