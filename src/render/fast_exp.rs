//! `e^{−τ}` for many optical depths at once, without a library call per value: shading a sample
//! takes the transmittance toward each of the 26 sky cells, and `expf` one at a time was 5–7 %
//! of a frame. [`exp_neg`] is branch-free, so a loop over an array of depths vectorises.
//!
//! Cody–Waite range reduction and Cephes' degree-6 polynomial for `e^r` on `|r| ≤ ln2/2`
//! (S. L. Moshier, *Cephes Math Library*, `expf.c`): within 2 ulp of `expf` where the result
//! is a normal `f32`; depths beyond 87 give `e^{−87}` (1.6·10⁻³⁸) instead of a subnormal or 0.

/// Largest depth taken as is: `e^{−87}` is still a normal `f32`.
const MAX_DEPTH: f32 = 87.0;

/// `e^{−τ}` for `τ ≥ 0` (a negative or NaN `τ` is taken as 0, a depth above 87 as 87).
#[inline(always)]
pub(crate) fn exp_neg(tau: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    // ln 2 split in two: the first part has few bits, so `n·C1` is exact.
    const C1: f32 = 0.693_359_4;
    const C2: f32 = -2.121_944_4e-4;
    // Adding and subtracting 1.5·2²³ rounds to the nearest integer (no `round` call, which
    // is a library call without SSE4.1).
    const ROUND: f32 = 12_582_912.0;
    // `min`/`max`, not `clamp`: a NaN depth goes to 0 (`f32::min` returns the other operand).
    #[allow(clippy::manual_clamp)]
    let x = (-tau).min(0.0).max(-MAX_DEPTH);
    let n = (x * LOG2E + ROUND) - ROUND;
    let r = x - n * C1 - n * C2;
    let p = ((((1.987_569_1e-4 * r + 1.398_199_9e-3) * r + 8.333_452e-3) * r + 4.166_579_6e-2) * r
        + 1.666_666_5e-1)
        * r
        + 0.5;
    let er = p * r * r + r + 1.0;
    // 2ⁿ from its exponent bits: `n ∈ [−126, 0]` here, a normal number.
    er * f32::from_bits(((n as i32 + 127) as u32) << 23)
}

/// [`exp_neg`] of every depth of `taus`.
#[inline(always)]
pub(crate) fn exp_neg_all<const N: usize>(taus: &[f32; N]) -> [f32; N] {
    let mut out = [0.0f32; N];
    for (o, &t) in out.iter_mut().zip(taus) {
        *o = exp_neg(t);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_expf_within_two_ulp_over_the_depths_a_frame_sees() {
        let mut worst = 0.0f64;
        // Every 1/4096 of a depth from 0 to 87, plus the ends.
        for i in 0..=(87 * 4096) {
            let tau = i as f32 / 4096.0;
            let (fast, exact) = (exp_neg(tau) as f64, (-(tau as f64)).exp());
            let ulp = (exact as f32).to_bits() as f64;
            let ulps = (fast as f32).to_bits() as f64 - ulp;
            worst = worst.max(ulps.abs());
            assert!(
                ((fast - exact) / exact).abs() < 3e-7,
                "τ {tau}: {fast} vs {exact}"
            );
        }
        assert!(worst <= 2.0, "{worst} ulp");
        assert_eq!(exp_neg(0.0), 1.0);
        // Out of range: clamped, never NaN, never 0 or subnormal.
        assert_eq!(exp_neg(-1.0), 1.0);
        assert_eq!(exp_neg(f32::NAN), 1.0);
        assert_eq!(exp_neg(1e9), exp_neg(87.0));
        assert!(exp_neg(87.0).is_normal());
        let all = exp_neg_all(&[0.0, 0.5, 3.0]);
        assert_eq!(all, [exp_neg(0.0), exp_neg(0.5), exp_neg(3.0)]);
    }
}
