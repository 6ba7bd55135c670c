//! Gradient noise at eight points at once, one point per AVX2 lane: what the billows' octaves
//! need when they are evaluated ahead of their use ([`crate::render::medium::noise::Billows`]
//! fills the lanes with the octaves and blobs of one sample).
//!
//! [`crate::render::medium::noise::simd`] puts the eight corners of one point in the lanes and
//! blends them across lanes; here each lane is a whole point, so the corners are eight passes of
//! the same lane-wise operations and the blend is lane-wise too — no shuffles, and the hash's
//! products and the gradients' selects serve eight points each. Every lane does the scalar
//! noise's operations in its order ([`crate::render::medium::noise::gradient::gradient_noise_scalar`]:
//! wrapping products, bit selects, sign flips by XOR, IEEE `+ − ×` and no FMA), so the bits are
//! the same as one point at a time (tested below).

use glam::Vec3A;

/// True when [`gradient_noise8`] runs eight lanes at once on this machine (x86-64 with AVX2);
/// elsewhere it is a loop over the one-point noise, and callers should not evaluate ahead.
#[inline]
pub(crate) fn wide() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Gradient noise at the eight points `(x[i], y[i], z[i])`: the bits of
/// [`crate::render::medium::noise::gradient_noise`] at each.
#[inline]
pub(crate) fn gradient_noise8(x: &[f32; 8], y: &[f32; 8], z: &[f32; 8]) -> [f32; 8] {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            if let Some(v) = unsafe { avx2::gradient_noise8(x, y, z) } {
                return v;
            }
        }
    }
    std::array::from_fn(|i| super::simd::gradient_noise(Vec3A::new(x[i], y[i], z[i])))
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use core::arch::x86_64::*;

    use super::super::gradient::HASH_AXES;
    use super::super::simd::avx2::{grad, mix};

    /// One corner's contribution: [`crate::render::medium::noise::gradient::grad`] of the corner's hash
    /// `hx ^ hy ^ hz` (the axes' products) and the point's offset from it (the one-point AVX2
    /// noise's hash and gradient, here over eight points).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn corner(hx: __m256i, hy: __m256i, hz: __m256i, x: __m256, y: __m256, z: __m256) -> __m256 {
        grad(mix(_mm256_xor_si256(_mm256_xor_si256(hx, hy), hz)), x, y, z)
    }

    /// `6t⁵ − 15t⁴ + 10t³` as [`crate::render::medium::noise::gradient::fade`] forms it.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn fade(t: __m256) -> __m256 {
        let inner = _mm256_add_ps(
            _mm256_mul_ps(
                t,
                _mm256_sub_ps(_mm256_mul_ps(t, _mm256_set1_ps(6.0)), _mm256_set1_ps(15.0)),
            ),
            _mm256_set1_ps(10.0),
        );
        _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(t, t), t), inner)
    }

    /// `a + t·(b − a)`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn lerp(a: __m256, b: __m256, t: __m256) -> __m256 {
        _mm256_add_ps(a, _mm256_mul_ps(t, _mm256_sub_ps(b, a)))
    }

    /// The eight points' noise; `None` when a lattice coordinate lies beyond 2³¹ in magnitude
    /// (or is NaN), where the truncating conversion would differ from the scalar path's
    /// saturating `as i32` (the caller then goes point by point).
    #[target_feature(enable = "avx2")]
    pub(super) fn gradient_noise8(x: &[f32; 8], y: &[f32; 8], z: &[f32; 8]) -> Option<[f32; 8]> {
        // SAFETY: 8 f32 each, unaligned loads and store.
        let (px, py, pz) = unsafe {
            (
                _mm256_loadu_ps(x.as_ptr()),
                _mm256_loadu_ps(y.as_ptr()),
                _mm256_loadu_ps(z.as_ptr()),
            )
        };
        // `+ 0.0` turns the floor of −0.0 into +0.0, as glam's floor (the scalar path's) gives.
        let floor = |p: __m256| {
            _mm256_add_ps(
                _mm256_round_ps::<{ _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC }>(p),
                _mm256_setzero_ps(),
            )
        };
        let (fx, fy, fz) = (floor(px), floor(py), floor(pz));
        let limit = _mm256_set1_ps(2_147_483_648.0);
        let abs = |f: __m256| _mm256_andnot_ps(_mm256_set1_ps(-0.0), f);
        let inside = _mm256_and_ps(
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_LT_OQ>(abs(fx), limit),
                _mm256_cmp_ps::<_CMP_LT_OQ>(abs(fy), limit),
            ),
            _mm256_cmp_ps::<_CMP_LT_OQ>(abs(fz), limit),
        );
        if _mm256_movemask_ps(inside) != 0xff {
            return None;
        }
        let [a, b, c] = HASH_AXES;
        let product = |f: __m256, axis: u32| {
            let h0 = _mm256_mullo_epi32(_mm256_cvttps_epi32(f), _mm256_set1_epi32(axis as i32));
            (h0, _mm256_add_epi32(h0, _mm256_set1_epi32(axis as i32)))
        };
        let (hx0, hx1) = product(fx, a);
        let (hy0, hy1) = product(fy, b);
        let (hz0, hz1) = product(fz, c);
        let (rx, ry, rz) = (
            _mm256_sub_ps(px, fx),
            _mm256_sub_ps(py, fy),
            _mm256_sub_ps(pz, fz),
        );
        let one = _mm256_set1_ps(1.0);
        let (rx1, ry1, rz1) = (
            _mm256_sub_ps(rx, one),
            _mm256_sub_ps(ry, one),
            _mm256_sub_ps(rz, one),
        );
        let (u, v, w) = (fade(rx), fade(ry), fade(rz));
        let x00 = lerp(
            corner(hx0, hy0, hz0, rx, ry, rz),
            corner(hx1, hy0, hz0, rx1, ry, rz),
            u,
        );
        let x10 = lerp(
            corner(hx0, hy1, hz0, rx, ry1, rz),
            corner(hx1, hy1, hz0, rx1, ry1, rz),
            u,
        );
        let x01 = lerp(
            corner(hx0, hy0, hz1, rx, ry, rz1),
            corner(hx1, hy0, hz1, rx1, ry, rz1),
            u,
        );
        let x11 = lerp(
            corner(hx0, hy1, hz1, rx, ry1, rz1),
            corner(hx1, hy1, hz1, rx1, ry1, rz1),
            u,
        );
        let n = lerp(lerp(x00, x10, v), lerp(x01, x11, v), w);
        let mut out = [0.0f32; 8];
        // SAFETY: 8 f32, unaligned store.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), n) };
        Some(out)
    }
}

