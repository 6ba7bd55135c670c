//! Seed-free 3-D gradient noise (Perlin 2002, "Improving Noise") and the cumulus billows built
//! from it ([`Billows`]: self-similar octaves of rounded `|noise|`, each present only where the
//! cloud is large enough to hold it).
//!
//! In: a point in noise space (the renderer maps each blob's local frame there, with a seeded
//! per-blob offset, so the seed enters through the offset and the lattice hash is fixed).
//! Out: values in about `[−1, 1]`. Pure functions: identical on every thread and platform
//! (only `+ − × floor` on f32, no transcendental functions).

mod gradient;
mod lanes;
mod simd;

use glam::Vec3A;

pub(crate) use simd::gradient_noise;

/// Wavelength ratio between billow octaves: slightly off 2 so octave lattices do not line up.
pub(crate) const LACUNARITY: f32 = 2.03;

/// Shift between octaves (noise units), so the lattice zeros at the origin do not coincide.
const OCTAVE_SHIFT: Vec3A = Vec3A::new(17.31, -9.77, 5.13);

/// Direction each octave drifts along with the evolution phase (different per octave, so the
/// sum changes shape instead of sliding as a whole).
const EVOLVE_DIR: [Vec3A; 3] = [
    Vec3A::new(0.0, 1.0, 0.0),
    Vec3A::new(0.6, -0.8, 0.0),
    Vec3A::new(-0.48, 0.0, 0.877),
];

/// Billow height of gradient noise `n`: `x(2 − x)` with `x = min(1, 2|n|)` — 0 on the sheets
/// where `n` crosses zero (the creases between puffs), rising steeply and rounding off on top
/// (the puffs of cumulus; Wrenninge's pyroclastic `|noise|`, rounded).
#[cfg(test)]
#[inline]
pub(crate) fn billow(p: Vec3A) -> f32 {
    billow_of(gradient_noise(p))
}

/// [`billow`] of the noise value `n`.
#[inline]
fn billow_of(n: f32) -> f32 {
    let x = (2.0 * n.abs()).min(1.0);
    x * (2.0 - x)
}

/// Most octaves [`Billows`] holds: the scene's limit, checked by [`crate::render::NoiseSettings::validate`].
pub(crate) const MAX_OCTAVES: usize = crate::render::NoiseSettings::MAX_OCTAVES;

/// Share of an octave's depth that lies below the surface: a billow pushes the surface out by
/// up to `(1 − CREASE)·a_k` on its top and cuts in by up to `CREASE·a_k` in its creases. A
/// little above the mean of [`billow`] (≈ 0.5): the creases between puffs cut deeper than the
/// tops push out, which keeps the outline of a small cloud crisp (at 0.65 a young one-blob
/// puff's outline came out soft), at the cost of a cloud a few percent inside the model's
/// surface on average (silhouette coverage 0.9–1.0 of the model's).
pub(crate) const CREASE: f32 = 0.70;

/// Hurst exponent of the octaves' depths: octave `k` is `a·λ_k·(λ_0/λ_k)^(1−H)` deep. `H = 1`
/// would be strictly self-similar (depth in proportion to wavelength); measured cloud outlines
/// are rougher toward small scales (perimeter dimension ≈ 1.35 over 1–1000 km, Lovejoy 1982:
/// `H ≈ 0.65`). 0.9 lets the finest octaves show on a young, small cloud's outline; rougher
/// (0.7) puts more detail at the pixel scale than one ray a pixel resolves (the duck's single
/// scattering against Mitsuba went from 4.9 % to 5.2 %).
pub(crate) const HURST: f32 = 0.9;

/// Ratios `F / λ` (local feature size over an octave's wavelength) between which an octave
/// fades in: absent on a part smaller than 0.2 of its wavelength, full on one 0.6 as large.
const FADE_IN: (f32, f32) = (0.2, 0.6);

