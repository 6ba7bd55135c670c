//! The cloud's density model: the extinction a ray sample sees from the blobs it crosses.
//!
//! The blob field gives the large shape; its edge is eroded by billowy noise whose scale and
//! depth are in world units (fractions of the target diagonal `L`), so a small or growing blob
//! gets the same detail as a large one (after Schneider's Nubis clouds: a low-frequency base
//! shape eroded at its edge by billows at a few scales).
//!
//! With `G(x) = Σ f_i(x)`, iso-level `t` and `g = G/t`:
//!
//! ```text
//! d(x)   = (g − 1) / S(x)                      approximate depth below the iso-surface (world)
//! σ_t(x) = σ · smoothstep(0, W, d − E·e(x))     σ = density / L, W = edge·L, E = amplitude·L
//! S(x)   = Σ_i w_i s_i / Σ_i w_i,   w_i = max(f_i − ½ max_j f_j, 0)
//! e(x)   = Σ_i w_i erosion(N_i x + o_i) / Σ_i w_i      ∈ [0, 1]
//! ```
//!
//! `E` is capped per blob at 0.35 of its smallest semi-axis (blended like `S`), so erosion cannot
//! cut a thin blob (a leg, a neck) in two.
//!
//! `s_i` is blob `i`'s world-space slope of `g` on its own iso-surface (`4B·r_iso / R_i`, `R_i`
//! the support's mean radius), so `d` is a distance in world units for steep fitted blobs and
//! soft canonical ones alike. `erosion` ([`super::noise::erosion`]) is 0 on the tops of the
//! billows and 1 in the creases between them: the iso-surface is carved inward by up to `E`,
//! never pushed outward, so density exists only where the model's own surface is — a blob
//! whose field stays below the iso-level is never lifted into view.
//!
//! `N_i = (frequency / L)·R_iᵀ(x − c_i)` is blob `i`'s local frame scaled to noise units
//! (world scale, anchored to the blob: the texture moves and turns with it) and `o_i` a seeded
//! offset drawn for the blob's index. The weights are continuous in `x` and keep only the
//! dominant blobs, so a sample evaluates one to three noise stacks, and only in the band
//! `0 < d < E + W`: deeper inside the density is `σ` and outside it is 0.

use glam::Vec3A;

use super::noise::{Octaves, erosion};

/// Most blobs whose weights enter the noise blend at one sample; the strongest are kept (the
/// field still sums all).
pub(super) const MAX_ACTIVE: usize = 24;

/// One blob crossed by the current ray: its span and its frames as affine functions of `t`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Hit {
    pub(super) t0: f32,
    pub(super) t1: f32,
    pub(super) b2: f32,
    /// World slope `s_i` of the normalised field on the blob's iso-surface.
    pub(super) slope: f32,
    /// Erosion depth `E_i`: `E`, capped at a 0.35 of the blob's smallest semi-axis.
    pub(super) depth: f32,
    /// Transpose of the world → unit-support map: the field's world gradient is
    /// `−4B²(1 − |q|²)·Aᵀq` at unit-support point `q`.
    pub(super) a_t: glam::Mat3A,
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
    /// Soft edge width `W` (world units).
    pub(super) edge: f32,
    /// Erosion depth `E` (world units).
    pub(super) depth: f32,
    /// Noise octaves and their evolution (phase in noise units; 0 = frozen).
    pub(super) octaves: Octaves,
    pub(super) inv_threshold: f32,
}

impl DensityParams {
    /// `σ_t` at depth `d` below the iso-surface; `erosion()` (in `[0, 1]`) is called only when
    /// it can change the result.
    #[inline]
    fn extinction(&self, d: f32, depth: f32, erosion: impl FnOnce() -> f32) -> f32 {
        if d <= 0.0 {
            return 0.0;
        }
        if d >= depth + self.edge {
            return self.sigma;
        }
        let v = if depth > 0.0 {
            d - depth * erosion()
        } else {
            d
        };
        self.sigma * smoothstep(0.0, self.edge, v)
    }
}

