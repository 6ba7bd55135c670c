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
//! d(x)   = (g − 1) / |∇g(x)|                   depth below the iso-surface (world, first order)
//! σ_t(x) = σ · ramp((d − E·e(x)) / W)          σ = density / L, W = edge·L, E = amplitude·L
//! e(x)   = Σ_i w_i erosion(N_i x + o_i) / Σ_i w_i,   w_i = max(f_i − ½ max_j f_j, 0)   ∈ [0, 1]
//! ```
//!
//! `∇g` is the exact gradient of the summed field (`∇f_i = −4B²(1 − |q|²)·A_iᵀq` at blob `i`'s
//! unit-support point `q = A_i(x − c_i)`), so `d` is a distance in world units whatever the
//! blobs' shapes and overlaps, and the density ramp is `W` wide as asked (a depth from one blob's
//! mean slope was 3–5× too deep on fitted models: the ramp was a sub-voxel step that aliased in
//! frames and in the exported grids). `E` is capped per blob at
//! [`super::blobs::EROSION_CAP`] of its smallest semi-axis (blended like `e`), so erosion cannot
//! cut a thin blob (a leg, a neck) in two. `erosion` ([`super::noise::erosion`]) is 0 on the tops of the
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
    /// Erosion depth `E_i`: `E`, capped at [`super::blobs::EROSION_CAP`] of the blob's smallest
    /// semi-axis.
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
#[derive(Clone, Copy, Debug, PartialEq)]
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
        self.sigma * ramp(v, self.edge)
    }
}

/// The edge's density profile: `clamp(v / w, 0, 1)`, linear from the surface (`v = 0`) to full
/// density at depth `w`; a step at 0 when `w = 0`.
///
/// Linear rather than smoothstep because a voxel grid (the volume export, a renderer's density
/// texture) reconstructs a linear profile exactly: smoothstep's quadratic start, interpolated
/// linearly over the outermost voxel, came out too dense there (the exported grid's fringe
/// 20 % more opaque than the frame's), which widened and brightened the backlit rim in other
/// renderers.
#[inline]
fn ramp(v: f32, w: f32) -> f32 {
    if w <= 0.0 {
        return if v > 0.0 { 1.0 } else { 0.0 };
    }
    (v / w).clamp(0.0, 1.0)
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
    let (mut esum, mut wsum) = (0.0, 0.0);
    for &(f, k) in &act[..n] {
        let w = f - 0.5 * fmax;
        if w > 0.0 {
            esum += w * hits[k as usize].depth;
            wsum += w;
        }
    }
    // Depth below the iso-surface to first order: (g − 1) / |∇g| (`grad` is ∇G / −4).
    let d = (g - 1.0) / (4.0 * grad.length() * p.inv_threshold).max(1e-30);
    let sigma = p.extinction(d, esum / wsum, || {
        let mut sum = 0.0;
        for &(f, k) in &act[..n] {
            let w = f - 0.5 * fmax;
            if w > 0.0 {
                let h = &hits[k as usize];
                super::counters::add(super::counters::Counter::NoiseEvals, 1);
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
    fn ramp_is_linear_and_clamped() {
        assert_eq!(ramp(-0.1, 0.5), 0.0);
        assert_eq!(ramp(0.6, 0.5), 1.0);
        assert!((ramp(0.25, 0.5) - 0.5).abs() < 1e-6);
        assert!((ramp(0.1, 0.5) - 0.2).abs() < 1e-6);
        assert_eq!(ramp(0.01, 0.0), 1.0);
        assert_eq!(ramp(0.0, 0.0), 0.0);
    }
}