/// The cumulus's billows: octaves of [`billow`] whose wavelengths are fixed in world units
/// (anchored to each blob's frame by the caller) and whose depths follow their wavelengths
/// (`∝ λ^H`, [`HURST`]: nearly in proportion, the finer ones a little rougher), each present
/// only where the local feature size is larger than its wavelength, so a small blob, a thin
/// leg and a fat body all get billows of their own size without the texture stretching as
/// blobs grow.
///
/// The displacement at noise point `p` (octave 0 has unit wavelength there) of a part with
/// feature size `F` is `D = Σ_k a_k·s(F/λ_k)·(billow_k − CREASE)` (world units, positive =
/// outward), `a_k = a·λ_k·(λ_0/λ_k)^(1−H)` octave `k`'s depth, `s` a smoothstep over
/// [`FADE_IN`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Billows {
    n: usize,
    /// World wavelength of each octave.
    wavelength: [f32; MAX_OCTAVES],
    /// Evolution drift of each octave (noise units).
    drift: [Vec3A; MAX_OCTAVES],
    /// Full depth of each octave (world units): `a·λ_k·(λ_0/λ_k)^(1−`[`HURST`]`)`.
    depth: [f32; MAX_OCTAVES],
    /// Feature sizes at and above which octave `k` is surely at full depth (`F/λ_k ≥`
    /// [`FADE_IN`]`.1`), and at and below which it is surely absent (`≤ FADE_IN.0`), with a
    /// margin for rounding: between them [`Billows::depths`] divides, outside it need not.
    full_from: [f32; MAX_OCTAVES],
    absent_to: [f32; MAX_OCTAVES],
    /// `Σ_k` of the full depths (summed in [`Billows::depths`]' order): no part's total depth
    /// is larger.
    max_total: f32,
}

impl Billows {
    /// `octaves` (at most [`MAX_OCTAVES`]) octaves from `largest` (world units) down, each
    /// [`LACUNARITY`] times finer, none finer than `finest`; octave 0 `amplitude × largest` deep,
    /// the others `amplitude × wavelength × (largest/wavelength)^(1−`[`HURST`]`)`;
    /// evolution `phase` (noise units, 0 = frozen).
    pub(crate) fn new(octaves: u32, largest: f32, finest: f32, amplitude: f32, phase: f32) -> Self {
        let amplitude = amplitude.max(0.0);
        let mut b = Billows {
            n: 0,
            wavelength: [0.0; MAX_OCTAVES],
            drift: [Vec3A::ZERO; MAX_OCTAVES],
            depth: [0.0; MAX_OCTAVES],
            full_from: [f32::INFINITY; MAX_OCTAVES],
            absent_to: [f32::NEG_INFINITY; MAX_OCTAVES],
            max_total: 0.0,
        };
        if !(largest > 0.0) || amplitude == 0.0 {
            return b;
        }
        let mut lambda = largest;
        for o in 0..(octaves as usize).min(MAX_OCTAVES) {
            if lambda < finest {
                break;
            }
            b.wavelength[o] = lambda;
            b.depth[o] = amplitude * lambda * (largest / lambda).powf(1.0 - HURST);
            b.drift[o] = EVOLVE_DIR[o % 3] * (phase * (1.0 + 0.5 * o as f32));
            b.n = o + 1;
            lambda /= LACUNARITY;
        }
        b.set_bounds();
        b
    }

    /// The per-octave shortcuts of [`Billows::depths`] and [`Billows::max_total`] for the
    /// first `n` octaves. The thresholds are the exact products in f64 widened by 10⁻⁶ (far
    /// more than the one rounding to f32), so that past them the division `F/λ` lands surely
    /// beyond the fade's ends and the smoothstep is exactly 1 or 0.
    fn set_bounds(&mut self) {
        let (lo, hi) = FADE_IN;
        self.max_total = 0.0;
        for o in 0..MAX_OCTAVES {
            if o < self.n {
                let l = self.wavelength[o] as f64;
                self.full_from[o] = (hi as f64 * l * (1.0 + 1e-6)) as f32;
                self.absent_to[o] = (lo as f64 * l * (1.0 - 1e-6)) as f32;
                self.max_total += self.depth[o];
            } else {
                self.full_from[o] = f32::INFINITY;
                self.absent_to[o] = f32::NEG_INFINITY;
            }
        }
    }

