//! The one interpolation rule of keyed values over time (the keyed camera, the keyed target
//! transform): a cubic Hermite spline whose tangents are the Catmull–Rom ones for uneven times,
//! `(p[i+1] − p[i−1]) / (t[i+1] − t[i−1])`, one-sided at the ends. It passes through every key
//! with a continuous velocity; with two keys it is the straight line between them at a constant
//! rate. Before the first key and after the last it holds.

use std::ops::{Add, Mul, Sub};

/// Checks that key `i`'s time comes after key `i − 1`'s (the keys of a spline, a retime): the
/// message names the key as `what i` (`"camera keyframe 3"`).
pub fn check_increasing(what: &str, times: impl IntoIterator<Item = f64>) -> Result<(), String> {
    let mut before: Option<f64> = None;
    for (i, t) in times.into_iter().enumerate() {
        if let Some(b) = before.filter(|&b| t <= b) {
            return Err(format!(
                "{what} {i}: times must increase, got {t} after {b}"
            ));
        }
        before = Some(t);
    }
    Ok(())
}

/// The number type a value is scaled by (`f32` for the camera, `f64` for the transform).
pub trait Scalar: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> {
    /// `v` in this type.
    fn of(v: f64) -> Self;
}

impl Scalar for f32 {
    #[inline]
    fn of(v: f64) -> f32 {
        v as f32
    }
}

impl Scalar for f64 {
    #[inline]
    fn of(v: f64) -> f64 {
        v
    }
}

/// The value at `t` of the spline through `value(j)` at `times[j]` (at least two, strictly
/// increasing; see the module doc). `V` is any vector of `S`s (a point, an angle triple, a
/// scalar).
pub fn catmull_rom<S, V>(times: &[f64], t: f64, value: impl Fn(usize) -> V) -> V
where
    S: Scalar,
    V: Copy + Add<Output = V> + Sub<Output = V> + Mul<S, Output = V> + std::ops::Div<S, Output = V>,
{
    let n = times.len();
    assert!(n >= 2, "a spline needs at least two keys, got {n}");
    let t = t.clamp(times[0], times[n - 1]);
    let i = times.windows(2).position(|w| t <= w[1]).unwrap_or(n - 2);
    let (t0, t1) = (times[i], times[i + 1]);
    let h = t1 - t0;
    let s = S::of(((t - t0) / h).clamp(0.0, 1.0));
    let tangent = |j: usize| -> V {
        let (a, b) = (j.saturating_sub(1), (j + 1).min(n - 1));
        (value(b) - value(a)) / S::of(times[b] - times[a])
    };
    let (one, two, three) = (S::of(1.0), S::of(2.0), S::of(3.0));
    let (s2, s3) = (s * s, s * s * s);
    let (h00, h10) = (two * s3 - three * s2 + one, s3 - two * s2 + s);
    let (h01, h11) = (three * s2 - two * s3, s3 - s2);
    value(i) * h00
        + tangent(i) * (h10 * S::of(h))
        + value(i + 1) * h01
        + tangent(i + 1) * (h11 * S::of(h))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn two_keys_are_a_straight_line_and_keys_are_passed() {
        let times = [1.0, 3.0];
        let p = [DVec3::new(0.0, 1.0, 2.0), DVec3::new(4.0, -1.0, 2.0)];
        for u in [0.0, 0.25, 0.5, 0.9, 1.0] {
            let got: DVec3 = catmull_rom::<f64, _>(&times, 1.0 + 2.0 * u, |j| p[j]);
            assert!((got - p[0].lerp(p[1], u)).length() < 1e-12, "{u}: {got}");
        }
        let held: DVec3 = catmull_rom::<f64, _>(&times, -5.0, |j| p[j]);
        assert_eq!(held, p[0]);
        let times = [0.0, 1.0, 4.0];
        let v = [0.0, 2.0, -1.0];
        for (j, &t) in times.iter().enumerate() {
            let got: f64 = catmull_rom::<f64, _>(&times, t, |k| v[k]);
            assert!((got - v[j]).abs() < 1e-12);
        }
        // No jump in velocity at the middle key.
        let d = 1e-6;
        let at = |t: f64| -> f64 { catmull_rom::<f64, _>(&times, t, |k| v[k]) };
        let (a, b) = ((at(1.0) - at(1.0 - d)) / d, (at(1.0 + d) - at(1.0)) / d);
        assert!((a - b).abs() < 1e-4, "{a} vs {b}");
    }
}
