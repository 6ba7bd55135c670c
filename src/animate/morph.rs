//! The metamorphosis scheme (the paper's motivation: a piece of cloud turning into a shape):
//! one blob model turns into another.
//!
//! - **Alignment.** The source is first moved and uniformly scaled so that its blob bounds have
//!   the target's centre and diagonal (a natural cloud becomes the shape where the shape is).
//! - **Pairing.** Source and target blobs (live ones) are paired by the assignment that
//!   minimises the total travel (sum of centre distances), solved exactly (Hungarian method,
//!   O(n³); models have a few hundred blobs). When the counts differ, each surplus target
//!   blob *splits* from the source partner of its nearest paired target blob (it starts there
//!   at zero size and grows), and each surplus source blob *merges* into the target partner of
//!   its nearest paired source blob (it travels there and shrinks to nothing).
//! - **Motion.** Every blob moves along a smoothstep-eased straight path while its semi-axes,
//!   `A`, `B` are interpolated linearly and its rotation by slerp. Starts are staggered: blobs
//!   whose target is nearer the target's centroid move first (inside out), over the first
//!   `stagger` fraction of the motion, so the core of the cloud forms first and the cloud stays
//!   one piece.
//! - **Blob list.** Index `i < n` (the target's length) is target blob `i`; surplus source
//!   blobs follow. The last frame is the target, followed by the merged blobs hidden (`B = 0`).
//!   [`MorphPlan::sources`] says which source blob each entry starts as (a story keeps a blob's
//!   identity from one target to the next by it, [`super::story`]).
//! - **In place.** [`MorphPlan::in_place`] skips the alignment: a story's next morph starts
//!   from the target on screen, where it is.
//! - **One piece.** Straight paths between two shapes need not keep the cloud in one piece (a
//!   duck into a torus knot breaks a loop off half way). [`MorphPlan::kept_in_one_piece`]
//!   samples the motion at [`ONE_PIECE_KEYS`] keyframes, pulls each blob the cloud's field
//!   does not join toward its nearest joined neighbour until it joins (the aggregation's rule,
//!   [`super::pieces`]), and adds those pulls, zero at both ends, along a Catmull–Rom spline
//!   through the keyframes (so velocities stay continuous). A story's morphs use it.
//! - **Paced by volume.** Two shapes of different bulk lose (or gain) most of the difference
//!   where the blobs stop overlapping, late in the motion. [`MorphPlan::paced_by_volume`]
//!   measures the visible volume at [`PACE_KEYS`] points of the motion at plan time and gives
//!   each interval time in proportion to `PACE_TIME_SHARE` of the time plus the rest by its share
//!   of the volume change, so no frame changes the volume by much more than the average (at
//!   most `1 / (1 − PACE_TIME_SHARE)` times it, between the sampled points).

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::aggregation::catmull_rom;
use super::pieces::keep_in_one_piece;
use super::stats::{Lattice, visible_volume};
use super::{
    AnimateError, Timeline, blend_shape, blob_bounds, check_fraction, check_seconds, smoothstep,
};
use crate::blobby::Blob;

/// Settings of the morph scheme. `from` names the source model in the caller's terms (the scene
/// file's target description; `()` where the caller has the model already): this stage never
/// reads it, [`super::plan_with_source`] takes the loaded source model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MorphConfig<S = ()> {
    /// The model the cloud starts as, as the caller names it.
    pub from: S,
    /// Fraction of the motion over which the blobs' starts are spread, in `[0, 0.9]`.
    #[serde(default = "default_stagger")]
    pub stagger: f64,
    /// Seconds the source holds still at the start of the shot.
    #[serde(default = "default_lead")]
    pub lead_seconds: f64,
    /// Seconds the finished target holds still at the end of the shot.
    #[serde(default = "default_hold")]
    pub hold_seconds: f64,
}

fn default_stagger() -> f64 {
    0.4
}
fn default_lead() -> f64 {
    0.5
}
fn default_hold() -> f64 {
    0.5
}

