//! Seed-free 3-D gradient noise (Perlin 2002, "Improving Noise") and the cloud edge erosion
//! built from it (billows at the low octaves, wisps at the high ones).
//!
//! In: a point in noise space (the renderer maps each blob's local frame there, with a seeded
//! per-blob offset, so the seed enters through the offset and the lattice hash is fixed).
//! Out: values in about `[−1, 1]`. Pure functions: identical on every thread and platform
//! (only `+ − × floor` on f32, no transcendental functions).

use glam::Vec3A;

/// Lattice hash of an integer point: a few multiply-xorshift rounds, well mixed in the low bits.
#[inline]
fn hash3(i: i32, j: i32, k: i32) -> u32 {
    let mut h = (i as u32).wrapping_mul(0x8DA6_B343)
        ^ (j as u32).wrapping_mul(0xD816_3841)
        ^ (k as u32).wrapping_mul(0xCB1A_B31F);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297A_2D39);
    h ^ (h >> 15)
}

/// Dot product of the offset `(x, y, z)` with one of Perlin's 12 edge gradients (16 entries,
/// four repeated), chosen by the hash.
#[inline]
fn grad(h: u32, x: f32, y: f32, z: f32) -> f32 {
    let h = h & 15;
    let u = if h < 8 { x } else { y };
    let v = if h < 4 {
        y
    } else if h == 12 || h == 14 {
        x
    } else {
        z
    };
    (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
}

/// Quintic fade `6t⁵ − 15t⁴ + 10t³` (C² continuous lattice blending).
#[inline]
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

/// Improved Perlin gradient noise at `p`: zero on the integer lattice, about `[−1, 1]`.
#[inline]
pub fn gradient_noise(p: Vec3A) -> f32 {
    let f = p.floor();
    let (i, j, k) = (f.x as i32, f.y as i32, f.z as i32);
    let r = p - f;
    let (x, y, z) = (r.x, r.y, r.z);
    let (u, v, w) = (fade(x), fade(y), fade(z));
    let c = |di: i32, dj: i32, dk: i32| {
        grad(
            hash3(i + di, j + dj, k + dk),
            x - di as f32,
            y - dj as f32,
            z - dk as f32,
        )
    };
    let x00 = lerp(c(0, 0, 0), c(1, 0, 0), u);
    let x10 = lerp(c(0, 1, 0), c(1, 1, 0), u);
    let x01 = lerp(c(0, 0, 1), c(1, 0, 1), u);
    let x11 = lerp(c(0, 1, 1), c(1, 1, 1), u);
    lerp(lerp(x00, x10, v), lerp(x01, x11, v), w)
}

/// Frequency ratio between erosion octaves: slightly off 2 so octave lattices do not line up.
pub const LACUNARITY: f32 = 2.03;

/// Shift between octaves (noise units), so the lattice zeros at the origin do not coincide.
const OCTAVE_SHIFT: Vec3A = Vec3A::new(17.31, -9.77, 5.13);

/// Direction each octave drifts along with the evolution phase (different per octave, so the
/// sum changes shape instead of sliding as a whole).
const EVOLVE_DIR: [Vec3A; 3] = [
    Vec3A::new(0.0, 1.0, 0.0),
    Vec3A::new(0.6, -0.8, 0.0),
    Vec3A::new(-0.48, 0.0, 0.877),
];

/// Billow height of gradient noise `n`: `x(2 − x)` with `x = min(1, 2|n|)` — 0 on the sheets
/// where `n` crosses zero (the creases between puffs), rising steeply and rounding off on top
/// (the puffs of cumulus).
#[inline]
pub fn billow(p: Vec3A) -> f32 {
    let x = (2.0 * gradient_noise(p).abs()).min(1.0);
    x * (2.0 - x)
}

/// Most octaves [`Octaves`] holds.
pub const MAX_OCTAVES: usize = 8;

/// The per-frame constants of [`erosion`]: each octave's evolution drift and weight, and their
/// total weight, computed once instead of at every sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Octaves {
    n: usize,
    drift: [Vec3A; MAX_OCTAVES],
    weight: [f32; MAX_OCTAVES],
    norm: f32,
}

