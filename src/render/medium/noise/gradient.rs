//! The portable gradient noise (Perlin 2002, "Improving Noise"): the lattice hash, the gradient
//! dot product, the fade curve and the one-corner-at-a-time reference every vectorised version
//! must equal bit for bit.

use glam::Vec3A;

/// Multipliers of the lattice hash, one per axis.
pub(crate) const HASH_AXES: [u32; 3] = [0x8DA6_B343, 0xD816_3841, 0xCB1A_B31F];

/// The lattice hash's mixing rounds (a few multiply-xorshifts, well mixed in the low bits) of
/// `h = i·A ^ j·B ^ k·C`.
#[inline]
pub(crate) fn mix(mut h: u32) -> u32 {
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    h = h.wrapping_mul(0x297A_2D39);
    h ^ (h >> 15)
}

/// Lattice hash of an integer point.
#[inline]
fn hash3(i: i32, j: i32, k: i32) -> u32 {
    let [a, b, c] = HASH_AXES;
    mix((i as u32).wrapping_mul(a) ^ (j as u32).wrapping_mul(b) ^ (k as u32).wrapping_mul(c))
}

/// Dot product of the offset `(x, y, z)` with one of Perlin's 12 edge gradients (16 entries,
/// four repeated), chosen by the hash.
#[inline]
pub(crate) fn grad(h: u32, x: f32, y: f32, z: f32) -> f32 {
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
pub(crate) fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

#[inline]
pub(crate) fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + t * (b - a)
}

/// [`super::gradient_noise`] one corner at a time (the reference the SIMD version must equal).
#[inline]
pub(crate) fn gradient_noise_scalar(p: Vec3A) -> f32 {
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