impl<S> MorphConfig<S> {
    /// Check ranges; errors name the field as `animation.NAME`.
    pub fn validate(&self) -> Result<(), AnimateError> {
        check_fraction("stagger", self.stagger, 0.9)?;
        check_seconds("lead_seconds", self.lead_seconds)?;
        check_seconds("hold_seconds", self.hold_seconds)?;
        Ok(())
    }
}

/// A planned morph.
#[derive(Clone, Debug)]
pub struct MorphPlan {
    /// Per entry of the blob list: where it starts and ends (shape and place).
    from: Vec<Blob>,
    to: Vec<Blob>,
    /// Per entry: the source blob (index into the source model) it starts as; `None` for a
    /// split blob (it starts at zero size) or a dead target blob.
    origin: Vec<Option<usize>>,
    /// Per entry: start of its motion as a fraction of the motion, and its duration.
    start: Vec<f64>,
    span: f64,
    lead: f64,
    target: Vec<Blob>,
    timeline: Timeline,
    /// Per keyframe `j` (at `j / ONE_PIECE_KEYS` of the motion), each entry's pull that keeps the
    /// cloud in one piece; empty without [`MorphPlan::kept_in_one_piece`].
    pulls: Vec<Vec<DVec3>>,
    /// The motion's fraction at `j / PACE_KEYS` of its time; empty: the time itself.
    pace: Vec<f64>,
}

/// Points of the motion at which [`MorphPlan::paced_by_volume`] measures the volume.
pub const PACE_KEYS: usize = 24;

/// Share of a paced morph's time spread evenly; the rest goes by the volume's change.
pub const PACE_TIME_SHARE: f64 = 0.3;

/// Keyframes over a morph's motion at which [`MorphPlan::kept_in_one_piece`] joins the cloud
/// (about every other frame of a 3-second morph at 24 fps).
pub const ONE_PIECE_KEYS: usize = 36;

impl MorphPlan {
    /// Plan the morph of `source` into `target` (config already validated); the source is
    /// first moved and scaled onto the target's box.
    pub fn new<S>(
        cfg: &MorphConfig<S>,
        source: &[Blob],
        target: &[Blob],
        timeline: Timeline,
    ) -> MorphPlan {
        MorphPlan::in_place(cfg, &align(source, target), target, timeline)
    }

