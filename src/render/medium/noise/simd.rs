//! The SIMD versions of [`super::gradient_noise`], the one place with `unsafe` for the
//! noise: SSE2 (every x86-64 has it) and AVX2, chosen at run time, so a baseline build uses the
//! wider path on a machine that has it and a farm's older machines still run.
//!
//! Both do the same operations in the same order per corner as the portable
//! [`super::gradient::gradient_noise_scalar`] — wrapping integer products, bit selects, sign flips
//! by XOR, IEEE `+ − ×` on f32 and no FMA — so the bits are the same on every machine and path
//! (the tests below compare them with the scalar noise bit for bit).

use glam::Vec3A;

/// Improved Perlin gradient noise at `p`: zero on the integer lattice, about `[−1, 1]`, on the
/// widest path this machine has (x86-64: AVX2, else SSE2: the eight corners hashed and dotted
/// several at a time, the same operations in the same order as the portable
/// [`super::gradient::gradient_noise_scalar`], so the bits are the same on every machine).
#[inline]
pub(crate) fn gradient_noise(p: Vec3A) -> f32 {
    #[cfg(target_arch = "x86_64")]
    {
        // The detection is cached after the first call: one load and a branch.
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2 (checked just above).
            unsafe { avx2::gradient_noise(p) }
        } else {
            sse2::gradient_noise(p)
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        super::gradient::gradient_noise_scalar(p)
    }
}

/// The trilinear blend of the eight corners, vectorised: `lo` holds the corners with `di = 0`
/// and `hi` those with `di = 1`, each as `[(0,0), (1,0), (0,1), (1,1)]` in `(dj, dk)`, and `r`
/// the point's offset in its cell. The fades `t·t·t·(t·(t·6 − 15) + 10)` of the three axes at
/// once, then `lerp` along x, y and z — the scalar path's operations in its order, so the same
/// bits ([`crate::render::medium::noise::gradient::fade`], [`crate::render::medium::noise::gradient::lerp`]).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn blend_corners(
    lo: core::arch::x86_64::__m128,
    hi: core::arch::x86_64::__m128,
    r: core::arch::x86_64::__m128,
) -> f32 {
    use core::arch::x86_64::*;
    // SAFETY: SSE2 is part of x86-64.
    unsafe {
        let t = r;
        let fades = _mm_mul_ps(
            _mm_mul_ps(_mm_mul_ps(t, t), t),
            _mm_add_ps(
                _mm_mul_ps(
                    t,
                    _mm_sub_ps(_mm_mul_ps(t, _mm_set1_ps(6.0)), _mm_set1_ps(15.0)),
                ),
                _mm_set1_ps(10.0),
            ),
        );
        let u = _mm_shuffle_ps::<0b00_00_00_00>(fades, fades);
        // [x00, x10, x01, x11]
        let mixed = _mm_add_ps(lo, _mm_mul_ps(u, _mm_sub_ps(hi, lo)));
        // lerp(x00, x10, v) and lerp(x01, x11, v) in lanes 0 and 1, then their lerp by w.
        let a = _mm_shuffle_ps::<0b00_00_10_00>(mixed, mixed);
        let b = _mm_shuffle_ps::<0b00_00_11_01>(mixed, mixed);
        let v = _mm_shuffle_ps::<0b01_01_01_01>(fades, fades);
        let y = _mm_add_ps(a, _mm_mul_ps(v, _mm_sub_ps(b, a)));
        let y1 = _mm_shuffle_ps::<0b01_01_01_01>(y, y);
        let w = _mm_shuffle_ps::<0b10_10_10_10>(fades, fades);
        _mm_cvtss_f32(_mm_add_ps(y, _mm_mul_ps(w, _mm_sub_ps(y1, y))))
    }
}