/// World slope of blob field `g = B²(1 − r²)²` (`r` in unit-support coordinates) on its own
/// iso-surface `g = 1`, `r² = 1 − 1/B`: `4B·r`, divided by the support's mean radius
/// `support_radius`. A blob that alone never reaches the iso-level (`B ≤ 1`) uses its steepest
/// slope `(8/3√3)·B²` at `r = 1/√3` instead.
pub(super) fn iso_slope(b: f64, support_radius: f64) -> f32 {
    let b = b.abs();
    let s = if b > 1.0 {
        4.0 * b * (1.0 - 1.0 / b).sqrt()
    } else {
        8.0 / (3.0 * 3f64.sqrt()) * b * b
    };
    (s / support_radius.max(1e-30)) as f32
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

/// `(σ_t, inside)` at parameter `t` of the ray whose `hits` were gathered (sorted by `t0`);
/// `inside` is true within the iso-surface (`g > 1`), where erosion may still give 0.
#[inline]
pub(super) fn density(p: &DensityParams, hits: &[Hit], t: f32) -> (f32, bool) {
    let mut g = 0.0;
    let mut act = [(0.0f32, 0u32); MAX_ACTIVE];
    let mut n = 0;
    let mut fmax = 0.0f32;
    let mut grad = Vec3A::ZERO;
    for (k, h) in hits.iter().enumerate() {
        if h.t0 > t {
            break;
        }
        if t > h.t1 {
            continue;
        }
        let q = h.o + h.d * t;
        let u = q.length_squared();
        if u < 1.0 {
            let w = 1.0 - u;
            let f = h.b2 * w * w;
            grad += h.a_t * q * (h.b2 * w);
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
    let g = g * p.inv_threshold;
    if g <= 1.0 || !g.is_finite() {
        return (0.0, false);
    }
    let (mut ssum, mut esum, mut wsum) = (0.0, 0.0, 0.0);
    for &(f, k) in &act[..n] {
        let w = f - 0.5 * fmax;
        if w > 0.0 {
            ssum += w * hits[k as usize].slope;
            esum += w * hits[k as usize].depth;
            wsum += w;
        }
    }
    // Depth below the iso-surface to first order: (g − 1) / |∇g|.
    let _ = ssum;
    let d = (g - 1.0) / (4.0 * grad.length() * p.inv_threshold).max(1e-30);
    let sigma = p.extinction(d, esum / wsum, || {
        let mut sum = 0.0;
        for &(f, k) in &act[..n] {
            let w = f - 0.5 * fmax;
            if w > 0.0 {
                let h = &hits[k as usize];
                sum += w * erosion(h.no + h.nd * t, &p.octaves);
            }
        }
        (sum / wsum).clamp(0.0, 1.0)
    });
    (sigma, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso_slope_of_canonical_and_steep_blobs() {
        // Canonical blob A = 1, B = 2: r_iso = √½, slope 4·2·√½ = 5.657 per unit support radius.
        assert!((iso_slope(2.0, 1.0) - 5.656_854).abs() < 1e-4);
        // Halving the size doubles the world slope.
        assert!((iso_slope(2.0, 0.5) - 2.0 * iso_slope(2.0, 1.0)).abs() < 1e-4);
        // Sub-threshold blob: steepest slope, positive and finite.
        let s = iso_slope(0.5, 1.0);
        assert!(s > 0.0 && s < 1.0, "{s}");
    }

    #[test]
    fn extinction_is_zero_outside_full_deep_inside_and_eroded_between() {
        let p = DensityParams {
            sigma: 10.0,
            edge: 0.01,
            depth: 0.05,
            octaves: Octaves::new(3, 0.0),
            inv_threshold: 1.0,
        };
        let e = p.depth;
        assert_eq!(p.extinction(-0.1, e, || unreachable!()), 0.0);
        assert_eq!(p.extinction(0.0, e, || unreachable!()), 0.0);
        assert_eq!(p.extinction(0.07, e, || unreachable!()), 10.0);
        // On a billow top (erosion 0) the edge ramp starts at the iso-surface; in a crease
        // (erosion 1) the surface is carved in by the full depth.
        assert_eq!(p.extinction(0.02, e, || 0.0), 10.0);
        assert_eq!(p.extinction(0.02, e, || 1.0), 0.0);
        assert!((p.extinction(0.005, e, || 0.0) - 5.0).abs() < 1e-5);
        // A thin blob's capped depth cannot carve deeper than the cap.
        assert_eq!(p.extinction(0.02, 0.005, || 1.0), 10.0);
    }

    #[test]
    fn smoothstep_edges() {
        assert_eq!(smoothstep(0.75, 1.25, 0.5), 0.0);
        assert_eq!(smoothstep(0.75, 1.25, 1.5), 1.0);
        assert!((smoothstep(0.75, 1.25, 1.0) - 0.5).abs() < 1e-6);
        assert_eq!(smoothstep(1.0, 1.0, 1.01), 1.0);
    }
}