    /// Plan the morph of `source` into `target` where both are (no alignment: a story's next
    /// morph starts from the target on screen). Config already validated.
    pub fn in_place<S>(
        cfg: &MorphConfig<S>,
        source: &[Blob],
        target: &[Blob],
        timeline: Timeline,
    ) -> MorphPlan {
        let s_live: Vec<usize> = (0..source.len()).filter(|&i| source[i].is_live()).collect();
        let t_live: Vec<usize> = (0..target.len()).filter(|&i| target[i].is_live()).collect();
        let cost = |a: usize, b: usize| source[s_live[a]].center.distance(target[t_live[b]].center);
        // Rows = the smaller side.
        let swap = s_live.len() > t_live.len();
        let (rows, cols) = if swap {
            (t_live.len(), s_live.len())
        } else {
            (s_live.len(), t_live.len())
        };
        let assignment = hungarian(
            rows,
            cols,
            |r, c| if swap { cost(c, r) } else { cost(r, c) },
        );
        // partner_of_target[t] = source index (both in model indices).
        let mut partner_of_target = vec![None; target.len()];
        let mut partner_of_source = vec![None; source.len()];
        for (r, &c) in assignment.iter().enumerate() {
            let (si, ti) = if swap {
                (s_live[c], t_live[r])
            } else {
                (s_live[r], t_live[c])
            };
            partner_of_target[ti] = Some(si);
            partner_of_source[si] = Some(ti);
        }
        let paired_targets: Vec<usize> = t_live
            .iter()
            .copied()
            .filter(|&t| partner_of_target[t].is_some())
            .collect();
        let paired_sources: Vec<usize> = s_live
            .iter()
            .copied()
            .filter(|&s| partner_of_source[s].is_some())
            .collect();
        let nearest = |set: &[usize], blobs: &[Blob], x: DVec3| -> Option<usize> {
            set.iter().copied().min_by(|&a, &b| {
                blobs[a]
                    .center
                    .distance_squared(x)
                    .total_cmp(&blobs[b].center.distance_squared(x))
            })
        };
        let mut from = Vec::with_capacity(target.len());
        let mut to = Vec::with_capacity(target.len());
        let mut origin = Vec::with_capacity(target.len());
        for (ti, t) in target.iter().enumerate() {
            origin.push(partner_of_target[ti].filter(|_| t.is_live()));
            let start = if !t.is_live() {
                *t
            } else if let Some(si) = partner_of_target[ti] {
                source[si]
            } else {
                // Split from the source partner of the nearest paired target blob.
                let host = nearest(&paired_targets, target, t.center)
                    .and_then(|h| partner_of_target[h])
                    .map_or(t.center, |s| source[s].center);
                Blob {
                    center: host,
                    semi_axes: DVec3::ZERO,
                    ..*t
                }
            };
            from.push(start);
            to.push(*t);
        }
        for &si in &s_live {
            if partner_of_source[si].is_some() {
                continue;
            }
            // Merge into the target partner of the nearest paired source blob.
            let s = source[si];
            let host = nearest(&paired_sources, source, s.center)
                .and_then(|h| partner_of_source[h])
                .map_or(s.center, |t| target[t].center);
            from.push(s);
            origin.push(Some(si));
            to.push(Blob {
                center: host,
                semi_axes: DVec3::ZERO,
                b: 0.0,
                ..s
            });
        }
        // Inside out: rank by the distance of the end point from the target's centroid.
        let centroid =
            t_live.iter().map(|&i| target[i].center).sum::<DVec3>() / t_live.len().max(1) as f64;
        let mut rank: Vec<usize> = (0..to.len()).collect();
        rank.sort_by(|&a, &b| {
            to[a]
                .center
                .distance_squared(centroid)
                .total_cmp(&to[b].center.distance_squared(centroid))
                .then(a.cmp(&b))
        });
        let mut start = vec![0.0; to.len()];
        let n = rank.len().max(2) - 1;
        for (r, &i) in rank.iter().enumerate() {
            start[i] = cfg.stagger * r as f64 / n as f64;
        }
        MorphPlan {
            from,
            to,
            origin,
            start,
            span: 1.0 - cfg.stagger,
            lead: cfg.lead_seconds,
            target: target.to_vec(),
            timeline,
            pulls: Vec::new(),
            pace: Vec::new(),
        }
    }