    /// An upper bound of [`Billows::total_depth`] for any feature size (each octave at full
    /// depth): where even it cannot reach a point, no billow can.
    #[inline]
    pub(crate) fn max_total(&self) -> f32 {
        self.max_total
    }

    /// The same billows without the octaves finer than `finest` (world units): for sampling
    /// on a lattice that cannot hold them (the light grid).
    pub(crate) fn coarsened(&self, finest: f32) -> Self {
        let mut b = *self;
        b.n = self.wavelength[..self.n]
            .iter()
            .take_while(|&&l| l >= finest)
            .count();
        b.set_bounds();
        b
    }

    /// Number of octaves.
    #[cfg(test)]
    pub(crate) fn octaves(&self) -> usize {
        self.n
    }

    /// Depth `a·λ_k·s(F/λ_k)` of each octave on a part of feature size `feature`, the
    /// number of leading octaves that are non-zero, and the depths' sum (in octave order: the
    /// bits of [`Billows::total_depth`]).
    #[inline]
    pub(crate) fn depths(&self, feature: f32) -> ([f32; MAX_OCTAVES], usize, f32) {
        let mut d = [0.0; MAX_OCTAVES];
        let mut n = 0;
        // From −0.0, as `Sum` folds: the bits of `d[..n].iter().sum()` also for `n = 0`.
        let mut total = -0.0f32;
        let (lo, hi) = FADE_IN;
        for o in 0..self.n {
            let l = self.wavelength[o];
            // Past the fade's ends the smoothstep is exactly 1 or 0: no division.
            let s = if feature >= self.full_from[o] {
                1.0
            } else if feature <= self.absent_to[o] {
                0.0
            } else {
                let r = ((feature / l - lo) / (hi - lo)).clamp(0.0, 1.0);
                r * r * (3.0 - 2.0 * r)
            };
            d[o] = self.depth[o] * s;
            if s > 0.0 {
                n = o + 1;
                // The absent octaves are the coarse ones (a prefix): skipping their zeros
                // gives the same bits.
                total += d[o];
            }
        }
        (d, n, total)
    }

    /// Total depth `Σ_k a·λ_k·s(F/λ_k)`: the displacement lies in
    /// `[−CREASE·total, (1 − CREASE)·total]`.
    #[cfg(test)]
    #[inline]
    pub(crate) fn total_depth(&self, feature: f32) -> f32 {
        self.depths(feature).2
    }

    /// The blend `Σ_j w_j D(p_j) / √(Σ_j w_j²)` of several blobs' displacements (`norm` =
    /// `1/√(Σ w²)`), octave by octave from the coarsest: after each octave `settled(lo, hi)`
    /// gets the range the final blend can still take and may end the evaluation with its own
    /// answer (`Err`), so the fine octaves run only where they can still matter. `points` are
    /// the blobs' noise points (advanced in place).
    ///
    /// Where the noise runs eight points at once ([`lanes::wide`]), the octaves' noises
    /// are formed ahead, eight (octave, blob) lanes at a time in the order they are summed, and
    /// the sums and checks then read them: the same values in the same order, so the same
    /// bits as one noise at a time, at the cost of a few lanes past an early answer.
    #[inline]
    pub(crate) fn blend<R>(
        &self,
        points: &mut [Vec3A],
        weights: &[f32],
        norm: f32,
        depths: &[f32; MAX_OCTAVES],
        n: usize,
        settled: impl FnMut(f32, f32) -> Option<R>,
    ) -> Result<f32, R> {
        self.blend_in(lanes::wide(), points, weights, norm, depths, n, settled)
    }

