//! The cloud's density model: the extinction a ray sample sees from the blobs it crosses.
//!
//! The blob field gives the large shape; its surface is displaced along its normal by
//! cumulus billows ([`crate::render::medium::noise::Billows`]), pushed out on their tops and cut in at their
//! creases — pyroclastic displacement after Wrenninge (*Production Volume Rendering*), with
//! octaves that follow the local feature size as Bouthors & Neyret's puff hierarchies do.
//!
//! With `G(x) = Σ f_i(x)`, iso-level `t` and `g = G/t`:
//!
//! ```text
//! d(x)   = 2(g − √g) / |∇g(x)|                signed depth below the iso-surface (world, first order in √g)
//! σ_t(x) = σ · ramp((d + D(x)) / W)            σ = density / L, W = edge·L
//! D(x)   = Σ_i w_i D_F(N_i x + o_i) / √(Σ_i w_i²),  w_i = max(f_i − ½ max_j f_j, 0)
//! F(x)   = Σ_i w_i F_i / Σ_i w_i               local feature size, F_i = blob i's median semi-axis
//! ```
//!
//! `D_F` is the billow displacement for feature size `F` ([`crate::render::medium::noise::Billows`]): octaves
//! from a fifth of the target down to the frame's finest, each about `amplitude × wavelength`
//! deep (finer ones a little deeper: [`crate::render::medium::noise::HURST`]) and present only where `F`
//! exceeds its wavelength, so a young blob, a leg and the body each get
//! billows of their own size, and a thin part is never cut deeper than a fraction of its
//! radius (it keeps its width).
//!
//! `∇g` is the exact gradient of the summed field (`∇f_i = −4B²(1 − |q|²)·A_iᵀq` at blob `i`'s
//! unit-support point `q = A_i(x − c_i)`), so `d` is a distance in world units whatever the
//! blobs' shapes and overlaps, and the density ramp is `W` wide as asked. Outside the
//! iso-surface (`0 < g < 1`) `d` is negative, and a billow top lifts density there; beyond the
//! supports the field is 0 and so is the density (the billows fit in the shell between the
//! iso-surface and the support, which the fitted `A` makes a good part of each semi-axis).
//!
//! `N_i = R_iᵀ(x − c_i)/λ_0` is blob `i`'s local frame scaled to noise units (world scale,
//! anchored to the blob: the texture moves and turns with it, and does not stretch as the blob
//! grows) and `o_i` a seeded offset drawn for the blob's index. The weights are continuous in
//! `x` and keep only the dominant blobs, so a sample evaluates one to three billow stacks, and
//! only in the band `−lift(D⁺) < d < W − lift(D⁻)` that the bounds of `D` leave undecided:
//! deeper inside the density is `σ`, further out 0 (and the march may step on coarsely). The
//! band is bounded by the lifts of the largest push and the deepest crease, not by `D⁺`, `D⁻`
//! themselves: where the supports end close to the surface, the soft limit keeps a billow top
//! well short of the push it was given, and the march need not look for one further out.

use glam::Vec3A;

use crate::render::medium::noise::{Billows, CREASE, MAX_OCTAVES};

/// Most blobs whose weights enter the noise blend at one sample; the strongest are kept (the
/// field still sums all).
pub(crate) const MAX_ACTIVE: usize = 24;

