//! The blend of the early cloud into the fitted target, as a path through two progresses:
//! `detail` (category III's growth and strength) and `fitted` (categories I and II going from
//! their early `B` to the fitted one).
//!
//! Blending both at once loses volume: the early ellipsoids cover space that the fitted model
//! gives to category III, and they withdraw before III has grown into it (the duck lost 9 % of
//! the final volume that way). So the plan samples the visible volume `V(detail, fitted)` on a
//! grid at plan time and takes the monotone lattice path from `(0, 0)` to `(1, 1)` whose
//! largest step down in volume is smallest — zero where such a path exists, so the volume never
//! decreases at the grid's nodes. Time is then spent along the path in proportion to the volume
//! it adds (with a share by steps, so no stretch is instant): the volume rises evenly.

use super::lerp;

/// Grid steps per progress axis (17 × 17 volumes at plan time).
pub(super) const GRID_STEPS: usize = 16;

/// Share of the blend's time spent in proportion to path steps rather than to volume.
const STEP_SHARE: f64 = 0.2;

/// Bisections of a held frame's fitted progress ([`BlendPath::held_at_frames`]).
const HOLD_BISECTIONS: usize = 6;

/// One point of the blend path: at eased blend time `u`, the two progresses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct BlendKnot {
    /// Eased blend time in `[0, 1]`.
    pub u: f64,
    /// Category III's progress in `[0, 1]`.
    pub detail: f64,
    /// Categories I and II's progress from the early `B` to the fitted one, in `[0, 1]`.
    pub fitted: f64,
}

/// The blend as a piecewise-linear path of knots (time-ordered, from `(0, 0, 0)` to
/// `(1, 1, 1)`); empty means both progresses equal the eased time.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct BlendPath {
    knots: Vec<BlendKnot>,
}

impl BlendPath {
    /// The least-dropping monotone path through `grid` (`grid[i][j]` = volume at detail
    /// `i / n`, fitted `j / n`, a square of side `n + 1`), paced by its volumes.
    pub fn least_dropping(grid: &[Vec<f64>]) -> BlendPath {
        let (cells, _) = least_dropping_path(grid);
        let n = (grid.len().max(2) - 1) as f64;
        let nodes: Vec<(f64, f64)> = cells
            .iter()
            .map(|&(i, j)| (i as f64 / n, j as f64 / n))
            .collect();
        let volumes: Vec<f64> = cells.iter().map(|&(i, j)| grid[i][j]).collect();
        BlendPath::paced(&nodes, &volumes)
    }

    /// Knots through `nodes` (progress pairs) whose times share the volume added
    /// (`1 − STEP_SHARE`) and the steps (`STEP_SHARE`).
    fn paced(nodes: &[(f64, f64)], volumes: &[f64]) -> BlendPath {
        let n = nodes.len();
        if n < 2 || volumes.len() != n {
            return BlendPath::default();
        }
        let mut v = volumes.to_vec();
        for k in 1..n {
            v[k] = v[k].max(v[k - 1]);
        }
        let rise = v[n - 1] - v[0];
        let knots = (0..n)
            .map(|k| {
                let steps = k as f64 / (n - 1) as f64;
                let by_volume = if rise > 0.0 {
                    (v[k] - v[0]) / rise
                } else {
                    steps
                };
                BlendKnot {
                    u: (1.0 - STEP_SHARE) * by_volume + STEP_SHARE * steps,
                    detail: nodes[k].0,
                    fitted: nodes[k].1,
                }
            })
            .collect();
        BlendPath { knots }
    }

    /// The knots as `[u, detail, fitted]` (what [`BlendPath::from_knots`] takes back).
    pub fn knots(&self) -> Vec<[f64; 3]> {
        self.knots
            .iter()
            .map(|k| [k.u, k.detail, k.fitted])
            .collect()
    }

    /// A path from knots `[u, detail, fitted]`, if they are one: finite, in `[0, 1]`, `u`
    /// non-decreasing (none, or at least two). `None` otherwise.
    pub fn from_knots(knots: &[[f64; 3]]) -> Option<BlendPath> {
        let valid = knots.len() != 1
            && knots
                .iter()
                .all(|k| k.iter().all(|v| (0.0..=1.0).contains(v)))
            && knots.windows(2).all(|w| w[0][0] <= w[1][0]);
        valid.then(|| BlendPath {
            knots: knots
                .iter()
                .map(|&[u, detail, fitted]| BlendKnot { u, detail, fitted })
                .collect(),
        })
    }