/// The noise's corners four at a time: lanes `(dj, dk) = (0,0), (1,0), (0,1), (1,1)`, one
/// vector for `di = 0` and one for `di = 1`. The hash's per-axis products are formed once per
/// axis (`(i+1)·A = i·A + A` in wrapping arithmetic) and the 32-bit products of the mixing
/// rounds from SSE2's 32×32→64 multiply.
#[cfg(target_arch = "x86_64")]
pub(super) mod sse2 {
    use core::arch::x86_64::*;

    use glam::Vec3A;

    use super::super::gradient::HASH_AXES;

    /// Low 32 bits of the lane-wise product `a·b` (SSE4.1's `pmulld` from SSE2).
    #[inline(always)]
    unsafe fn mullo(a: __m128i, b: __m128i) -> __m128i {
        unsafe {
            let even = _mm_mul_epu32(a, b);
            let odd = _mm_mul_epu32(_mm_srli_epi64::<32>(a), _mm_srli_epi64::<32>(b));
            _mm_unpacklo_epi32(
                _mm_shuffle_epi32::<0b00_00_10_00>(even),
                _mm_shuffle_epi32::<0b00_00_10_00>(odd),
            )
        }
    }

    /// [`crate::render::medium::noise::gradient::mix`] lane-wise.
    #[inline(always)]
    unsafe fn mix(h: __m128i) -> __m128i {
        unsafe {
            let h = _mm_xor_si128(h, _mm_srli_epi32::<15>(h));
            let h = mullo(h, _mm_set1_epi32(0x2C1B_3C6D));
            let h = _mm_xor_si128(h, _mm_srli_epi32::<12>(h));
            let h = mullo(h, _mm_set1_epi32(0x297A_2D39));
            _mm_xor_si128(h, _mm_srli_epi32::<15>(h))
        }
    }

    /// `a` where `mask` is set, else `b`.
    #[inline(always)]
    unsafe fn select(mask: __m128, a: __m128, b: __m128) -> __m128 {
        unsafe { _mm_or_ps(_mm_and_ps(mask, a), _mm_andnot_ps(mask, b)) }
    }

    /// [`crate::render::medium::noise::gradient::grad`] lane-wise (the sign flips are the sign bit, as `-u` is).
    #[inline(always)]
    unsafe fn grad(h: __m128i, x: __m128, y: __m128, z: __m128) -> __m128 {
        unsafe {
            let h = _mm_and_si128(h, _mm_set1_epi32(15));
            let below8 = _mm_castsi128_ps(_mm_cmplt_epi32(h, _mm_set1_epi32(8)));
            let below4 = _mm_castsi128_ps(_mm_cmplt_epi32(h, _mm_set1_epi32(4)));
            let x_as_v = _mm_castsi128_ps(_mm_or_si128(
                _mm_cmpeq_epi32(h, _mm_set1_epi32(12)),
                _mm_cmpeq_epi32(h, _mm_set1_epi32(14)),
            ));
            let u = select(below8, x, y);
            let v = select(below4, y, select(x_as_v, x, z));
            let su = _mm_slli_epi32::<31>(_mm_and_si128(h, _mm_set1_epi32(1)));
            let sv = _mm_slli_epi32::<30>(_mm_and_si128(h, _mm_set1_epi32(2)));
            _mm_add_ps(
                _mm_xor_ps(u, _mm_castsi128_ps(su)),
                _mm_xor_ps(v, _mm_castsi128_ps(sv)),
            )
        }
    }