impl Octaves {
    /// `octaves` (at most [`MAX_OCTAVES`]) at evolution `phase`: each octave moves along its
    /// own direction (slow evolution; 0 = frozen). Octave 0 and 1 weigh 1 and ½, the wisps
    /// from octave 2 on 0.3, 0.15, …
    pub fn new(octaves: u32, phase: f32) -> Self {
        let n = (octaves as usize).min(MAX_OCTAVES);
        let (mut drift, mut weight) = ([Vec3A::ZERO; MAX_OCTAVES], [0.0; MAX_OCTAVES]);
        let (mut norm, mut wisp) = (0.0, 0.3f32);
        for o in 0..n {
            drift[o] = EVOLVE_DIR[o.min(2)] * (phase * (1.0 + 0.5 * o as f32));
            weight[o] = match o {
                0 => 1.0,
                1 => 0.5,
                _ => {
                    wisp *= 0.5;
                    2.0 * wisp
                }
            };
            norm += weight[o];
        }
        Octaves {
            n,
            drift,
            weight,
            norm,
        }
    }
}

/// Edge erosion in `[0, 1]` at noise point `p`: 0 on the tops of the billows, 1 deep in the
/// creases. Octave 0 and 1 are [`billow`]s, octave 2 and above wispy plain gradient noise
/// `½ + ½n` (weights and drifts in [`Octaves`]); no octaves give 0 (no erosion).
#[inline]
pub fn erosion(p: Vec3A, oct: &Octaves) -> f32 {
    let mut sum = 0.0;
    let mut q = p;
    for o in 0..oct.n {
        let h = if o < 2 {
            billow(q + oct.drift[o])
        } else {
            0.5 + 0.5 * gradient_noise(q + oct.drift[o])
        };
        sum += oct.weight[o] * h;
        q = q * LACUNARITY + OCTAVE_SHIFT * (o + 1) as f32;
    }
    if oct.norm > 0.0 {
        (1.0 - sum / oct.norm).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_zero_on_lattice_and_erosion_bounded_and_varied() {
        assert_eq!(gradient_noise(Vec3A::new(3.0, -2.0, 7.0)), 0.0);
        let (mut lo, mut hi, mut sum, mut sq) = (f32::MAX, f32::MIN, 0.0f64, 0.0f64);
        let n = 20_000;
        for i in 0..n {
            let t = i as f32;
            let p = Vec3A::new(t * 0.137, (t * 0.071).sin() * 40.0, t * 0.011);
            let v = erosion(p, &Octaves::new(3, 0.0));
            lo = lo.min(v);
            hi = hi.max(v);
            sum += v as f64;
            sq += (v * v) as f64;
        }
        let mean = sum / n as f64;
        let sd = (sq / n as f64 - mean * mean).sqrt();
        assert!(lo >= 0.0 && hi <= 1.0 && hi - lo > 0.6, "range {lo}..{hi}");
        assert!(mean > 0.2 && mean < 0.6, "mean {mean}");
        assert!(sd > 0.08 && sd < 0.4, "sd {sd}");
        assert_eq!(erosion(Vec3A::ONE, &Octaves::new(0, 0.0)), 0.0);
    }

    #[test]
    fn erosion_is_continuous_and_evolves() {
        let p = Vec3A::new(1.234, 5.678, -9.1);
        let e = Vec3A::splat(1e-4);
        assert!(
            (erosion(p, &Octaves::new(3, 0.0)) - erosion(p + e, &Octaves::new(3, 0.0))).abs()
                < 1e-2
        );
        assert!(
            (erosion(p, &Octaves::new(3, 0.0)) - erosion(p, &Octaves::new(3, 1e-4))).abs() < 1e-2
        );
        assert_ne!(
            erosion(p, &Octaves::new(3, 0.0)),
            erosion(p, &Octaves::new(3, 0.37))
        );
    }
}