    /// This path checked at the shot's frames `(t, u)` (seconds, eased blend time; in time
    /// order) against `volume(t, detail, fitted)`: a frame inside the blend whose volume would
    /// fall below the frame before's keeps a lower fitted progress — halfway back to the frame
    /// before's, else the frame before's — since I/II going to their fitted `B` is what takes
    /// volume away. A frame that would hold more than the finished blend (the first frame at
    /// `u ≥ 1`) goes the least further toward fitted that brings it down to it, when that does
    /// not fall below the frame before: else the finished frame would lose volume (from the
    /// duck's centre (0, 0, 0) the last frame of the blend held 1.0007 of the final volume).
    /// The path unchanged when no frame is held; otherwise knots at the frames.
    pub fn held_at_frames(
        &self,
        frames: &[(f64, f64)],
        volume: impl Fn(f64, f64, f64) -> usize,
    ) -> BlendPath {
        let mut knots = vec![BlendKnot {
            u: 0.0,
            detail: 0.0,
            fitted: 0.0,
        }];
        let mut held = false;
        // The last frame before the blend (its volume is counted when first needed), then the
        // volume of the frame before.
        let mut start = None;
        let mut last: Option<usize> = None;
        let mut last_fitted = 0.0;
        // The finished blend's volume, a ceiling for the frames before it.
        let ceiling = frames
            .iter()
            .find(|f| f.1 >= 1.0)
            .map(|&(t, _)| volume(t, 1.0, 1.0));
        for &(t, u) in frames {
            if u >= 1.0 {
                break;
            }
            if u <= 0.0 {
                start = Some(t);
                continue;
            }
            let (detail, fitted) = self.at(u);
            let before = *last.get_or_insert_with(|| start.map_or(0, |t0| volume(t0, 0.0, 0.0)));
            let mut pick = (fitted, volume(t, detail, fitted));
            if pick.1 < before {
                // The most fitted progress that keeps the volume (bisection between the frame
                // before's and the path's), so the frame lags the path as little as it must.
                let (mut lo, mut hi) = (last_fitted, fitted);
                pick = (lo, volume(t, detail, lo));
                for _ in 0..HOLD_BISECTIONS {
                    let mid = 0.5 * (lo + hi);
                    let v = volume(t, detail, mid);
                    if v >= before {
                        (lo, pick) = (mid, (mid, v));
                    } else {
                        hi = mid;
                    }
                }
                held = true;
            }
            if let Some(cap) = ceiling
                && pick.1 > cap
                && let Some(lower) = lowered_to(cap, pick.0, |f| volume(t, detail, f))
                && lower.1 >= before
            {
                pick = lower;
                held = true;
            }
            knots.push(BlendKnot {
                u,
                detail,
                fitted: pick.0,
            });
            last = Some(pick.1);
            last_fitted = pick.0;
        }
        if !held {
            return self.clone();
        }
        knots.push(BlendKnot {
            u: 1.0,
            detail: 1.0,
            fitted: 1.0,
        });
        BlendPath { knots }
    }

    /// `(detail, fitted)` at eased blend time `u` (clamped to `[0, 1]`).
    pub fn at(&self, u: f64) -> (f64, f64) {
        let u = u.clamp(0.0, 1.0);
        let k = &self.knots;
        if k.len() < 2 {
            return (u, u);
        }
        let seg = k
            .windows(2)
            .position(|w| u <= w[1].u)
            .unwrap_or(k.len() - 2);
        let (a, b) = (k[seg], k[seg + 1]);
        let s = if b.u > a.u {
            ((u - a.u) / (b.u - a.u)).clamp(0.0, 1.0)
        } else {
            1.0
        };
        (lerp(a.detail, b.detail, s), lerp(a.fitted, b.fitted, s))
    }
}

/// The least fitted progress in `[from, 1]` whose volume (`volume(fitted)`) is at most `cap`,
/// with its volume ([`HOLD_BISECTIONS`] bisections); `None` when even the fitted end holds more.
fn lowered_to(cap: usize, from: f64, volume: impl Fn(f64) -> usize) -> Option<(f64, usize)> {
    let end = volume(1.0);
    if end > cap {
        return None;
    }
    let (mut lo, mut hi) = (from, 1.0);
    let mut best = (1.0, end);
    for _ in 0..HOLD_BISECTIONS {
        let mid = 0.5 * (lo + hi);
        let v = volume(mid);
        if v <= cap {
            (hi, best) = (mid, (mid, v));
        } else {
            lo = mid;
        }
    }
    Some(best)
}