/// One blob crossed by the current ray: its span and its frames as functions of `t`.
///
/// The unit-support point is `q(t) = q_m + (t − t_m)·d`, with `t_m` the parameter closest to
/// the blob's centre (`q_m ⊥ d`), so `|q|² = |q_m|² + |d|²(t − t_m)²` and the gradient's
/// `Aᵀq = Aᵀq_m + (t − t_m)·Aᵀd`: a sample costs a few multiply-adds a hit instead of two
/// matrix products, and centring on `t_m` keeps `|q|²` free of the cancellation an expansion
/// about the ray's origin would suffer (the eye is tens of support radii away).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Hit {
    /// The blob's index in the frame's blob list (its identity, for the ID mattes).
    pub(crate) blob: u32,
    pub(crate) t0: f32,
    pub(crate) t1: f32,
    pub(crate) b2: f32,
    /// Feature size `F_i` (world units): the blob's median semi-axis.
    pub(crate) feature: f32,
    /// Half the smallest semi-axis of the support: `½(1 − |q|²)·r` under-estimates the world
    /// distance from unit-support point `q` to the support's boundary.
    pub(crate) half_min_support: f32,
    /// `t_m`: the ray parameter of the point closest to the blob's centre in its unit-support
    /// frame.
    pub(crate) mid: f32,
    /// `|q_m|²`, the smallest `|q|²` along the ray.
    pub(crate) u_min: f32,
    /// `|d|²`: how fast `|q|²` grows away from `t_m`.
    pub(crate) u_curve: f32,
    /// `Aᵀq_m` and `Aᵀd` (transpose of the world → unit-support map `A`): the field's world
    /// gradient is `−4B²(1 − |q|²)·Aᵀq` at unit-support point `q`.
    pub(crate) grad_mid: Vec3A,
    pub(crate) grad_dir: Vec3A,
    /// Noise coordinates `no + t·nd`.
    pub(crate) no: Vec3A,
    pub(crate) nd: Vec3A,
}

impl Hit {
    /// The hit of a ray whose unit-support coordinates are `o + t·d` (`d ≠ 0`), with `a_t`
    /// the transpose of the blob's world → unit-support map; the remaining fields as given.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        blob: u32,
        (t0, t1): (f32, f32),
        b2: f32,
        feature: f32,
        half_min_support: f32,
        a_t: glam::Mat3A,
        (o, d): (Vec3A, Vec3A),
        (no, nd): (Vec3A, Vec3A),
    ) -> Hit {
        let u_curve = d.length_squared();
        let mid = -o.dot(d) / u_curve;
        let q_mid = o + d * mid;
        Hit {
            blob,
            t0,
            t1,
            b2,
            feature,
            half_min_support,
            mid,
            u_min: q_mid.length_squared(),
            u_curve,
            grad_mid: a_t * q_mid,
            grad_dir: a_t * d,
            no,
            nd,
        }
    }

    /// `(t − t_m, |q(t)|²)`: the offset from the closest point and the squared unit-support
    /// radius at `t` (the support is `< 1`).
    #[inline(always)]
    pub(crate) fn offset_and_radius2(&self, t: f32) -> (f32, f32) {
        let s = t - self.mid;
        (s, self.u_curve * (s * s) + self.u_min)
    }

    /// `Aᵀq` at offset `s = t − t_m` (the field's gradient is `−4B²(1 − |q|²)` times it).
    #[inline(always)]
    pub(crate) fn a_t_q(&self, s: f32) -> Vec3A {
        self.grad_dir * s + self.grad_mid
    }
}

/// Deepest a crease may cut, as a fraction of the local feature size `F` (softly: a crease of
/// depth `c` cuts `c·m/(c + m)`, `m = MAX_CUT·F`), so legs, necks and the knot's tube keep
/// their width while the body's billows cut in freely.
pub(crate) const MAX_CUT: f32 = 0.35;

/// Density parameters, already in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct DensityParams {
    /// Extinction inside the cloud, per world unit.
    pub(crate) sigma: f32,
    /// Soft edge width `W` (world units).
    pub(crate) edge: f32,
    /// The billows displacing the surface.
    pub(crate) billows: Billows,
    pub(crate) inv_threshold: f32,
}

impl DensityParams {
    /// `σ_t` at signed depth `d` below the iso-surface of a part of feature size `feature`;
    /// `displacement(depths, n, settle)` (world units, in the bounds [`Billows::total_depth`]
    /// gives) is called only when it can change the result, and may end early with
    /// [`Settle::check`]'s answer. Returns `(σ_t, may_hold_density)`: the flag is false only
    /// where no billow can reach (so a coarse march may skip on).
    ///
    /// `reach` is how far the supports extend from this point (world units): outward pushes are
    /// softly limited to it, `D·r/(D + r)`, so a billow top rounds off before the support ends
    /// instead of being cut flat by it (a blob with a small `A` has a thin shell).
    #[inline]
    fn extinction(
        &self,
        d: f32,
        feature: f32,
        reach: f32,
        displacement: impl FnOnce(&[f32; MAX_OCTAVES], usize, &Settle) -> Result<f32, f32>,
    ) -> (f32, bool) {
        let (depths, n, total) = self.billows.depths(feature);
        let settle = Settle {
            d,
            edge: self.edge,
            sigma: self.sigma,
            lo_total: -CREASE * total,
            hi_total: (1.0 - CREASE) * total,
            reach,
            cut: MAX_CUT * feature,
        };
        // The lifts of the largest push and the deepest crease bound every lift (the soft
        // limits are increasing): beyond them no billow can reach, and below them no crease.
        if d + settle.lift(settle.hi_total) <= 0.0 {
            return (0.0, false);
        }
        if d + settle.lift(settle.lo_total) >= self.edge {
            return (self.sigma, true);
        }
        if n == 0 {
            return (self.sigma * ramp(d, self.edge), true);
        }
        match displacement(&depths, n, &settle) {
            Ok(push) => (self.sigma * ramp(d + settle.lift(push), self.edge), true),
            Err(sigma) => (sigma, true),
        }
    }
}