    /// This morph paced so that its visible volume (at iso-level `threshold`, on `lattice`)
    /// changes about evenly over its time (see the module doc). Deterministic.
    pub fn paced_by_volume(mut self, threshold: f64, lattice: Lattice) -> MorphPlan {
        let keys = PACE_KEYS;
        let volume: Vec<f64> = (0..=keys)
            .map(|j| {
                visible_volume(&self.shape(j as f64 / keys as f64), threshold, lattice).voxels
                    as f64
            })
            .collect();
        let change: Vec<f64> = volume.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        let total: f64 = change.iter().sum();
        // Each interval's share of the time, then the time at each key.
        let mut at = vec![0.0];
        for c in &change {
            let share = if total > 0.0 {
                PACE_TIME_SHARE / keys as f64 + (1.0 - PACE_TIME_SHARE) * c / total
            } else {
                1.0 / keys as f64
            };
            at.push(at[at.len() - 1] + share);
        }
        // Invert: the motion's fraction at even steps of the time.
        let end = at[keys];
        self.pace = (0..=keys)
            .map(|j| {
                let tau = j as f64 / keys as f64 * end;
                let k = at.windows(2).position(|w| tau <= w[1]).unwrap_or(keys - 1);
                let f =
                    ((tau - at[k]) / (at[k + 1] - at[k]).max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
                (k as f64 + f) / keys as f64
            })
            .collect();
        self.pace[0] = 0.0;
        self.pace[keys] = 1.0;
        self
    }

    /// This morph with the pulls that keep its cloud in one piece at iso-level `threshold` (see
    /// the module doc). Deterministic.
    pub fn kept_in_one_piece(mut self, threshold: f64) -> MorphPlan {
        let keys = ONE_PIECE_KEYS;
        let mut pulls = vec![vec![DVec3::ZERO; self.to.len()]; keys + 1];
        for (j, pull) in pulls.iter_mut().enumerate().take(keys).skip(1) {
            let mut blobs = self.pose(j as f64 / keys as f64);
            let before: Vec<DVec3> = blobs.iter().map(|b| b.center).collect();
            let live: Vec<usize> = (0..blobs.len()).filter(|&i| blobs[i].is_live()).collect();
            keep_in_one_piece(&mut blobs, &live, threshold);
            for (p, (b, c)) in pull.iter_mut().zip(blobs.iter().zip(&before)) {
                *p = b.center - *c;
            }
        }
        self.pulls = pulls;
        self
    }

    /// The shot's timeline.
    pub fn timeline(&self) -> Timeline {
        self.timeline
    }

    /// Per entry of the blob list, the source blob (index into the source model's blobs) it
    /// starts as: a paired or merged blob; `None` for a split blob or a dead target blob.
    pub fn sources(&self) -> &[Option<usize>] {
        &self.origin
    }

    /// Each entry's part in the morph (see [`super::mattes`]): `paired`, `split` (a target
    /// blob that starts at zero size), `merged` (a surplus source blob), `None` for a target
    /// blob that is dead.
    pub fn roles(&self) -> Vec<Option<&'static str>> {
        (0..self.to.len())
            .map(|i| match self.target.get(i) {
                None => Some("merged"),
                Some(t) if !t.is_live() => None,
                Some(_) if self.from[i].semi_axes == DVec3::ZERO => Some("split"),
                Some(_) => Some("paired"),
            })
            .collect()
    }

    /// The blobs of frame `k` (target first, then merged source blobs).
    pub fn frame(&self, k: usize) -> Vec<Blob> {
        self.at(self.timeline.time(k))
    }

    /// The blobs at `t` seconds (any time; see [`super::Plan::at`]).
    pub fn at(&self, t: f64) -> Vec<Blob> {
        let done = self.timeline.progress_at(t) >= 1.0;
        if done {
            let mut out = self.target.clone();
            out.extend(
                self.to[self.target.len()..]
                    .iter()
                    .map(|b| Blob { b: 0.0, ..*b }),
            );
            return out;
        }
        let motion = (self.timeline.motion_seconds() - self.lead).max(1e-9);
        let u = ((t - self.lead) / motion).clamp(0.0, 1.0);
        let u = if self.pace.is_empty() {
            u
        } else {
            let keys = self.pace.len() - 1;
            let x = u * keys as f64;
            let j = (x.floor() as usize).min(keys - 1);
            super::lerp(self.pace[j], self.pace[j + 1], x - j as f64)
        };
        self.shape(u)
    }

    /// The blobs at `u` of the motion (after the lead and the pace): on their straight paths,
    /// pulled into one piece when the plan keeps it so.
    fn shape(&self, u: f64) -> Vec<Blob> {
        let mut blobs = self.pose(u);
        if !self.pulls.is_empty() {
            let keys = self.pulls.len() - 1;
            let x = u * keys as f64;
            let j = (x.floor() as usize).min(keys - 1);
            let key = |k: isize| &self.pulls[k.clamp(0, keys as isize) as usize];
            let j = j as isize;
            let (p0, p1, p2, p3) = (key(j - 1), key(j), key(j + 1), key(j + 2));
            for (i, b) in blobs.iter_mut().enumerate() {
                b.center += catmull_rom(p0[i], p1[i], p2[i], p3[i], x - j as f64);
            }
        }
        blobs
    }