/// The lattice path from `(0, 0)` to `(n, n)` through `grid` (steps `(1, k)` for any `k ≥ 0`,
/// or `(0, 1)`) that minimises the largest drop `grid[prev] − grid[next]` along it, then the
/// sum of its drops, then its length; ties go to the predecessor tried first (row before, from
/// its first column). Returns
/// the cells and the largest drop (0 when the volume never decreases along it).
fn least_dropping_path(grid: &[Vec<f64>]) -> (Vec<(usize, usize)>, f64) {
    let n = grid.len();
    if n == 0 {
        return (Vec::new(), 0.0);
    }
    // (largest drop, sum of drops, steps) to reach each cell, and the step taken into it.
    let mut cost = vec![vec![(f64::INFINITY, f64::INFINITY, usize::MAX); n]; n];
    let mut from = vec![vec![(0usize, 0usize); n]; n];
    cost[0][0] = (0.0, 0.0, 0);
    for i in 0..n {
        for j in 0..n {
            if i == 0 && j == 0 {
                continue;
            }
            // From the row before at any column up to this one (III's progress one step, I/II's
            // any number: where III adds much per step, I/II can blend far), or from the
            // column before in this row.
            let from_row = (0..=j).filter(|_| i > 0).map(|pj| (i - 1, pj));
            let preds = from_row.chain((j > 0).then(|| (i, j - 1)));
            for (pi, pj) in preds {
                let (worst, sum, steps) = cost[pi][pj];
                let drop = (grid[pi][pj] - grid[i][j]).max(0.0);
                let c = (worst.max(drop), sum + drop, steps + 1);
                if better(c, cost[i][j]) {
                    cost[i][j] = c;
                    from[i][j] = (pi, pj);
                }
            }
        }
    }
    let mut cells = vec![(n - 1, n - 1)];
    while cells.last() != Some(&(0, 0)) {
        let &(i, j) = cells.last().unwrap_or(&(0, 0));
        cells.push(from[i][j]);
    }
    cells.reverse();
    (cells, cost[n - 1][n - 1].0)
}