    #[inline]
    pub(crate) fn gradient_noise(p: Vec3A) -> f32 {
        let f = p.floor();
        let (i, j, k) = (f.x as i32, f.y as i32, f.z as i32);
        let r = p - f;
        let (x, y, z) = (r.x, r.y, r.z);
        let [a, b, c] = HASH_AXES;
        let hi = (i as u32).wrapping_mul(a);
        let hj = (j as u32).wrapping_mul(b);
        let hk = (k as u32).wrapping_mul(c);
        let (hj1, hk1) = (hj.wrapping_add(b), hk.wrapping_add(c));
        // SAFETY: SSE2 is part of x86-64.
        unsafe {
            // `_mm_set_*` lists lanes from the last to the first.
            let jk = _mm_set_epi32(
                (hj1 ^ hk1) as i32,
                (hj ^ hk1) as i32,
                (hj1 ^ hk) as i32,
                (hj ^ hk) as i32,
            );
            let h0 = mix(_mm_xor_si128(jk, _mm_set1_epi32(hi as i32)));
            let h1 = mix(_mm_xor_si128(jk, _mm_set1_epi32(hi.wrapping_add(a) as i32)));
            let ys = _mm_set_ps(y - 1.0, y, y - 1.0, y);
            let zs = _mm_set_ps(z - 1.0, z - 1.0, z, z);
            let c0 = grad(h0, _mm_set1_ps(x), ys, zs);
            let c1 = grad(h1, _mm_set1_ps(x - 1.0), ys, zs);
            super::blend_corners(c0, c1, r.into())
        }
    }
}

/// All eight corners at once: lanes 0–3 are `di = 0`, lanes 4–7 `di = 1`, each half in the SSE2
/// version's `(dj, dk)` order; AVX2 has the 32-bit lane product `vpmulld` the mixing rounds need.
#[cfg(target_arch = "x86_64")]
pub(super) mod avx2 {
    use core::arch::x86_64::*;

    use glam::Vec3A;

    use super::super::gradient::HASH_AXES;

    /// [`crate::render::medium::noise::gradient::mix`] lane-wise.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(in crate::render::medium) fn mix(h: __m256i) -> __m256i {
        let h = _mm256_xor_si256(h, _mm256_srli_epi32::<15>(h));
        let h = _mm256_mullo_epi32(h, _mm256_set1_epi32(0x2C1B_3C6D));
        let h = _mm256_xor_si256(h, _mm256_srli_epi32::<12>(h));
        let h = _mm256_mullo_epi32(h, _mm256_set1_epi32(0x297A_2D39));
        _mm256_xor_si256(h, _mm256_srli_epi32::<15>(h))
    }

    /// `a` where `mask` is set, else `b` (the masks are all-ones or all-zeros lanes).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn select(mask: __m256, a: __m256, b: __m256) -> __m256 {
        _mm256_or_ps(_mm256_and_ps(mask, a), _mm256_andnot_ps(mask, b))
    }

    /// [`crate::render::medium::noise::gradient::grad`] lane-wise (the sign flips are the sign bit, as `-u` is).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(in crate::render::medium) fn grad(h: __m256i, x: __m256, y: __m256, z: __m256) -> __m256 {
        let h = _mm256_and_si256(h, _mm256_set1_epi32(15));
        let below8 = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(8), h));
        let below4 = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(4), h));
        let x_as_v = _mm256_castsi256_ps(_mm256_or_si256(
            _mm256_cmpeq_epi32(h, _mm256_set1_epi32(12)),
            _mm256_cmpeq_epi32(h, _mm256_set1_epi32(14)),
        ));
        let u = select(below8, x, y);
        let v = select(below4, y, select(x_as_v, x, z));
        let su = _mm256_slli_epi32::<31>(_mm256_and_si256(h, _mm256_set1_epi32(1)));
        let sv = _mm256_slli_epi32::<30>(_mm256_and_si256(h, _mm256_set1_epi32(2)));
        _mm256_add_ps(
            _mm256_xor_ps(u, _mm256_castsi256_ps(su)),
            _mm256_xor_ps(v, _mm256_castsi256_ps(sv)),
        )
    }

    /// Callers must know the CPU has AVX2 (calling it is `unsafe` elsewhere).
    #[target_feature(enable = "avx2")]
    pub(crate) fn gradient_noise(p: Vec3A) -> f32 {
        // glam's floor (the scalar path's), then the lattice point's integers by a truncating
        // conversion: exact for the integral `f` below 2³¹ in magnitude, which is all the
        // saturating `as i32` of the scalar path could differ on (those points go there).
        let f = p.floor();
        let fv: __m128 = f.into();
        let inside = _mm_movemask_ps(_mm_cmplt_ps(
            _mm_andnot_ps(_mm_set1_ps(-0.0), fv),
            _mm_set1_ps(2_147_483_648.0),
        ));
        if inside & 0b111 != 0b111 {
            return super::super::gradient::gradient_noise_scalar(p);
        }
        let [a, b, c] = HASH_AXES;
        let axes = _mm_setr_epi32(a as i32, b as i32, c as i32, 0);
        // `(i·A, j·B, k·C)` and the next lattice point's, `(i+1)·A = i·A + A` (wrapping).
        let prod = _mm_mullo_epi32(_mm_cvttps_epi32(fv), axes);
        let both = _mm256_set_m128i(_mm_add_epi32(prod, axes), prod);
        let pick = |lanes: __m256i| _mm256_permutevar8x32_epi32(both, lanes);
        let h = mix(_mm256_xor_si256(
            _mm256_xor_si256(
                pick(_mm256_setr_epi32(0, 0, 0, 0, 4, 4, 4, 4)),
                pick(_mm256_setr_epi32(1, 5, 1, 5, 1, 5, 1, 5)),
            ),
            pick(_mm256_setr_epi32(2, 2, 6, 6, 2, 2, 6, 6)),
        ));
        let r = p - f;
        let rv: __m128 = r.into();
        let offsets = _mm256_set_m128(_mm_sub_ps(rv, _mm_set1_ps(1.0)), rv);
        let spread = |lanes: __m256i| _mm256_permutevar8x32_ps(offsets, lanes);
        let xs = spread(_mm256_setr_epi32(0, 0, 0, 0, 4, 4, 4, 4));
        let ys = spread(_mm256_setr_epi32(1, 5, 1, 5, 1, 5, 1, 5));
        let zs = spread(_mm256_setr_epi32(2, 2, 6, 6, 2, 2, 6, 6));
        let corners = grad(h, xs, ys, zs);
        let c0 = _mm256_castps256_ps128(corners);
        let c1 = _mm256_extractf128_ps::<1>(corners);
        super::blend_corners(c0, c1, rv)
    }
}