    /// The blobs at `u` of the motion (after the lead), on their straight paths.
    fn pose(&self, u: f64) -> Vec<Blob> {
        (0..self.to.len())
            .map(|i| {
                let e = smoothstep((u - self.start[i]) / self.span);
                let (a, b) = (&self.from[i], &self.to[i]);
                let mut blob = blend_shape(a, b, e, a.center.lerp(b.center, e));
                if !blob.is_live() || blob.semi_axes.min_element() <= 0.0 {
                    blob.b = 0.0;
                }
                blob
            })
            .collect()
    }
}

/// `source` moved and uniformly scaled so that its blob bounds have `target`'s centre and
/// diagonal.
fn align(source: &[Blob], target: &[Blob]) -> Vec<Blob> {
    let (sb, tb) = (blob_bounds(source), blob_bounds(target));
    if sb.is_empty() || tb.is_empty() {
        return source.to_vec();
    }
    let scale = tb.diagonal() / sb.diagonal().max(f64::MIN_POSITIVE);
    let (sc, tc) = (sb.center(), tb.center());
    source
        .iter()
        .map(|b| Blob {
            center: tc + (b.center - sc) * scale,
            semi_axes: b.semi_axes * scale,
            ..*b
        })
        .collect()
}

/// Minimum-cost assignment of each of `rows` rows to a distinct one of `cols ≥ rows` columns
/// (Hungarian method with potentials, O(rows² · cols)); returns the column of each row.
pub fn hungarian(rows: usize, cols: usize, cost: impl Fn(usize, usize) -> f64) -> Vec<usize> {
    assert!(rows <= cols, "more rows than columns");
    // 1-based arrays, column 0 is the virtual start.
    let (mut u, mut v) = (vec![0.0; rows + 1], vec![0.0; cols + 1]);
    let mut owner = vec![0usize; cols + 1];
    let mut way = vec![0usize; cols + 1];
    for r in 1..=rows {
        owner[0] = r;
        let mut j0 = 0;
        let mut minv = vec![f64::INFINITY; cols + 1];
        let mut used = vec![false; cols + 1];
        loop {
            used[j0] = true;
            let i0 = owner[j0];
            let (mut delta, mut j1) = (f64::INFINITY, 0);
            for j in 1..=cols {
                if used[j] {
                    continue;
                }
                let cur = cost(i0 - 1, j - 1) - u[i0] - v[j];
                if cur < minv[j] {
                    minv[j] = cur;
                    way[j] = j0;
                }
                if minv[j] < delta {
                    delta = minv[j];
                    j1 = j;
                }
            }
            for j in 0..=cols {
                if used[j] {
                    u[owner[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if owner[j0] == 0 {
                break;
            }
        }
        loop {
            let j1 = way[j0];
            owner[j0] = owner[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    let mut result = vec![0; rows];
    for j in 1..=cols {
        if owner[j] > 0 {
            result[owner[j] - 1] = j - 1;
        }
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hungarian_finds_the_optimum_of_small_problems() {
        // Brute force over all injective maps of 3 rows into 4 columns.
        let c = [
            [4.0, 1.0, 3.0, 9.0],
            [2.0, 0.0, 5.0, 1.0],
            [3.0, 2.0, 2.0, 7.0],
        ];
        let got = hungarian(3, 4, |r, k| c[r][k]);
        let total: f64 = got.iter().enumerate().map(|(r, &k)| c[r][k]).sum();
        let mut best = f64::INFINITY;
        for a in 0..4 {
            for b in 0..4 {
                for d in 0..4 {
                    if a != b && b != d && a != d {
                        best = best.min(c[0][a] + c[1][b] + c[2][d]);
                    }
                }
            }
        }
        assert_eq!(total, best);
        let mut cols = got.clone();
        cols.sort();
        cols.dedup();
        assert_eq!(cols.len(), 3);
    }
}