/// Lexicographic order on (largest drop, sum of drops, steps); a strict improvement only, so
/// the first predecessor tried wins ties.
fn better(a: (f64, f64, usize), b: (f64, f64, usize)) -> bool {
    if a.0 != b.0 {
        return a.0 < b.0;
    }
    if a.1 != b.1 {
        return a.1 < b.1;
    }
    a.2 < b.2
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The duck's measured volumes (rows detail 0..1, columns fitted 0..1, step 1/8): blending
    /// both at once dips; the chosen path never decreases.
    fn duck_grid() -> Vec<Vec<f64>> {
        [
            [
                0.804, 0.773, 0.739, 0.703, 0.664, 0.617, 0.567, 0.499, 0.194,
            ],
            [
                0.804, 0.773, 0.739, 0.703, 0.664, 0.617, 0.567, 0.499, 0.194,
            ],
            [
                0.804, 0.773, 0.739, 0.703, 0.664, 0.617, 0.567, 0.499, 0.204,
            ],
            [
                0.808, 0.778, 0.746, 0.712, 0.676, 0.634, 0.586, 0.518, 0.286,
            ],
            [
                0.867, 0.842, 0.814, 0.786, 0.755, 0.721, 0.681, 0.627, 0.473,
            ],
            [
                1.009, 0.988, 0.966, 0.941, 0.917, 0.889, 0.858, 0.818, 0.723,
            ],
            [
                1.095, 1.077, 1.057, 1.037, 1.015, 0.990, 0.962, 0.928, 0.855,
            ],
            [
                1.144, 1.127, 1.109, 1.089, 1.069, 1.047, 1.022, 0.989, 0.929,
            ],
            [
                1.191, 1.175, 1.159, 1.141, 1.122, 1.102, 1.078, 1.051, 1.000,
            ],
        ]
        .iter()
        .map(|r| r.to_vec())
        .collect()
    }

    #[test]
    fn the_diagonal_dips_and_the_chosen_path_does_not() {
        let g = duck_grid();
        let diagonal_drop = (1..g.len())
            .map(|k| g[k - 1][k - 1] - g[k][k])
            .fold(0.0, f64::max);
        assert!(
            diagonal_drop > 0.01,
            "the diagonal should dip: {diagonal_drop}"
        );
        let (cells, drop) = least_dropping_path(&g);
        assert_eq!(drop, 0.0);
        assert_eq!(cells.first(), Some(&(0, 0)));
        assert_eq!(cells.last(), Some(&(8, 8)));
        for w in cells.windows(2) {
            let ((a, b), (c, d)) = (w[0], w[1]);
            assert!(c >= a && d >= b && c - a <= 1 && (c, d) != (a, b));
            assert!(c > a || d == b + 1);
            assert!(g[c][d] >= g[a][b], "{:?} → {:?} drops", w[0], w[1]);
        }
    }

    #[test]
    fn the_path_is_paced_by_volume_and_runs_corner_to_corner() {
        let path = BlendPath::least_dropping(&duck_grid());
        assert_eq!(path.at(0.0), (0.0, 0.0));
        assert_eq!(path.at(1.0), (1.0, 1.0));
        let mut last = (0.0, 0.0);
        for k in 0..=100 {
            let p = path.at(k as f64 / 100.0);
            assert!(p.0 >= last.0 && p.1 >= last.1, "progress goes back at {k}");
            last = p;
        }
    }

    /// A volume that rises with `detail` and falls with `fitted`, dipping between the path's
    /// knots (the underside start's failure): the held path never falls at a frame, lags the
    /// path only where it must, and a path with no dip comes back unchanged.
    #[test]
    fn a_held_path_never_falls_at_a_frame() {
        let path = BlendPath {
            knots: vec![
                BlendKnot {
                    u: 0.0,
                    detail: 0.0,
                    fitted: 0.0,
                },
                BlendKnot {
                    u: 0.5,
                    detail: 0.5,
                    fitted: 0.5,
                },
                BlendKnot {
                    u: 1.0,
                    detail: 1.0,
                    fitted: 1.0,
                },
            ],
        };
        // Cells: detail adds 1000, fitted takes 1200 but only in its first half.
        let volume = |_t: f64, d: f64, f: f64| (1000.0 + 1000.0 * d - 1200.0 * f.min(0.5)) as usize;
        let frames: Vec<(f64, f64)> = (0..=20).map(|k| (k as f64, k as f64 / 20.0)).collect();
        let held = path.held_at_frames(&frames, volume);
        assert_ne!(held, path, "the path dips, so it is held");
        let mut last = volume(0.0, 0.0, 0.0);
        let mut lagged = 0;
        for &(t, u) in &frames[1..frames.len() - 1] {
            let (d, f) = held.at(u);
            let v = volume(t, d, f);
            assert!(v >= last, "frame {t} falls: {v} < {last}");
            assert!(f <= path.at(u).1 + 1e-12);
            lagged += usize::from(f < path.at(u).1);
            last = v;
        }
        assert!(lagged > 0 && held.at(1.0) == (1.0, 1.0));
        // Where fitted takes nothing, nothing is held.
        let rising = |_t: f64, d: f64, _f: f64| (1000.0 * d) as usize;
        assert_eq!(path.held_at_frames(&frames, rising), path);
    }

    /// A volume that overshoots the finished blend's near the end (the duck's centre start:
    /// 1.0007 of the final at the last frame of the blend): the frames are brought down to it,
    /// still never falling, so the finished frame loses nothing.
    #[test]
    fn a_frame_above_the_finished_blend_is_brought_down_to_it() {
        let path = BlendPath {
            knots: vec![
                BlendKnot {
                    u: 0.0,
                    detail: 0.0,
                    fitted: 0.0,
                },
                BlendKnot {
                    u: 0.9,
                    detail: 1.0,
                    fitted: 0.5,
                },
                BlendKnot {
                    u: 1.0,
                    detail: 1.0,
                    fitted: 1.0,
                },
            ],
        };
        // Detail adds 1000; fitted takes 100 over its second half: at detail 1 and fitted
        // ½ the volume is 2000, above the finished 1900.
        let volume =
            |_t: f64, d: f64, f: f64| (1000.0 + 1000.0 * d - 200.0 * (f - 0.5).max(0.0)) as usize;
        let frames: Vec<(f64, f64)> = (0..=20).map(|k| (k as f64, k as f64 / 20.0)).collect();
        assert!(
            path.held_at_frames(&frames, |_, _, _| 7) == path,
            "nothing to hold"
        );
        let held = path.held_at_frames(&frames, volume);
        let finished = volume(20.0, 1.0, 1.0);
        let mut last = volume(0.0, 0.0, 0.0);
        let mut lowered = 0;
        for &(t, u) in &frames[1..] {
            let (d, f) = held.at(u);
            let v = volume(t, d, f);
            assert!(v >= last, "frame {t} falls: {v} < {last}");
            assert!(
                v <= finished,
                "frame {t} holds {v}, above the finished {finished}"
            );
            lowered += usize::from(f > path.at(u).1);
            last = v;
        }
        assert!(lowered > 0 && held.at(1.0) == (1.0, 1.0));
    }

    #[test]
    fn an_empty_path_is_the_identity() {
        assert_eq!(BlendPath::default().at(0.3), (0.3, 0.3));
    }
}
