//! The aggregation scheme (paper §5.2.1): pieces of cloud fly in and gather into the target.
//!
//! Built backwards from the target:
//! 1. **Clusters.** The bounding box of the target's blobs is split by planes (the paper's six by
//!    default: `y = ±h/6`, `x = 0`, `z = 0`, `z = x`, `z = −x` through the box centre, 24
//!    regions); blobs are grouped by the region of their centre (empty regions are skipped).
//! 2. **Directions and speeds.** A cluster flies in along `−d`, where `d` points from the box
//!    centre through the cluster's centroid (its vertical part dropped when the centroid lies in
//!    the middle third of the height, so the middle band moves horizontally), normalised, plus a
//!    seeded random perturbation of size `direction_jitter`. Its speed is a seeded uniform draw
//!    in `speed = (min, max)`, in **bounding-box diagonals per keyframe interval**; it is raised
//!    where needed so that the cluster starts clear of its final bounding box.
//! 3. **Keyframes.** Keyframe `K − 1` is the target. Keyframe `j < K − 1` displaces each cluster
//!    by `d · speed · (K − 1 − j)`, jitters each blob inside its cluster's box (by `jitter` times
//!    the box size, fading to zero toward the target), scales its semi-axes by up to
//!    `± size_jitter`, tilts it by up to `rotation_jitter_deg`, then runs `repulsion_steps` of
//!    pairwise repulsion so blobs do not overlap too much.
//!    With `early_shape: Ellipsoids` each blob flies with `B = (1+A)/A` (alone it fills its
//!    ellipsoid), blending to the fitted value over the last interval. Finally every cluster
//!    is made one piece: a shown blob that the cluster's field does not join to the cluster's
//!    largest shown blob is pulled toward its nearest joined neighbour just far enough
//!    ([`super::pieces`]).
//! 4. **Frames.** Centres follow a Catmull–Rom spline through the keyframes (with linearly
//!    extrapolated end points, so a cluster's own motion is exactly constant-speed, the paper's
//!    rule, while the per-blob jitter moves smoothly); semi-axes, A and B are interpolated
//!    linearly and rotations by slerp.

use std::collections::BTreeMap;

use glam::{DQuat, DVec3};
use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::diffusion::EarlyShape;
use super::pieces::keep_in_one_piece;
use super::repulsion::{NO_CLUSTER, repel};
use super::{AnimateError, Timeline, blend_shape, blob_bounds, invalid};
use crate::blobby::Blob;
use crate::geometry::Aabb;
use crate::rng::{Stream, item_rng};

/// A splitting plane `n̂ · (p − c) = offset · h_n` through the target's box, where `c` is the
/// box centre and `h_n` the box's extent along `n̂` (so `offset` is a fraction of that extent).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plane {
    /// Plane normal (need not be unit length, must not be zero).
    pub normal: DVec3,
    /// Signed offset from the box centre as a fraction of the box's extent along the normal.
    #[serde(default)]
    pub offset: f64,
}

/// How the target's bounding box is split into cluster regions.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Planes {
    /// The paper's six planes: `y = ±h/6`, `x = 0`, `z = 0`, `z = x`, `z = −x` (24 regions).
    #[default]
    PaperDefault,
    /// Planes given in the scene.
    Custom(Vec<Plane>),
}

impl Planes {
    /// The planes as a list.
    pub fn planes(&self) -> Vec<Plane> {
        match self {
            Planes::PaperDefault => {
                let p = |x, y, z, offset| Plane {
                    normal: DVec3::new(x, y, z),
                    offset,
                };
                vec![
                    p(0.0, 1.0, 0.0, 1.0 / 6.0),
                    p(0.0, 1.0, 0.0, -1.0 / 6.0),
                    p(1.0, 0.0, 0.0, 0.0),
                    p(0.0, 0.0, 1.0, 0.0),
                    p(-1.0, 0.0, 1.0, 0.0),
                    p(1.0, 0.0, 1.0, 0.0),
                ]
            }
            Planes::Custom(v) => v.clone(),
        }
    }
}