#[cfg(test)]
mod tests {
    use super::super::gradient::gradient_noise_scalar;
    use super::*;

    /// Points of every sign and size, lattice points and their neighbours (the hash's wrapping
    /// products, the floor at negative integers), and points past the 32-bit lattice (the
    /// scalar path's saturating conversion).
    fn points() -> impl Iterator<Item = Vec3A> {
        let mut rng = 0x1234_5678u64;
        let mut next = move || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((rng >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 2.0
        };
        let far = [
            Vec3A::new(3e9, 0.5, -0.5),
            Vec3A::new(0.25, -5e9, 1.5),
            Vec3A::new(2_147_483_520.0, -2_147_483_648.0, 7.5),
            Vec3A::new(f32::NAN, 1.0, 2.0),
            Vec3A::new(-0.0, 0.0, -1e-30),
        ];
        (0..200_000)
            .map(move |n| {
                let scale = [1.0, 10.0, 300.0, 1e5][n % 4];
                let p = Vec3A::new(next(), next(), next()) * scale;
                if n % 7 == 0 { p.round() } else { p }
            })
            .chain(far)
    }

    #[test]
    fn simd_noise_has_the_scalar_noises_bits() {
        for p in points() {
            let scalar = gradient_noise_scalar(p).to_bits();
            assert_eq!(gradient_noise(p).to_bits(), scalar, "dispatched, at {p}");
            #[cfg(target_arch = "x86_64")]
            {
                assert_eq!(sse2::gradient_noise(p).to_bits(), scalar, "SSE2, at {p}");
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2.
                    let wide = unsafe { avx2::gradient_noise(p) };
                    assert_eq!(wide.to_bits(), scalar, "AVX2, at {p}");
                }
            }
        }
    }
}
