//! The quantized blob layout: centres as 3 × u16 fixed point in the centres' bounding box,
//! influence radii as 3 × u16 on a log scale between the smallest and largest radius, `|B|` as
//! u16 up to the largest `|B|`, rotations as a smallest-three quaternion in 40 bits (2-bit index
//! of the dropped largest component, three 12-bit components in `[−1/√2, 1/√2]`).
//!
//! The ranges are stored in the header as f32, and the quantizer works from those f32 values, so
//! encoder and decoder agree exactly.

use glam::{DQuat, DVec3};

use super::wire::{Reader, Writer};
use super::{Packed, QUANTIZED_BLOB_BYTES, QUANTIZED_SPHERE_BYTES};
use crate::blobby::ModelError;

/// Largest 16-bit code.
const Q16: f64 = u16::MAX as f64;
/// Largest 12-bit code.
const Q12: f64 = 4095.0;

/// The header ranges every quantized value is relative to.
#[derive(Clone, Copy, Debug)]
pub(super) struct Ranges {
    /// Centres' bounding box.
    lo: DVec3,
    hi: DVec3,
    /// `ln r` range of the positive influence radii.
    log_r_lo: f64,
    log_r_hi: f64,
    /// Largest `|B|`.
    b_max: f64,
}

/// Round through f32, as the header stores it.
fn f32_round(x: f64) -> f64 {
    x as f32 as f64
}

impl Ranges {
    fn of(blobs: &[Packed]) -> Ranges {
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        let (mut lr_lo, mut lr_hi, mut b_max) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
        for p in blobs.iter().filter(|p| p.center.is_finite()) {
            lo = lo.min(p.center);
            hi = hi.max(p.center);
        }
        for p in blobs.iter().filter(|p| is_live(p)) {
            for r in p.radii.to_array() {
                lr_lo = lr_lo.min(r.ln());
                lr_hi = lr_hi.max(r.ln());
            }
            b_max = b_max.max(p.b.abs());
        }
        if lo.x > hi.x {
            (lo, hi) = (DVec3::ZERO, DVec3::ZERO);
        }
        if lr_lo > lr_hi {
            (lr_lo, lr_hi) = (0.0, 0.0);
        }
        Ranges {
            lo: lo.as_vec3().as_dvec3(),
            hi: hi.as_vec3().as_dvec3(),
            log_r_lo: f32_round(lr_lo),
            log_r_hi: f32_round(lr_hi),
            b_max: f32_round(b_max),
        }
    }

    fn write(&self, w: &mut Writer) {
        w.vec3(self.lo);
        w.vec3(self.hi);
        w.f32(self.log_r_lo);
        w.f32(self.log_r_hi);
        w.f32(self.b_max);
    }

    /// Read and check the ranges (finite, ordered).
    pub fn read(r: &mut Reader) -> Result<Ranges, ModelError> {
        let at = r.pos();
        let q = Ranges {
            lo: r.vec3("quantization centre box")?,
            hi: r.vec3("quantization centre box")?,
            log_r_lo: r.f32("quantization radius range")?,
            log_r_hi: r.f32("quantization radius range")?,
            b_max: r.f32("quantization B range")?,
        };
        let finite = q.lo.is_finite()
            && q.hi.is_finite()
            && q.log_r_lo.is_finite()
            && q.log_r_hi.is_finite()
            && q.b_max.is_finite();
        if !finite || q.lo.cmpgt(q.hi).any() || q.log_r_lo > q.log_r_hi || q.b_max < 0.0 {
            return Err(r.invalid(at, "quantization ranges are not finite or not ordered"));
        }
        Ok(q)
    }

    /// Decode one blob.
    pub fn read_blob(&self, r: &mut Reader, isotropic: bool) -> Result<Packed, ModelError> {
        let mut center = DVec3::ZERO;
        for k in 0..3 {
            center[k] = dequantize(r.u16("blob centre")?, self.lo[k], self.hi[k]);
        }
        let rotation = if isotropic {
            DQuat::IDENTITY
        } else {
            let mut b = [0u8; 8];
            for x in &mut b[..5] {
                *x = r.u8("blob rotation")?;
            }
            unpack_rotation(u64::from_le_bytes(b))
        };
        let mut radii = DVec3::ZERO;
        for k in 0..if isotropic { 1 } else { 3 } {
            let lr = dequantize(r.u16("blob radii")?, self.log_r_lo, self.log_r_hi);
            radii[k] = lr.exp();
        }
        if isotropic {
            radii = DVec3::splat(radii.x);
        }
        let b = dequantize(r.u16("blob strength B")?, 0.0, self.b_max);
        Ok(Packed {
            center,
            rotation,
            radii,
            b,
        })
    }
}