/// Time warp of the motion.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Easing {
    /// Constant cluster speed to the very end (the paper).
    #[default]
    Linear,
    /// Quadratic ease-out: the clouds slow down to rest on the target.
    EaseOut,
}

/// Settings of the aggregation scheme. Every field has a default.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AggregationConfig {
    /// Region planes.
    pub planes: Planes,
    /// Number of keyframes including the target (≥ 2).
    pub keyframes: usize,
    /// `(min, max)` cluster speed in bounding-box diagonals per keyframe interval.
    pub speed: (f64, f64),
    /// Random perturbation of each cluster's direction (0 = exactly outward; 1 ≈ 45°).
    pub direction_jitter: f64,
    /// Random displacement of each blob inside its cluster's box, as a fraction of the box size
    /// (at the first keyframe; it fades linearly to zero at the target).
    pub jitter: f64,
    /// Random relative change of each blob's size (semi-axes scaled by `1 ± size_jitter`).
    pub size_jitter: f64,
    /// Random tilt of each blob, in degrees at the first keyframe.
    pub rotation_jitter_deg: f64,
    /// Jacobi steps of pairwise blob repulsion per keyframe.
    pub repulsion_steps: usize,
    /// Blobs repel while their centres are closer than `repulsion` times the sum of their
    /// equivalent radii (0 disables repulsion).
    pub repulsion: f64,
    /// Time warp of the motion.
    pub easing: Easing,
    /// Seconds the finished target holds still at the end of the shot.
    pub hold_seconds: f64,
    /// How the blobs look in flight: `Fitted` (the default) or `Ellipsoids` (each at its
    /// ellipsoid's extent, blending to the fitted parameters over the last keyframe interval;
    /// much fuller pieces, as all blobs at that strength overlap heavily).
    pub early_shape: EarlyShape,
}

impl Default for AggregationConfig {
    fn default() -> Self {
        AggregationConfig {
            planes: Planes::PaperDefault,
            keyframes: 8,
            speed: (0.08, 0.16),
            direction_jitter: 0.3,
            jitter: 0.1,
            size_jitter: 0.15,
            rotation_jitter_deg: 20.0,
            repulsion_steps: 8,
            repulsion: 0.7,
            easing: Easing::Linear,
            hold_seconds: 0.5,
            early_shape: EarlyShape::Fitted,
        }
    }
}

impl AggregationConfig {
    /// Check ranges; errors name the field as `animation.NAME`.
    pub fn validate(&self) -> Result<(), AnimateError> {
        let finite_nonneg = |name: &str, v: f64| {
            if v.is_finite() && v >= 0.0 {
                Ok(())
            } else {
                Err(invalid(
                    &format!("animation.{name}"),
                    format!("must be a finite number ≥ 0, got {v}"),
                ))
            }
        };
        if self.keyframes < 2 {
            return Err(invalid(
                "animation.keyframes",
                format!("need at least 2 keyframes, got {}", self.keyframes),
            ));
        }
        let (lo, hi) = self.speed;
        finite_nonneg("speed", lo)?;
        finite_nonneg("speed", hi)?;
        if lo > hi {
            return Err(invalid(
                "animation.speed",
                format!("min {lo} is larger than max {hi}"),
            ));
        }
        finite_nonneg("direction_jitter", self.direction_jitter)?;
        finite_nonneg("jitter", self.jitter)?;
        finite_nonneg("rotation_jitter_deg", self.rotation_jitter_deg)?;
        finite_nonneg("repulsion", self.repulsion)?;
        finite_nonneg("hold_seconds", self.hold_seconds)?;
        if !(self.size_jitter.is_finite() && (0.0..1.0).contains(&self.size_jitter)) {
            return Err(invalid(
                "animation.size_jitter",
                format!("must be in [0, 1), got {}", self.size_jitter),
            ));
        }
        if let Planes::Custom(planes) = &self.planes {
            for (i, p) in planes.iter().enumerate() {
                if !(p.normal.is_finite() && p.normal.length() > 0.0 && p.offset.is_finite()) {
                    return Err(invalid(
                        &format!("animation.planes[{i}]"),
                        "normal must be finite and non-zero, offset finite",
                    ));
                }
            }
        }
        Ok(())
    }
}

