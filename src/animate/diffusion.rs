//! The diffusion scheme (paper §5.2.2): the target spreads out from one piece of cloud.
//!
//! - **Categories** (in the model's selection order, live blobs only): I = the first blob (the
//!   largest), II = the next `category_ii` fraction of the live blobs (rounded, at least one
//!   when there are ≥ 2), III = the rest. Dead blobs (`B = 0`) stay hidden throughout.
//! - **Order.** Blob I is shown first. Then, repeatedly, the next blob of category II is the
//!   remaining one whose centre has the smallest signed distance to the surface of the blobs
//!   shown so far (negative inside). The distance is estimated as `−F/|∇F|` of the visible
//!   blobs' field, clamped to `±D` (`D` = target diagonal); a centre outside every visible
//!   support gets `D + (distance to the nearest visible centre)`, so nearer blobs come first.
//!   Ties go to the lower index. Category III keeps its selection order.
//! - **Schedule.** Blob I is visible at full size from the first frame. The blobs of II start
//!   at evenly spaced times, each growing over `grow_seconds`; all of III start together and
//!   grow over `final_grow_seconds`, finishing when the motion ends. Both durations shrink if
//!   the shot is too short to fit them (each at most a third of the motion).
//! - **Growth.** A new blob starts at the centre of the nearest blob (by centre distance) shown
//!   before it, at zero size, and moves to its place while its semi-axes grow to full size
//!   (smoothstep in time); A, B and the rotation are the target's. Before it starts, a blob is
//!   hidden (`B = 0`). The visible count never decreases.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::{AnimateError, Timeline, blob_bounds, invalid, smoothstep};
use crate::blobby::{Blob, BlobField};

/// Settings of the diffusion scheme. Every field has a default.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DiffusionConfig {
    /// Seconds each category-II blob takes to move out and grow to full size.
    pub grow_seconds: f64,
    /// Seconds category III takes to grow in, all together, at the end.
    pub final_grow_seconds: f64,
    /// Fraction of all blobs in category II (after the first blob), in `[0, 1]`.
    pub category_ii: f64,
    /// Seconds the finished target holds still at the end of the shot.
    pub hold_seconds: f64,
}

impl Default for DiffusionConfig {
    fn default() -> Self {
        DiffusionConfig {
            grow_seconds: 0.6,
            final_grow_seconds: 1.0,
            category_ii: 0.10,
            hold_seconds: 0.5,
        }
    }
}

impl DiffusionConfig {
    /// Check ranges; errors name the field as `animation.NAME`.
    pub fn validate(&self) -> Result<(), AnimateError> {
        for (name, v) in [
            ("grow_seconds", self.grow_seconds),
            ("final_grow_seconds", self.final_grow_seconds),
            ("hold_seconds", self.hold_seconds),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(
                    &format!("animation.{name}"),
                    format!("must be a finite number of seconds ≥ 0, got {v}"),
                ));
            }
        }
        if !(self.category_ii.is_finite() && (0.0..=1.0).contains(&self.category_ii)) {
            return Err(invalid(
                "animation.category_ii",
                format!("must be a fraction in [0, 1], got {}", self.category_ii),
            ));
        }
        Ok(())
    }
}

/// A planned diffusion: display order and per-blob schedule.
#[derive(Clone, Debug)]
pub struct DiffusionPlan {
    target: Vec<Blob>,
    order: Vec<usize>,
    category_ii: usize,
    /// Per blob (by index): where it starts, when it starts and how long it grows (seconds).
    origin: Vec<DVec3>,
    start: Vec<f64>,
    grow: Vec<f64>,
    timeline: Timeline,
}

impl DiffusionPlan {
    /// Plan the scheme for `target` with iso-level `threshold` (config already validated).
    pub fn new(
        cfg: &DiffusionConfig,
        target: &[Blob],
        threshold: f64,
        timeline: Timeline,
    ) -> DiffusionPlan {
        let n = target.len();
        let n_live = target.iter().filter(|b| b.is_live()).count();
        let n_ii = category_ii_count(n_live, cfg.category_ii);
        let order = display_order(target, threshold, n_ii);
        // Start points: the nearest blob shown earlier (III: the nearest of I and II).
        let mut origin = vec![DVec3::ZERO; n];
        for (pos, &i) in order.iter().enumerate() {
            let earlier = &order[..pos.min(1 + n_ii)];
            origin[i] = earlier
                .iter()
                .map(|&j| target[j].center)
                .min_by(|a, b| {
                    a.distance_squared(target[i].center)
                        .total_cmp(&b.distance_squared(target[i].center))
                })
                .unwrap_or(target[i].center);
        }
        // Schedule: II evenly spaced, III together at the end.
        let motion = timeline.motion_seconds();
        let g2 = cfg.grow_seconds.min(motion / 3.0);
        let g3 = cfg.final_grow_seconds.min(motion / 3.0);
        let iii_start = motion - g3;
        let mut start = vec![0.0; n];
        let mut grow = vec![0.0; n];
        let ii_window = (iii_start - g2).max(0.0);
        for (k, &i) in order.iter().enumerate().skip(1) {
            if k <= n_ii {
                start[i] = if n_ii > 1 {
                    ii_window * (k - 1) as f64 / (n_ii - 1) as f64
                } else {
                    0.0
                };
                grow[i] = g2;
            } else {
                start[i] = iii_start;
                grow[i] = g3;
            }
        }
        DiffusionPlan {
            target: target.to_vec(),
            order,
            category_ii: n_ii,
            origin,
            start,
            grow,
            timeline,
        }
    }