    /// [`Billows::blend`], forming the noises ahead in lanes when `wide`.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn blend_in<R>(
        &self,
        wide: bool,
        points: &mut [Vec3A],
        weights: &[f32],
        norm: f32,
        depths: &[f32; MAX_OCTAVES],
        n: usize,
        mut settled: impl FnMut(f32, f32) -> Option<R>,
    ) -> Result<f32, R> {
        let spread = weights.iter().sum::<f32>() * norm;
        let mut rest: f32 = depths[..n].iter().sum();
        let mut sum = 0.0;
        let n = n.min(self.n);
        // Octave `o`'s weighted billows summed: the blend so far, and maybe an answer.
        let mut add_octave = |o: usize, acc: f32| {
            sum += depths[o] * acc * norm;
            rest -= depths[o];
            let r = rest.max(0.0) * spread;
            settled(sum - CREASE * r, sum + (1.0 - CREASE) * r)
        };
        let count = |m: usize| {
            crate::render::counters::add(crate::render::counters::Counter::NoiseOctaves, m as u64)
        };
        // A narrow noise: one at a time, as each octave is reached. (Forming only the later
        // octaves ahead, after the first one or two alone, was slower on the 1080p duck: 7.1
        // against 6.5–6.8 s CPU.)
        if !wide {
            for o in 0..n {
                if depths[o] > 0.0 {
                    count(points.len());
                    let mut acc = 0.0;
                    for (q, &w) in points.iter().zip(weights) {
                        acc += w * (billow_of(gradient_noise(*q + self.drift[o])) - CREASE);
                    }
                    if let Some(answer) = add_octave(o, acc) {
                        return Err(answer);
                    }
                }
                to_next_octave(points, o);
            }
        } else {
            let mut ahead = Ahead::new();
            for o in 0..n {
                if depths[o] > 0.0 {
                    count(points.len());
                    let mut acc = 0.0;
                    for &w in weights {
                        acc += w * (ahead.next(self, points, depths, n) - CREASE);
                    }
                    if let Some(answer) = add_octave(o, acc) {
                        return Err(answer);
                    }
                }
            }
        }
        Ok(sum)
    }

    /// Displacement (world units, positive outward) at noise point `p` for octave depths
    /// `depths` (from [`Billows::depths`]; only the first `n` are evaluated).
    #[cfg(test)]
    #[inline]
    pub(crate) fn displacement(&self, p: Vec3A, depths: &[f32; MAX_OCTAVES], n: usize) -> f32 {
        let mut sum = 0.0;
        let mut q = p;
        for o in 0..n.min(self.n) {
            if depths[o] > 0.0 {
                sum += depths[o] * (billow(q + self.drift[o]) - CREASE);
            }
            q = q * LACUNARITY + OCTAVE_SHIFT * (o + 1) as f32;
        }
        sum
    }
}

/// Advance the blobs' noise points from octave `o`'s lattice to octave `o + 1`'s (in place;
/// the one order both of [`Billows::blend`]'s paths use, so they see the same bits).
#[inline]
fn to_next_octave(points: &mut [Vec3A], o: usize) {
    for q in points.iter_mut() {
        *q = *q * LACUNARITY + OCTAVE_SHIFT * (o + 1) as f32;
    }
}

/// The billow values of [`Billows::blend`]'s (octave, blob) pairs, formed ahead in lanes of
/// eight: the octaves with depth in order, each
/// blob of an octave in turn, the blobs' points advanced to the next octave's lattice as each
/// octave is passed (in place, as the one-at-a-time loop did).
struct Ahead {
    values: [f32; 8],
    /// Values formed, and read, of `values`.
    len: usize,
    read: usize,
    /// The next (octave, blob) to form.
    octave: usize,
    blob: usize,
}

impl Ahead {
    #[inline]
    fn new() -> Ahead {
        Ahead {
            values: [0.0; 8],
            len: 0,
            read: 0,
            octave: 0,
            blob: 0,
        }
    }

    /// The next pair's billow value.
    #[inline]
    fn next(
        &mut self,
        b: &Billows,
        points: &mut [Vec3A],
        depths: &[f32; MAX_OCTAVES],
        n: usize,
    ) -> f32 {
        if self.read == self.len {
            self.fill(b, points, depths, n);
        }
        self.read += 1;
        self.values[self.read - 1]
    }

