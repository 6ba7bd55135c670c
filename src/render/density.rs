//! The cloud's density model: the extinction a ray sample sees from the blobs it crosses.
//!
//! With `G(x) = Σ f_i(x)` and iso-level `t`, the field value `g = G/t` is perturbed by
//! fractal noise and pushed through a smoothstep across the soft edge:
//!
//! ```text
//! σ_t(x) = σ · smoothstep(1 − k·edge, 1 + k·edge, g + k · amplitude · e(g) · n(x)),  σ = density / L
//! e(g) = clamp(1 − 0.75 (g − 1), 0.25, 1)          (noise erodes the edge more than the core)
//! n(x) = Σ_i w_i fbm(N_i x + o_i) / Σ_i w_i,  w_i = max(f_i − ½ max_j f_j, 0)
//! k(x) = Σ_i w_i k_i / Σ_i w_i
//! ```
//!
//! `k_i` is blob `i`'s field slope `|∂f_i/∂ρ|` on its own iso-surface relative to the canonical
//! blob's (`A = 1, B = 2`: slope 4), clamped to `[¼, 16]`. Fitted blobs with a small `A` and a
//! large `B` have a much steeper field; without `k` their edge would be hard and their noise
//! invisible. With it, edge width and noise relief are about the same fraction of every blob.
//!
//! `N_i = (frequency / L)·R_iᵀ(x − c_i)` is blob `i`'s local frame in units of `L` (the length
//! scale) and `o_i` a seeded offset drawn for the blob's index, so the texture moves and turns
//! with its blob. The weights are continuous in `x` and keep only the dominant blobs (those
//! above half the strongest), so a sample evaluates one to three noise stacks. Noise is skipped
//! where it cannot change the result (`g` far below or above the edge).

use glam::Vec3A;

use super::noise::fbm;

/// Most blobs whose weights enter the noise blend at one sample; the strongest are kept (the
/// field still sums all).
pub(super) const MAX_ACTIVE: usize = 24;

/// One blob crossed by the current ray: its span and its frames as affine functions of `t`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Hit {
    pub(super) t0: f32,
    pub(super) t1: f32,
    pub(super) b2: f32,
    /// Edge and noise gain `k_i`.
    pub(super) gain: f32,
    /// Unit-support coordinates `o + t·d` (support is `|·| < 1`).
    pub(super) o: Vec3A,
    pub(super) d: Vec3A,
    /// Noise coordinates `no + t·nd`.
    pub(super) no: Vec3A,
    pub(super) nd: Vec3A,
}

/// Density parameters, already in world units.
#[derive(Clone, Copy, Debug)]
pub(super) struct DensityParams {
    /// Extinction inside the cloud, per world unit.
    pub(super) sigma: f32,
    pub(super) edge: f32,
    pub(super) amplitude: f32,
    pub(super) octaves: u32,
    pub(super) inv_threshold: f32,
}

impl DensityParams {
    /// Noise erosion weight `e(g)`.
    #[inline]
    fn erosion(g: f32) -> f32 {
        (1.0 - 0.75 * (g - 1.0)).clamp(0.25, 1.0)
    }

    /// `σ_t` for normalised field `g` and gain `k`; `noise()` (in `[−1, 1]`) is called only
    /// when it can change the result.
    #[inline]
    fn extinction(&self, g: f32, k: f32, noise: impl FnOnce() -> f32) -> f32 {
        let amp = self.amplitude * Self::erosion(g) * k;
        let edge = self.edge * k;
        if g + amp <= 1.0 - edge {
            return 0.0;
        }
        if g - amp >= 1.0 + edge {
            return self.sigma;
        }
        let v = if amp > 0.0 { g + amp * noise() } else { g };
        self.sigma * smoothstep(1.0 - edge, 1.0 + edge, v)
    }
}