#[cfg(test)]
mod tests {
    use super::super::gradient::gradient_noise_scalar;
    use super::*;

    #[test]
    fn eight_lanes_have_the_scalar_noises_bits() {
        let mut rng = 0x9e37_79b9u64;
        let mut next = move || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0
        };
        let specials = [
            -0.0,
            0.0,
            -1e-30,
            1.0,
            -1.0,
            3e9,
            -5e9,
            2_147_483_520.0,
            f32::NAN,
        ];
        for n in 0..50_000 {
            let scale = [1.0, 10.0, 300.0, 1e5][n % 4];
            let mut lanes = [[0.0f32; 8]; 3];
            for (k, axis) in lanes.iter_mut().enumerate() {
                for (i, v) in axis.iter_mut().enumerate() {
                    *v = next() * scale;
                    if n % 7 == 0 {
                        *v = v.round();
                    }
                    if n % 13 == 0 && (i + k) % 3 == 0 {
                        *v = specials[(n / 13 + i) % specials.len()];
                    }
                }
            }
            let [x, y, z] = lanes;
            let got = gradient_noise8(&x, &y, &z);
            for i in 0..8 {
                let p = Vec3A::new(x[i], y[i], z[i]);
                assert_eq!(
                    got[i].to_bits(),
                    gradient_noise_scalar(p).to_bits(),
                    "lane {i} at {p}"
                );
            }
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod timing {
    use super::super::simd::{gradient_noise, sse2};
    use super::*;

    #[test]
    #[ignore = "timing: cargo test --release --lib noise_paths -- --ignored --nocapture"]
    fn noise_paths() {
        let pts: Vec<Vec3A> = (0..1_000_000)
            .map(|i| {
                Vec3A::new(
                    i as f32 * 0.0137,
                    (i % 977) as f32 * 0.31,
                    i as f32 * -0.0071,
                )
            })
            .collect();
        let time = |name: &str, f: &dyn Fn(Vec3A) -> f32| {
            let t = std::time::Instant::now();
            let mut s = 0.0;
            for _ in 0..5 {
                for &p in &pts {
                    s += f(p);
                }
            }
            println!(
                "{name}: {:.1} ns ({s})",
                t.elapsed().as_secs_f64() * 1e9 / 5e6
            );
        };
        time("scalar", &|p| {
            super::super::gradient::gradient_noise_scalar(p)
        });
        time("sse2", &|p| sse2::gradient_noise(p));
        time("dispatched", &|p| gradient_noise(p));
        // Eight points a call (one per lane): the time per point.
        let t = std::time::Instant::now();
        let mut s = 0.0;
        for _ in 0..5 {
            for c in pts.chunks_exact(8) {
                let x = std::array::from_fn(|i| c[i].x);
                let y = std::array::from_fn(|i| c[i].y);
                let z = std::array::from_fn(|i| c[i].z);
                s += gradient_noise8(&x, &y, &z).iter().sum::<f32>();
            }
        }
        println!(
            "eight lanes: {:.1} ns a point ({s})",
            t.elapsed().as_secs_f64() * 1e9 / 5e6
        );
    }
}