/// What decides a sample's density once its displacement is known to lie in a range: the
/// depth, the ramp and the lift's limits ([`DensityParams::extinction`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Settle {
    d: f32,
    edge: f32,
    sigma: f32,
    lo_total: f32,
    hi_total: f32,
    reach: f32,
    cut: f32,
}

impl Settle {
    /// The surface's lift for a raw displacement: clamped to its bounds, then softly limited
    /// (monotonic, so bounds of `push` give bounds of the lift).
    #[inline]
    fn lift(&self, push: f32) -> f32 {
        let push = push.clamp(self.lo_total, self.hi_total);
        if push > 0.0 {
            soft_limit(push, self.reach)
        } else {
            // Creases cut at most about `MAX_CUT·F` deep: a thin part keeps its width.
            push * self.cut / (self.cut - push).max(1e-30)
        }
    }

    /// The density once the displacement lies in `[lo, hi]`, if the octaves left cannot move
    /// the ramp off a clamp (then the answer is exact); `None` otherwise.
    #[inline]
    pub(crate) fn check(&self, lo: f32, hi: f32) -> Option<f32> {
        // A lift is ≥ 0 for a push > 0 and ≤ 0 for a push ≤ 0, so the signs alone often
        // decide (the same answers as the lifts, without their divisions).
        let empty = !(self.d > 0.0 && hi > 0.0) && self.d + self.lift(hi) <= 0.0;
        if empty {
            Some(0.0)
        } else if !(self.d < self.edge && lo <= 0.0) && self.d + self.lift(lo) >= self.edge {
            Some(self.sigma)
        } else {
            None
        }
    }
}