/// One piece of cloud: a cluster of blobs and how it flies in.
#[derive(Clone, Debug, PartialEq)]
pub struct Cluster {
    /// Blob indices, increasing.
    pub members: Vec<usize>,
    /// Unit direction pointing away from the target (the cluster flies in along `−direction`).
    pub direction: DVec3,
    /// Displacement from the target per keyframe interval (model units).
    pub step: f64,
    /// Box the blob centres stay inside at the target (the jitter box).
    pub center_box: Aabb,
}

/// A planned aggregation: clusters and keyframes; frames are interpolated on demand.
#[derive(Clone, Debug)]
pub struct AggregationPlan {
    target: Vec<Blob>,
    clusters: Vec<Cluster>,
    /// `keys[j][i]`: blob `i` at keyframe `j`; the last keyframe is the target.
    keys: Vec<Vec<Blob>>,
    easing: Easing,
    timeline: Timeline,
}

impl AggregationPlan {
    /// Plan the scheme for `target` with iso-level `threshold` (config already validated).
    pub fn new(
        cfg: &AggregationConfig,
        target: &[Blob],
        threshold: f64,
        timeline: Timeline,
        seed: u64,
    ) -> AggregationPlan {
        let bounds = blob_bounds(target);
        let bounds = if bounds.is_empty() {
            Aabb::from_points(target.iter().map(|b| &b.center))
        } else {
            bounds
        };
        let mut clusters = cluster_blobs(&cfg.planes.planes(), &bounds, target);
        let k = cfg.keyframes;
        for (ci, c) in clusters.iter_mut().enumerate() {
            orient_cluster(cfg, &bounds, target, c, seed, ci as u64);
        }
        let owner = owners(&clusters, target.len());
        let mut keys = vec![target.to_vec(); k];
        for (j, key) in keys.iter_mut().enumerate().take(k - 1) {
            let fade = (k - 1 - j) as f64 / (k - 1) as f64;
            for (i, blob) in key.iter_mut().enumerate() {
                if owner[i] == NO_CLUSTER {
                    continue;
                }
                let c = &clusters[owner[i]];
                let offset = c.direction * c.step * (k - 1 - j) as f64;
                *blob = jittered(
                    cfg,
                    blob,
                    c,
                    offset,
                    fade,
                    seed,
                    (j * target.len() + i) as u64,
                );
            }
            if cfg.repulsion > 0.0 && cfg.repulsion_steps > 0 {
                let boxes: Vec<Aabb> = clusters
                    .iter()
                    .map(|c| {
                        let offset = c.direction * c.step * (k - 1 - j) as f64;
                        Aabb {
                            min: c.center_box.min + offset,
                            max: c.center_box.max + offset,
                        }
                    })
                    .collect();
                repel(key, &owner, &boxes, cfg.repulsion, cfg.repulsion_steps);
            }
            if cfg.early_shape == EarlyShape::Ellipsoids {
                for (i, blob) in key.iter_mut().enumerate() {
                    if owner[i] != NO_CLUSTER && blob.is_live() {
                        blob.b = (1.0 + blob.a) / blob.a;
                    }
                }
            }
            // Whatever jitter and repulsion did, every cluster flies as one piece.
            for c in &clusters {
                keep_in_one_piece(key, &c.members, threshold);
            }
        }
        AggregationPlan {
            target: target.to_vec(),
            clusters,
            keys,
            easing: cfg.easing,
            timeline,
        }
    }

    /// The clusters, in region order.
    pub fn clusters(&self) -> &[Cluster] {
        &self.clusters
    }

