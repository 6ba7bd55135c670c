//! Seed-free 3-D gradient noise (Perlin 2002, "Improving Noise") and its fractal sum (fBm).
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

/// Lacunarity of [`fbm`]: slightly off 2 so octave lattices do not line up.
pub const LACUNARITY: f32 = 2.03;

/// Billow octave: `1.8·|n| − 0.4` of gradient noise `n` (mean |n| ≈ 0.22, so mean ≈ 0):
/// rounded bumps separated by sharp creases where `n` crosses zero — the cauliflower puffs of
/// cumulus when added to the field.
#[inline]
pub fn billow(p: Vec3A) -> f32 {
    1.8 * gradient_noise(p).abs() - 0.4
}

/// Fractal sum of [`billow`] octaves with gain ½ and lacunarity [`LACUNARITY`], each octave
/// shifted, normalised by the total amplitude: mean ≈ 0, about `[−0.4, 1.2]`, most values in
/// `[−0.4, 0.8]`. `octaves = 0` gives 0.
#[inline]
pub fn fbm(p: Vec3A, octaves: u32) -> f32 {
    let mut sum = 0.0;
    let mut amp = 1.0;
    let mut norm = 0.0;
    let mut q = p;
    for o in 0..octaves {
        sum += amp * billow(q);
        norm += amp;
        amp *= 0.5;
        // Shift each octave so that the lattice zeros at the origin do not coincide.
        q = q * LACUNARITY + Vec3A::new(17.31, -9.77, 5.13) * (o + 1) as f32;
    }
    if norm > 0.0 { sum / norm } else { 0.0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_zero_on_lattice_bounded_and_varied() {
        assert_eq!(gradient_noise(Vec3A::new(3.0, -2.0, 7.0)), 0.0);
        let (mut lo, mut hi, mut sum, mut sq) = (f32::MAX, f32::MIN, 0.0f64, 0.0f64);
        let n = 20_000;
        for i in 0..n {
            let t = i as f32;
            let p = Vec3A::new(t * 0.137, (t * 0.071).sin() * 40.0, t * 0.011);
            let v = fbm(p, 4);
            lo = lo.min(v);
            hi = hi.max(v);
            sum += v as f64;
            sq += (v * v) as f64;
        }
        let mean = sum / n as f64;
        let sd = (sq / n as f64 - mean * mean).sqrt();
        assert!(lo >= -0.4 && hi < 1.3, "range {lo}..{hi}");
        assert!(mean.abs() < 0.05, "mean {mean}");
        assert!(sd > 0.15 && sd < 0.5, "sd {sd}");
    }

    #[test]
    fn noise_is_continuous() {
        let p = Vec3A::new(1.234, 5.678, -9.1);
        let e = Vec3A::splat(1e-4);
        assert!((fbm(p, 4) - fbm(p + e, 4)).abs() < 1e-2);
    }
}