/// An outward push `push ≥ 0` softly limited to `reach`: `push·reach/(push + reach)`, below
/// both and increasing in `push` — so the lift of the largest push bounds every lift.
#[inline]
fn soft_limit(push: f32, reach: f32) -> f32 {
    push * reach / (push + reach).max(1e-30)
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

/// `(σ_t, inside)` at parameter `t` of the ray whose `hits` were gathered (sorted by `t0`),
/// summed over the hits `order` names (indices into `hits`, increasing: all of them, or those
/// spanning `t`); `inside` is true within the iso-surface (`g > 1`), where erosion may still
/// give 0.
#[inline]
pub(crate) fn density(p: &DensityParams, hits: &[Hit], order: &[u32], t: f32) -> (f32, bool) {
    let mut g = 0.0;
    let mut act = [(0.0f32, 0u32); MAX_ACTIVE];
    let mut n = 0;
    let mut fmax = 0.0f32;
    let mut grad = Vec3A::ZERO;
    let mut reach = 0.0f32;
    for &k in order {
        let h = &hits[k as usize];
        if h.t0 > t {
            break;
        }
        if t > h.t1 {
            continue;
        }
        let (s, u) = h.offset_and_radius2(t);
        if u < 1.0 {
            let w = 1.0 - u;
            let f = h.b2 * w * w;
            grad += h.a_t_q(s) * (h.b2 * w);
            g += f;
            // `f` and the reach are finite and ≥ 0: a plain comparison (no NaN handling)
            // gives `max`'s value.
            if f > fmax {
                fmax = f;
            }
            let r = w * h.half_min_support;
            if r > reach {
                reach = r;
            }
            if n < MAX_ACTIVE {
                act[n] = (f, k);
                n += 1;
            } else {
                // Full: keep the strongest, so the dominant blob is always among them
                // (the weights below would otherwise all vanish and give 0/0).
                let weakest = (0..MAX_ACTIVE)
                    .min_by(|&i, &j| act[i].0.total_cmp(&act[j].0))
                    .unwrap_or(0);
                if f > act[weakest].0 {
                    act[weakest] = (f, k);
                }
            }
        }
    }
    let g = g * p.inv_threshold;
    if !(g > 0.0 && g.is_finite()) {
        return (0.0, false);
    }
    // Signed depth below the iso-surface: the first-order distance of `√g`'s level 1,
    // `(√g − 1)/|∇√g| = 2(g − √g)/|∇g|` (`grad` is ∇G / −4). `√g` of one blob is linear in
    // `1 − |q|²`, so this stays a fair distance deep inside a strong blob, where `(g − 1)/|∇g|`
    // saturates near a fifth of its radius and the creases would hollow it out.
    let d = 2.0 * (g - g.sqrt()) / (4.0 * grad.length() * p.inv_threshold).max(1e-30);
    // Beyond the lift of the highest billow top or below the deepest crease any part could
    // have, the answer is [`DensityParams::extinction`]'s first two (its bounds, from the
    // part's own total ≤ `most`, are no wider): no feature size, no octave depths needed.
    let most = p.billows.max_total();
    if d + soft_limit((1.0 - CREASE) * most, reach) <= 0.0 {
        return (0.0, false);
    }
    if d - CREASE * most >= p.edge {
        return (p.sigma, true);
    }
    let (mut fsum, mut wsum) = (0.0, 0.0);
    for &(f, k) in &act[..n] {
        let w = f - 0.5 * fmax;
        if w > 0.0 {
            fsum += w * hits[k as usize].feature;
            wsum += w;
        }
    }
    p.extinction(d, fsum / wsum, reach, |depths, octaves, settle| {
        let mut points = [Vec3A::ZERO; MAX_ACTIVE];
        let mut weights = [0.0f32; MAX_ACTIVE];
        let (mut m, mut w2) = (0, 0.0);
        for &(f, k) in &act[..n] {
            let w = f - 0.5 * fmax;
            if w > 0.0 {
                let h = &hits[k as usize];
                crate::render::counters::add(crate::render::counters::Counter::NoiseEvals, 1);
                points[m] = h.no + h.nd * t;
                weights[m] = w;
                w2 += w * w;
                m += 1;
            }
        }
        // Variance-preserving blend (the blobs' billows are independent with mean ≈ 0): a plain
        // average would flatten the billows wherever blobs overlap, i.e. on most of a fitted
        // model's surface.
        p.billows.blend(
            &mut points[..m],
            &weights[..m],
            1.0 / w2.sqrt(),
            depths,
            octaves,
            |lo, hi| settle.check(lo, hi),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extinction_is_zero_outside_full_deep_inside_and_displaced_between() {
        let p = DensityParams {
            sigma: 10.0,
            edge: 0.01,
            billows: Billows::new(4, 0.2, 0.0, 0.25, 0.0),
            inv_threshold: 1.0,
        };
        let f = 1.0; // every octave at full depth
        let total = p.billows.total_depth(f);
        let octave =
            |k: i32| 0.25 * 0.2 * 2.03f32.powf(-(k as f32) * crate::render::medium::noise::HURST);
        assert!((total - (0..4).map(octave).sum::<f32>()).abs() < 1e-5);
        let never = |_: &[f32; 8], _: usize, _: &Settle| -> Result<f32, f32> { unreachable!() };
        // Beyond the highest billow top: nothing, and the march may skip.
        assert_eq!(
            p.extinction(-(1.0 - CREASE) * total - 1e-3, f, 1.0, never),
            (0.0, false)
        );
        // Deeper than the deepest crease plus the edge: full density.
        assert_eq!(
            p.extinction(CREASE * total + 0.011, f, 1.0, never),
            (10.0, true)
        );
        // Between: the surface is pushed out by a billow top and cut in by a crease.
        assert_eq!(
            p.extinction(-0.015, f, 1e9, |_, _, _| Ok(0.03)),
            (10.0, true)
        );
        assert_eq!(p.extinction(0.02, f, 1.0, |_, _, _| Ok(-0.03)), (0.0, true));
        let (s, inside) = p.extinction(-0.02, f, 1e9, |_, _, _| Ok(0.025));
        assert!(inside && (s - 5.0).abs() < 1e-3, "{s}");
        // Near the end of the supports a billow top is rounded off: a push of 0.02 where the
        // supports reach 0.02 further lifts the surface by 0.01 only.
        let (s, _) = p.extinction(-0.005, f, 0.02, |_, _, _| Ok(0.02));
        assert!((s - 5.0).abs() < 1e-3, "{s}");
        // So no billow reaches further than the lift of the largest push, `h·r/(h + r)` with
        // `h = (1 − CREASE)·total` (0.0119 here, not min(h, r) = 0.02): decided without
        // octaves, and the march may skip ...
        let top = (1.0 - CREASE) * total * 0.02 / ((1.0 - CREASE) * total + 0.02);
        assert!((top - 0.0119).abs() < 1e-4, "{top}");
        assert_eq!(p.extinction(-top - 1e-4, f, 0.02, never), (0.0, false));
        // ... while just inside it the octaves decide.
        assert_eq!(
            p.extinction(-top + 1e-4, f, 0.02, |_, _, _| Ok(0.0)),
            (0.0, true)
        );
        // Likewise no crease cuts deeper than the lift of the deepest, `c·m/(c + m)` with
        // `c = CREASE·total` and `m = MAX_CUT·F` (0.0573 here, not c = 0.0685): full density
        // below it plus the edge, without octaves.
        let (c, m) = (CREASE * total, MAX_CUT * f);
        let deepest = c * m / (c + m);
        assert!((deepest - 0.0573).abs() < 1e-4, "{deepest}");
        assert_eq!(
            p.extinction(deepest + 0.01 + 1e-4, f, 1.0, never),
            (10.0, true)
        );
        let (s, _) = p.extinction(deepest + 0.01 - 1e-3, f, 1.0, |_, _, _| Ok(-1.0));
        assert!(s < 10.0, "{s}");
        // And no density can lie beyond the reach.
        assert_eq!(p.extinction(-0.031, f, 0.03, never), (0.0, false));
        // A part smaller than the finest wavelength gets no billows: the plain edge ramp.
        assert_eq!(p.extinction(0.005, 0.0, 1.0, never), (5.0, true));
        assert_eq!(p.extinction(-0.001, 0.0, 1.0, never), (0.0, false));
    }

    #[test]
    fn a_hit_centred_on_its_closest_point_matches_the_direct_products() {
        // An eye 40 support radii away: an expansion of |o + t·d|² about the ray's origin would
        // lose about three of f32's seven digits to cancellation; centred on `t_m` it keeps them.
        let a_t = glam::Mat3A::from_cols(
            Vec3A::new(2.0, 0.3, -0.1),
            Vec3A::new(0.2, 1.5, 0.4),
            Vec3A::new(-0.3, 0.1, 3.0),
        );
        let o = Vec3A::new(-31.0, 17.5, 19.25);
        let d = -o.normalize() * 7.0 + Vec3A::new(0.09, -0.05, 0.02);
        let (t0, t1) = crate::render::camera::ray_ellipsoid(o, d).expect("the ray hits");
        let hit = Hit::new(
            3,
            (t0, t1),
            1.0,
            0.1,
            0.05,
            a_t,
            (o, d),
            (Vec3A::ZERO, Vec3A::ZERO),
        );
        for k in 0..=16 {
            let t = t0 + (t1 - t0) * k as f32 / 16.0;
            // The direct products in f64: the truth both f32 forms approximate.
            let q = o.as_dvec3() + d.as_dvec3() * t as f64;
            let u = q.length_squared();
            let grad = glam::DMat3::from_cols(
                a_t.x_axis.as_dvec3(),
                a_t.y_axis.as_dvec3(),
                a_t.z_axis.as_dvec3(),
            ) * q;
            let (s, u32) = hit.offset_and_radius2(t);
            let g = hit.a_t_q(s).as_dvec3();
            assert!((u32 as f64 - u).abs() < 2e-5, "t = {t}: {u}");
            assert!(
                (g - grad).length() < 2e-4 * grad.length().max(1.0),
                "{g} {grad}"
            );
        }
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