/// A blob that contributes to the field: positive finite radii and non-zero finite `B`.
fn is_live(p: &Packed) -> bool {
    p.radii.is_finite() && p.radii.min_element() > 0.0 && p.b.is_finite() && p.b != 0.0
}

/// `x` in `[lo, hi]` to a 16-bit code (clamped; 0 for an empty range or NaN).
fn quantize(x: f64, lo: f64, hi: f64) -> u16 {
    if hi > lo {
        ((x - lo) / (hi - lo) * Q16).round().clamp(0.0, Q16) as u16
    } else {
        0
    }
}

fn dequantize(q: u16, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * (q as f64 / Q16)
}

// The layouts' sizes, as written below.
const _: () = assert!(QUANTIZED_BLOB_BYTES == 6 + 5 + 6 + 2 && QUANTIZED_SPHERE_BYTES == 6 + 2 + 2);

/// Write the ranges, then every blob. Dead blobs (zero radius or `B`) are written with `B = 0`.
pub(super) fn write(w: &mut Writer, blobs: &[Packed], isotropic: bool) {
    let q = Ranges::of(blobs);
    q.write(w);
    for p in blobs {
        for k in 0..3 {
            w.u16(quantize(p.center[k], q.lo[k], q.hi[k]));
        }
        if !isotropic {
            w.bytes(&pack_rotation(p.rotation).to_le_bytes()[..5]);
        }
        let live = is_live(p);
        for k in 0..if isotropic { 1 } else { 3 } {
            let lr = if live { p.radii[k].ln() } else { q.log_r_lo };
            w.u16(quantize(lr, q.log_r_lo, q.log_r_hi));
        }
        let b = if live { p.b.abs() } else { 0.0 };
        w.u16(quantize(b, 0.0, q.b_max));
    }
}

/// Smallest-three: drop the largest-magnitude component (made positive), keep the other three
/// in `[−1/√2, 1/√2]` as 12-bit codes. Bits 0–1: dropped index; bits 2+12k..: component k.
fn pack_rotation(q: DQuat) -> u64 {
    let q = q.normalize();
    let c = q.to_array();
    let big = (0..4)
        .max_by(|&i, &j| c[i].abs().total_cmp(&c[j].abs()))
        .unwrap_or(3);
    let sign = if c[big] < 0.0 { -1.0 } else { 1.0 };
    let mut bits = big as u64;
    let mut k = 0;
    for (i, &v) in c.iter().enumerate() {
        if i != big {
            let unit = (v * sign * std::f64::consts::SQRT_2 + 1.0) * 0.5;
            let code = (unit * Q12).round().clamp(0.0, Q12) as u64;
            bits |= code << (2 + 12 * k);
            k += 1;
        }
    }
    bits
}

fn unpack_rotation(bits: u64) -> DQuat {
    let big = (bits & 3) as usize;
    let mut c = [0.0f64; 4];
    let mut k = 0;
    let mut sum = 0.0;
    for (i, ci) in c.iter_mut().enumerate() {
        if i != big {
            let code = (bits >> (2 + 12 * k)) & 0xfff;
            *ci = ((code as f64 / Q12) * 2.0 - 1.0) / std::f64::consts::SQRT_2;
            sum += *ci * *ci;
            k += 1;
        }
    }
    c[big] = (1.0 - sum).max(0.0).sqrt();
    let q = DQuat::from_array(c).normalize();
    if q.w < 0.0 { -q } else { q }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_packing_is_within_a_few_thousandths() {
        for i in 0..500 {
            let t = i as f64 * 0.377;
            let q = DQuat::from_euler(glam::EulerRot::ZYX, t, (t * 1.7).sin() * 3.0, t * t);
            let back = unpack_rotation(pack_rotation(q));
            let angle = q.angle_between(back);
            assert!(angle < 1.5e-3, "rotation {i}: error {angle} rad");
        }
    }

    #[test]
    fn scalars_round_trip_to_half_a_step() {
        for i in 0..=100 {
            let x = -2.0 + i as f64 * 0.05;
            let y = dequantize(quantize(x, -2.0, 3.0), -2.0, 3.0);
            assert!((x - y).abs() <= 0.5 * 5.0 / Q16 + 1e-12);
        }
        assert_eq!(quantize(f64::NAN, 0.0, 1.0), 0);
        assert_eq!(quantize(5.0, 1.0, 1.0), 0);
    }
}