    /// The display order of the live blobs: category I, then II, then III.
    pub fn order(&self) -> &[usize] {
        &self.order
    }

    /// Size of category II.
    pub fn category_ii_len(&self) -> usize {
        self.category_ii
    }

    /// The shot's timeline.
    pub fn timeline(&self) -> Timeline {
        self.timeline
    }

    /// The blobs of frame `k`; the target itself once the motion is over.
    pub fn frame(&self, k: usize) -> Vec<Blob> {
        if self.timeline.progress(k) >= 1.0 {
            return self.target.clone();
        }
        let t = self.timeline.time(k);
        let first = self.order.first().copied();
        self.target
            .iter()
            .enumerate()
            .map(|(i, blob)| {
                if Some(i) == first || !blob.is_live() {
                    return *blob;
                }
                let (s, g) = (self.start[i], self.grow[i]);
                if t <= s {
                    return Blob {
                        center: self.origin[i],
                        b: 0.0,
                        ..*blob
                    };
                }
                if g <= 0.0 || t >= s + g {
                    return *blob;
                }
                let e = smoothstep((t - s) / g);
                Blob {
                    center: self.origin[i].lerp(blob.center, e),
                    semi_axes: blob.semi_axes * e,
                    ..*blob
                }
            })
            .collect()
    }
}

/// Number of category-II blobs among `n`: `round(fraction · n)`, at least 1 when `n ≥ 2` and the
/// fraction is positive, at most `n − 1`.
pub fn category_ii_count(n: usize, fraction: f64) -> usize {
    if n < 2 {
        return 0;
    }
    let k = (fraction * n as f64).round() as usize;
    let k = if fraction > 0.0 { k.max(1) } else { k };
    k.min(n - 1)
}

/// Display order of the live blobs: the first, then the next `n_ii` (category II) greedily by
/// signed distance to the visible surface, then the rest (category III) in selection order.
pub fn display_order(blobs: &[Blob], threshold: f64, n_ii: usize) -> Vec<usize> {
    let live: Vec<usize> = (0..blobs.len()).filter(|&i| blobs[i].is_live()).collect();
    let Some((&first, rest)) = live.split_first() else {
        return Vec::new();
    };
    let n_ii = n_ii.min(rest.len());
    let diag = blob_bounds(blobs).diagonal().max(f64::MIN_POSITIVE);
    let mut order = vec![first];
    let mut remaining: Vec<usize> = rest[..n_ii].to_vec();
    let mut visible: Vec<Blob> = vec![blobs[first]];
    while !remaining.is_empty() {
        let field = BlobField::new(&visible, threshold);
        let (pick, _) = remaining
            .iter()
            .enumerate()
            .map(|(r, &i)| (r, signed_distance(&field, &visible, blobs[i].center, diag)))
            .fold(
                (0, f64::INFINITY),
                |best, cur| {
                    if cur.1 < best.1 { cur } else { best }
                },
            );
        let i = remaining.remove(pick);
        order.push(i);
        visible.push(blobs[i]);
    }
    order.extend_from_slice(&rest[n_ii..]);
    order
}

/// Signed distance estimate from `x` to the surface of `field` (negative inside), see the
/// module doc.
fn signed_distance(field: &BlobField, visible: &[Blob], x: DVec3, diag: f64) -> f64 {
    let (f, g) = field.value_and_gradient(x);
    if f + field.threshold() <= 0.0 {
        let nearest = visible
            .iter()
            .map(|b| b.center.distance(x))
            .fold(f64::INFINITY, f64::min);
        return diag + nearest;
    }
    let slope = g.length();
    if slope <= 0.0 {
        return if f > 0.0 { -diag } else { diag };
    }
    (-f / slope).clamp(-diag, diag)
}