    /// The keyframes (`keyframes()[j][i]` is blob `i` at keyframe `j`; the last is the target).
    pub fn keyframes(&self) -> &[Vec<Blob>] {
        &self.keys
    }

    /// The shot's timeline.
    pub fn timeline(&self) -> Timeline {
        self.timeline
    }

    /// The motion's progress (after easing) at frame `k`, in `[0, 1]`.
    pub fn progress(&self, k: usize) -> f64 {
        self.progress_at(self.timeline.time(k))
    }

    /// The motion's progress (after easing) at `t` seconds, in `[0, 1]`.
    pub fn progress_at(&self, t: f64) -> f64 {
        let s = self.timeline.progress_at(t);
        match self.easing {
            Easing::Linear => s,
            Easing::EaseOut => 1.0 - (1.0 - s) * (1.0 - s),
        }
    }

    /// The blobs of frame `k`; the target itself once the motion is over.
    pub fn frame(&self, k: usize) -> Vec<Blob> {
        self.at(self.timeline.time(k))
    }

    /// The blobs at `t` seconds (any time; see [`super::Plan::at`]).
    pub fn at(&self, t: f64) -> Vec<Blob> {
        let s = self.progress_at(t);
        if s >= 1.0 {
            return self.target.clone();
        }
        let last = self.keys.len() - 1;
        let u = s * last as f64;
        let j = (u.floor() as usize).min(last - 1);
        let t = u - j as f64;
        (0..self.target.len())
            .map(|i| {
                let p = |m: isize| -> DVec3 {
                    // Linear extrapolation past both ends keeps end segments constant-speed.
                    if m < 0 {
                        2.0 * self.keys[0][i].center - self.keys[1][i].center
                    } else if m as usize > last {
                        2.0 * self.keys[last][i].center - self.keys[last - 1][i].center
                    } else {
                        self.keys[m as usize][i].center
                    }
                };
                let ji = j as isize;
                let c = catmull_rom(p(ji - 1), p(ji), p(ji + 1), p(ji + 2), t);
                blend_shape(&self.keys[j][i], &self.keys[j + 1][i], t, c)
            })
            .collect()
    }
}

/// Uniform Catmull–Rom segment from `p1` (t = 0) to `p2` (t = 1).
pub(crate) fn catmull_rom(p0: DVec3, p1: DVec3, p2: DVec3, p3: DVec3, t: f64) -> DVec3 {
    let t2 = t * t;
    let t3 = t2 * t;
    0.5 * ((2.0 * p1)
        + (p2 - p0) * t
        + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2
        + (3.0 * p1 - p0 - 3.0 * p2 + p3) * t3)
}

/// Group live blobs by the region (side of every plane) their centre lies in; regions in a
/// fixed order. Dead blobs (`B = 0`) belong to no cluster and stay where they are.
fn cluster_blobs(planes: &[Plane], bounds: &Aabb, blobs: &[Blob]) -> Vec<Cluster> {
    let centre = bounds.center();
    let size = bounds.size();
    let mut regions: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
    for (i, b) in blobs.iter().enumerate().filter(|(_, b)| b.is_live()) {
        let mut key = 0u64;
        for (p, plane) in planes.iter().enumerate().take(64) {
            let n = plane.normal.normalize();
            let extent = n.abs().dot(size);
            if n.dot(b.center - centre) >= plane.offset * extent {
                key |= 1 << p;
            }
        }
        regions.entry(key).or_default().push(i);
    }
    regions
        .into_values()
        .map(|members| Cluster {
            members,
            direction: DVec3::Y,
            step: 0.0,
            center_box: Aabb::EMPTY,
        })
        .collect()
}

/// The cluster that owns each blob ([`NO_CLUSTER`] for dead blobs).
fn owners(clusters: &[Cluster], n: usize) -> Vec<usize> {
    let mut owner = vec![NO_CLUSTER; n];
    for (ci, c) in clusters.iter().enumerate() {
        for &i in &c.members {
            owner[i] = ci;
        }
    }
    owner
}