    /// Form the next lanes' values.
    #[inline(never)]
    fn fill(&mut self, b: &Billows, points: &mut [Vec3A], depths: &[f32; MAX_OCTAVES], n: usize) {
        let (mut x, mut y, mut z) = ([0.0f32; 8], [0.0f32; 8], [0.0f32; 8]);
        let mut k = 0;
        while k < 8 && self.octave < n {
            if depths[self.octave] > 0.0 && self.blob < points.len() {
                let p = points[self.blob] + b.drift[self.octave];
                (x[k], y[k], z[k]) = (p.x, p.y, p.z);
                k += 1;
                self.blob += 1;
            } else {
                // Past this octave's blobs (or an octave without depth): on to the next.
                to_next_octave(points, self.octave);
                self.octave += 1;
                self.blob = 0;
            }
        }
        let v = lanes::gradient_noise8(&x, &y, &z);
        for (out, n) in self.values.iter_mut().zip(v) {
            *out = billow_of(n);
        }
        self.len = k;
        self.read = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn walk(i: usize) -> Vec3A {
        let t = i as f32;
        Vec3A::new(t * 0.137, (t * 0.071).sin() * 40.0, t * 0.011)
    }

    #[test]
    fn noise_is_zero_on_lattice_and_billows_are_bounded_and_varied() {
        assert_eq!(gradient_noise(Vec3A::new(3.0, -2.0, 7.0)), 0.0);
        let b = Billows::new(4, 1.0, 0.0, 0.25, 0.0);
        let (depths, n, _) = b.depths(10.0);
        assert_eq!(n, 4);
        let total = b.total_depth(10.0);
        let (mut lo, mut hi, mut sum, mut sq) = (f32::MAX, f32::MIN, 0.0f64, 0.0f64);
        let count = 20_000;
        for i in 0..count {
            let v = b.displacement(walk(i), &depths, n);
            lo = lo.min(v);
            hi = hi.max(v);
            sum += v as f64;
            sq += (v * v) as f64;
        }
        let mean = sum / count as f64;
        let sd = (sq / count as f64 - mean * mean).sqrt();
        // Bounded by the documented range, using a good part of it, both signs.
        assert!(lo >= -CREASE * total && hi <= (1.0 - CREASE) * total);
        assert!(
            lo < -0.15 * total && hi > 0.15 * total,
            "range {lo}..{hi} of {total}"
        );
        // On average a little inside: the creases cut deeper than the tops push out (`CREASE`
        // above the billows' mean of about a half).
        let t = total as f64;
        assert!(mean < -0.1 * t && mean > -0.3 * t, "mean {mean} of {total}");
        assert!(sd > 0.05 * total as f64, "sd {sd}");
    }

    #[test]
    fn octaves_follow_the_feature_size_and_the_finest_wavelength() {
        let b = Billows::new(8, 0.2, 0.01, 0.25, 0.0);
        // 0.2 / 2.03^k ≥ 0.01: k ≤ 4.
        assert_eq!(b.octaves(), 5);
        assert_eq!(b.coarsened(0.05).octaves(), 2);
        // A part just below FADE_IN.0 of octave 1's wavelength gets neither octave 0 nor 1,
        // part of octave 2, and depths in proportion to wavelength^HURST where full.
        let f = 0.99 * FADE_IN.0 * 0.2 / LACUNARITY;
        let (d, n, _) = b.depths(f);
        assert_eq!(d[0], 0.0);
        assert_eq!(d[1], 0.0);
        assert!(d[2] > 0.0 && d[2] < b.depth[2]);
        assert!((d[4] / d[3] - LACUNARITY.powf(-HURST)).abs() < 1e-5);
        assert!((d[3] - 0.25 * 0.2 * LACUNARITY.powf(-3.0 * HURST)).abs() < 1e-6);
        assert_eq!(n, 5);
        // No feature, no billows; none without amplitude.
        assert_eq!(b.total_depth(0.0), 0.0);
        assert_eq!(Billows::new(8, 0.2, 0.01, 0.0, 0.0).octaves(), 0);
    }

    #[test]
    fn depths_shortcuts_give_the_divisions_bits() {
        let b = Billows::new(8, 0.37, 0.001, 0.5, 0.0);
        let (lo, hi) = FADE_IN;
        for k in 0..100_000 {
            let feature = 1e-4 * 1.0002f32.powi(k);
            let (d, n, total) = b.depths(feature);
            assert_eq!(total.to_bits(), d[..n].iter().sum::<f32>().to_bits());
            let mut last = 0;
            for o in 0..b.octaves() {
                let l = b.wavelength[o];
                let r = ((feature / l - lo) / (hi - lo)).clamp(0.0, 1.0);
                let s = r * r * (3.0 - 2.0 * r);
                assert_eq!(d[o].to_bits(), (b.depth[o] * s).to_bits(), "{feature} {o}");
                if s > 0.0 {
                    last = o + 1;
                }
            }
            assert_eq!(n, last);
            assert!(d[..n].iter().sum::<f32>() <= b.max_total());
        }
        // Near each threshold, densely.
        for o in 0..b.octaves() {
            for edge in [b.full_from[o], b.absent_to[o]] {
                let mut f = edge;
                for _ in 0..64 {
                    f = f.next_down();
                }
                for _ in 0..128 {
                    let (d, _, _) = b.depths(f);
                    let l = b.wavelength[o];
                    let r = ((f / l - lo) / (hi - lo)).clamp(0.0, 1.0);
                    let s = r * r * (3.0 - 2.0 * r);
                    assert_eq!(d[o].to_bits(), (b.depth[o] * s).to_bits());
                    f = f.next_up();
                }
            }
        }
    }

    #[test]
    fn blend_ahead_in_lanes_has_the_one_at_a_time_bits() {
        let b = Billows::new(8, 1.0, 0.0, 0.5, 0.3);
        for case in 0..3000 {
            let m = 1 + case % 5;
            let points: Vec<Vec3A> = (0..m).map(|j| walk(case * 7 + j) * 0.01).collect();
            let weights: Vec<f32> = (0..m).map(|j| 0.2 + 0.3 * j as f32).collect();
            let norm = 1.0 / weights.iter().map(|w| w * w).sum::<f32>().sqrt();
            let feature = [0.05, 0.3, 10.0][case % 3];
            let (depths, n, _) = b.depths(feature);
            // Stop after a case-dependent number of octaves, with the range seen then.
            let stop = case % (n + 2);
            let run = |wide: bool| {
                let mut seen = 0;
                let mut p = points.clone();
                b.blend_in(
                    wide,
                    &mut p,
                    &weights,
                    norm,
                    &depths,
                    n,
                    |lo: f32, hi: f32| {
                        seen += 1;
                        (seen == stop).then_some((lo.to_bits(), hi.to_bits()))
                    },
                )
            };
            let (wide, narrow) = (run(true), run(false));
            assert_eq!(
                wide.map(f32::to_bits),
                narrow.map(f32::to_bits),
                "case {case}"
            );
            if m == 1 && stop == 0 {
                let whole = b.displacement(points[0], &depths, n) * weights[0] * norm;
                assert!(
                    (narrow.unwrap_or(f32::NAN) - whole).abs() < 1e-5,
                    "case {case}"
                );
            }
        }
    }

    #[test]
    fn billows_are_continuous_and_evolve() {
        let p = Vec3A::new(1.234, 5.678, -9.1);
        let e = Vec3A::splat(1e-4);
        let b = |phase| Billows::new(3, 1.0, 0.0, 0.25, phase);
        let (d, n, _) = b(0.0).depths(10.0);
        let v = b(0.0).displacement(p, &d, n);
        assert!((v - b(0.0).displacement(p + e, &d, n)).abs() < 1e-2);
        assert!((v - b(1e-4).displacement(p, &d, n)).abs() < 1e-2);
        assert_ne!(v, b(0.37).displacement(p, &d, n));
    }
}