/// Edge and noise gain of a blob: its field slope `|∂f/∂ρ| = 4Bρ/(1+A)` at its own iso-surface
/// `ρ² = (1+A)(1 − 1/B)`, over the canonical blob's slope 4, clamped to `[¼, 16]`; 1 when the
/// blob alone never reaches the iso-level (`B ≤ 1`).
pub(super) fn gain(a: f64, b: f64) -> f32 {
    if b <= 1.0 {
        return 1.0;
    }
    let rho = ((1.0 + a) * (1.0 - 1.0 / b)).sqrt();
    ((4.0 * b * rho / (1.0 + a)) / 4.0).clamp(0.25, 16.0) as f32
}

/// `smoothstep` over `[lo, hi]`; a step at `lo` when the range is empty.
#[inline]
fn smoothstep(lo: f32, hi: f32, v: f32) -> f32 {
    if hi <= lo {
        return if v > lo { 1.0 } else { 0.0 };
    }
    let x = ((v - lo) / (hi - lo)).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// `σ_t` at parameter `t` of the ray whose `hits` were gathered (sorted by `t0`).
#[inline]
pub(super) fn density(p: &DensityParams, hits: &[Hit], t: f32) -> f32 {
    let mut g = 0.0;
    let mut act = [(0.0f32, 0u32); MAX_ACTIVE];
    let mut n = 0;
    let mut fmax = 0.0f32;
    for (k, h) in hits.iter().enumerate() {
        if h.t0 > t {
            break;
        }
        if t > h.t1 {
            continue;
        }
        let u = (h.o + h.d * t).length_squared();
        if u < 1.0 {
            let w = 1.0 - u;
            let f = h.b2 * w * w;
            g += f;
            fmax = fmax.max(f);
            if n < MAX_ACTIVE {
                act[n] = (f, k as u32);
                n += 1;
            } else {
                // Full: keep the strongest, so the dominant blob is always among them
                // (the weights below would otherwise all vanish and give 0/0).
                let weakest = (0..MAX_ACTIVE)
                    .min_by(|&i, &j| act[i].0.total_cmp(&act[j].0))
                    .unwrap_or(0);
                if f > act[weakest].0 {
                    act[weakest] = (f, k as u32);
                }
            }
        }
    }
    if g <= 0.0 || !g.is_finite() {
        return 0.0;
    }
    let (mut ksum, mut wsum) = (0.0, 0.0);
    for &(f, k) in &act[..n] {
        let w = f - 0.5 * fmax;
        if w > 0.0 {
            ksum += w * hits[k as usize].gain;
            wsum += w;
        }
    }
    p.extinction(g * p.inv_threshold, ksum / wsum, || {
        let mut sum = 0.0;
        for &(f, k) in &act[..n] {
            let w = f - 0.5 * fmax;
            if w > 0.0 {
                let h = &hits[k as usize];
                sum += w * fbm(h.no + h.nd * t, p.octaves);
            }
        }
        (sum / wsum).clamp(-1.0, 1.0)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canonical_blob_has_unit_gain() {
        for a in [0.3, 1.0, 2.0] {
            assert!((gain(a, (1.0 + a) / a) - 1.0 / a as f32).abs() < 1e-6);
        }
        assert_eq!(gain(1.0, 2.0), 1.0);
        assert_eq!(gain(1.0, 0.5), 1.0);
        // A steep fitted blob (A = 0.05, B = 9.48): about 8.7 times the canonical slope.
        assert!(
            (gain(0.05, 9.48) - 8.75).abs() < 0.05,
            "{}",
            gain(0.05, 9.48)
        );
    }

    #[test]
    fn smoothstep_edges() {
        assert_eq!(smoothstep(0.75, 1.25, 0.5), 0.0);
        assert_eq!(smoothstep(0.75, 1.25, 1.5), 1.0);
        assert!((smoothstep(0.75, 1.25, 1.0) - 0.5).abs() < 1e-6);
        assert_eq!(smoothstep(1.0, 1.0, 1.01), 1.0);
    }
}