/// Set a cluster's direction, step and jitter box (see the module doc for the rules).
fn orient_cluster(
    cfg: &AggregationConfig,
    bounds: &Aabb,
    blobs: &[Blob],
    c: &mut Cluster,
    seed: u64,
    item: u64,
) {
    let mut rng = item_rng(seed, Stream::Animate, u64::MAX - item);
    let centre = bounds.center();
    let size = bounds.size();
    let diag = bounds.diagonal().max(f64::MIN_POSITIVE);
    let n = c.members.len() as f64;
    let centroid = c.members.iter().map(|&i| blobs[i].center).sum::<DVec3>() / n;
    let mut out = centroid - centre;
    if out.y.abs() < size.y / 6.0 {
        out.y = 0.0;
    }
    // Degenerate: a centroid on the centre (or on the axis, in the middle band).
    let base = out.try_normalize().unwrap_or_else(|| {
        let a = rng.random::<f64>() * std::f64::consts::TAU;
        DVec3::new(a.cos(), 0.0, a.sin())
    });
    let noise = DVec3::new(
        rng.random::<f64>() * 2.0 - 1.0,
        rng.random::<f64>() * 2.0 - 1.0,
        rng.random::<f64>() * 2.0 - 1.0,
    ) * cfg.direction_jitter;
    c.direction = (base + noise).try_normalize().unwrap_or(base);
    // Jitter box: the centres' box, at least half a mean blob radius on each side.
    let mean_r = c
        .members
        .iter()
        .map(|&i| blobs[i].equivalent_radius())
        .sum::<f64>()
        / n;
    let centers = Aabb::from_points(c.members.iter().map(|&i| &blobs[i].center));
    c.center_box = centers.expanded(0.5 * mean_r);
    // Everything the cluster can cover at any keyframe: jitter box plus the largest support
    // half-extent grown by the size jitter. Clear of its final place once shifted by more than
    // this box along some axis.
    let half = c
        .members
        .iter()
        .map(|&i| blobs[i].support_bounds().size() * 0.5)
        .fold(DVec3::ZERO, DVec3::max)
        * (1.0 + cfg.size_jitter);
    let reach = c.center_box.size() + 2.0 * half;
    let d = c.direction.abs();
    let needed = (0..3)
        .filter(|&a| d[a] > 1e-6)
        .map(|a| reach[a] / d[a])
        .fold(f64::INFINITY, f64::min)
        * 1.1;
    let intervals = (cfg.keyframes - 1) as f64;
    let speed = cfg.speed.0 + (cfg.speed.1 - cfg.speed.0) * rng.random::<f64>();
    c.step = (speed * diag).max(needed / intervals);
}

/// A keyframe blob: the target blob jittered inside its cluster's box, resized and tilted, then
/// shifted by the cluster's offset. `fade ∈ (0, 1]` scales the jitter (1 at the first keyframe).
fn jittered(
    cfg: &AggregationConfig,
    target: &Blob,
    c: &Cluster,
    offset: DVec3,
    fade: f64,
    seed: u64,
    item: u64,
) -> Blob {
    let mut rng = item_rng(seed, Stream::Animate, item);
    let mut u = || rng.random::<f64>() * 2.0 - 1.0;
    let shake = DVec3::new(u(), u(), u()) * c.center_box.size() * (cfg.jitter * fade);
    let center = (target.center + shake).clamp(c.center_box.min, c.center_box.max) + offset;
    let scale = 1.0 + cfg.size_jitter * fade * u();
    let axis = DVec3::new(u(), u(), u())
        .try_normalize()
        .unwrap_or(DVec3::Y);
    let angle = cfg.rotation_jitter_deg.to_radians() * fade * u();
    Blob {
        center,
        rotation: (DQuat::from_axis_angle(axis, angle) * target.rotation).normalize(),
        semi_axes: target.semi_axes * scale,
        a: target.a,
        b: target.b,
    }
}
