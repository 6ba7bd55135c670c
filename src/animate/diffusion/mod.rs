//! The diffusion scheme (paper §5.2.2): the target spreads out from one piece of cloud.
//!
//! - **Categories** (in the model's selection order, live blobs only): I = the first blob (the
//!   largest), II = the next `category_ii` fraction of the live blobs (rounded, at least one
//!   when there are ≥ 2), III = the rest ("the details of the model"). Dead blobs (`B = 0`)
//!   stay hidden throughout.
//! - **Early shape.** A fitted blob's `A`, `B` were fitted to act in the sum of all blobs; many
//!   are below the iso-level alone, so categories I and II at their fitted parameters show a
//!   few separate eggs, not the rough shape. With `early_shape: Ellipsoids` (the default) each
//!   blob of I and II is shown at the extent of its ellipsoid (`B = (1+A)/A`: an isolated
//!   blob's surface is then exactly its ellipsoid; the model file keeps the decomposition's
//!   ellipsoid as the blob's `ρ = 1` ellipsoid, which the full optimiser only nudges), so the
//!   partial cloud is the union of those ellipsoids, blended. While category III grows in,
//!   every I/II blob blends to its fitted parameters (`B²` linearly, so the field is a convex
//!   combination of the early field and the fitted one). `early_shape: Fitted` keeps the
//!   fitted parameters throughout (the paper's literal reading).
//! - **Order.** Blob I is shown first. Then, repeatedly, the next blob of category II is the
//!   remaining one whose centre has the smallest signed distance to the surface of the blobs
//!   shown so far (as displayed, negative inside) among those that join the shown cloud (the
//!   segment from its centre to its nearest shown blob's centre lies inside the cloud with it
//!   added; early shape `Ellipsoids` only). The distance is estimated as `−F/|∇F|` of the
//!   visible blobs' field, clamped to `±D` (`D` = target diagonal); a centre outside every
//!   visible support gets `D + (distance to the nearest visible centre)`, so nearer blobs come
//!   first. Ties go to the lower index. II blobs that never join are deferred to III. Category
//!   III is ordered greedily by the distance of its centre to the nearest blob placed before.
//! - **Schedule.** Blob I is on screen from the first frame at `SEED_SIZE` of its size and
//!   grows, its volume rising evenly. Category II grows during the first part of the motion,
//!   paced by volume: blob `k` finishes growing when the first part is as far through as the
//!   early shape's volume (measured at plan time on a 2 % lattice), and starts at the previous
//!   blob's finish or `grow_seconds` before its own, whichever is earlier. The final part
//!   brings category III; its length is the motion's share of the volume III adds (the early
//!   shape's share counted within [0.2, 0.8]), at least `final_grow_seconds`; with
//!   `Progressive`, at least half the motion. `Together` grows all of III at once over the
//!   final part as the blend progresses, as the paper says ("finally added together").
//!   The blend has two progresses, III's growth and I/II's `B` going from early to fitted
//!   (geometrically); the plan samples the visible volume over both on a 17 × 17 grid and
//!   follows the path along which it never decreases (`blend.rs`), paced so that it rises
//!   evenly: III grows into the space the early ellipsoids held before they withdraw from
//!   it. A steered plan (`start`, `order`) also checks the path at the shot's frames on the 1 %
//!   lattice and holds I/II's progress back at a frame that would lose volume between the grid's
//!   nodes (`blend.rs`, `held_at_frames`). `Progressive` starts III's blobs at evenly spaced
//!   times over it, each growing over `grow_seconds`.
//! - **Growth.** A new blob starts at the centre of its parent — the nearest blob placed
//!   before it (nearest in that blob's ellipsoidal radius, so a long blob's far end counts as
//!   near) — at zero size, and moves out while its semi-axes grow to full size (smoothstep);
//!   its offset from its parent's *current* centre grows with its size, so a chain of III
//!   blobs (a leg) grows out as a scaled copy of itself about its root. Steered (`start`,
//!   `order`), a category-II blob emerges part way out instead — half way from its parent's
//!   centre to where the way to its own centre leaves the cloud shown before it (`emerge.rs`) —
//!   so it does not cross the body mid-sized (from the duck's tail it split a thin tip of the
//!   body off on screen). A III blob's `B²`
//!   rises from zero with the blend, so it adds to the field gently. Before it starts, a blob
//!   is hidden (`B = 0`). The visible count never decreases, and with `Together` neither
//!   does the visible volume.
//!
//! Where the early cloud would hold more than 90 % of the final volume (it is fuller than the
//! target in places and would have to shrink into it), its blobs are weakened to
//! `B = γ·(1+A)/A`, `γ` stepping down by 0.05 to at least 0.5: a cloud that starts fuller
//! than its target cannot grow into it without shrinking somewhere.
//!
//! Measured on the shipped duck and horse shots (docs/MEASUREMENTS.md, "Animation statistics"):
//! one piece at every frame, at most a third of the final volume added per second, and no frame
//! with less visible volume than the frame before (1 % lattice).

use std::sync::OnceLock;

use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::pieces::nearest_blob;
use super::stats::{DEFAULT_CELL_FRACTION, Lattice, visible_volume};
use super::{AnimateError, Timeline, blob_bounds, check_fraction, check_seconds, lerp, smoothstep};
use crate::blobby::Blob;
use crate::hash::Fnv1a;

mod blend;
mod early;
mod emerge;
mod order;

use blend::{BlendPath, GRID_STEPS};
use early::{blend_b, early_shape, volume_paced_finish};
use emerge::{emergence, way_out};
use order::order_by_nearest;
pub use order::{Steering, category_ii_count, display_order};

/// Size of blob I on the first frame, relative to its full size ("one small piece").
const SEED_SIZE: f64 = 0.35;

/// Most of the final volume the early cloud (I and II as shown) may hold before its strength is
/// lowered.
const EARLY_SHARE_MAX: f64 = 0.9;

/// Weakest early strength `γ` tried (`B = γ·(1+A)/A`).
const MIN_EARLY_STRENGTH: f64 = 0.5;

/// Share of the final span in which category III grows to full size (`Together`); its `B²`
/// keeps rising with the blend over the whole span.
const DETAIL_GROWTH_SHARE: f64 = 0.7;

/// How categories I and II look before category III arrives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum EarlyShape {
    /// Each blob at the extent of its ellipsoid (`B = (1+A)/A`), blending to the fitted
    /// parameters while category III grows in.
    #[default]
    Ellipsoids,
    /// The fitted parameters throughout.
    Fitted,
}

/// How category III arrives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum DetailArrival {
    /// All of category III grows at once at the end (the paper).
    #[default]
    Together,
    /// One after another, nearest to the visible cloud first.
    Progressive,
}

/// Settings of the diffusion scheme. Every field has a default.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DiffusionConfig {
    /// Seconds each category-II blob takes to move out and grow to full size.
    pub grow_seconds: f64,
    /// Seconds category III takes to grow in at the end.
    pub final_grow_seconds: f64,
    /// Fraction of all blobs in category II (after the first blob), in `[0, 1]`.
    pub category_ii: f64,
    /// Seconds the finished target holds still at the end of the shot.
    pub hold_seconds: f64,
    /// How categories I and II look before category III arrives.
    pub early_shape: EarlyShape,
    /// How category III arrives.
    pub category_iii: DetailArrival,
    /// Where the diffusion starts (world units, the target placed at the first frame): blob I
    /// is the live blob nearest this point. Default: none, the largest blob.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub start: Option<DVec3>,
    /// Blob indices (the model's) shown first, in this order: the first is blob I unless
    /// `start` picks it, the others open category II. Default: none, the paper's order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub order: Vec<usize>,
}

impl Default for DiffusionConfig {
    fn default() -> Self {
        DiffusionConfig {
            grow_seconds: 0.6,
            final_grow_seconds: 1.0,
            category_ii: 0.10,
            hold_seconds: 0.5,
            early_shape: EarlyShape::Ellipsoids,
            category_iii: DetailArrival::Together,
            start: None,
            order: Vec::new(),
        }
    }
}

impl DiffusionConfig {
    /// Check ranges; errors name the field as `animation.NAME`.
    pub fn validate(&self) -> Result<(), AnimateError> {
        check_seconds("grow_seconds", self.grow_seconds)?;
        check_seconds("final_grow_seconds", self.final_grow_seconds)?;
        check_seconds("hold_seconds", self.hold_seconds)?;
        check_fraction("category_ii", self.category_ii, 1.0)?;
        if let Some(p) = self.start
            && !p.is_finite()
        {
            return Err(super::invalid(
                "animation.start",
                format!("must be a finite point, got {p}"),
            ));
        }
        if let Some((k, &i)) = self
            .order
            .iter()
            .enumerate()
            .find(|&(k, i)| self.order[..k].contains(i))
        {
            return Err(super::invalid(
                "animation.order",
                format!(
                    "blob {i} is listed twice (entries {} and {k}); list each blob once",
                    self.order.iter().position(|j| *j == i).unwrap_or(0)
                ),
            ));
        }
        Ok(())
    }

    /// Check the steering against the target's blobs (world units): `start` inside the
    /// target's box, `order` naming live blobs of the model.
    pub fn check_target(&self, target: &[Blob]) -> Result<(), AnimateError> {
        if let Some(p) = self.start {
            let b = blob_bounds(target);
            let inside = (p.cmpge(b.min) & p.cmple(b.max)).all();
            if !inside {
                return Err(super::invalid(
                    "animation.start",
                    format!(
                        "({}, {}, {}) is outside the target's box ({:.4}, {:.4}, {:.4}) to \
                         ({:.4}, {:.4}, {:.4}) (world units, the target placed by `transform` \
                         at the first frame); pick a point on or in the target",
                        p.x, p.y, p.z, b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
                    ),
                ));
            }
        }
        for (k, &i) in self.order.iter().enumerate() {
            match target.get(i) {
                None => {
                    return Err(super::invalid(
                        "animation.order",
                        format!(
                            "entry {k} names blob {i}, but the target has {} blobs (0 to {})",
                            target.len(),
                            target.len().saturating_sub(1)
                        ),
                    ));
                }
                Some(b) if !b.is_live() => {
                    return Err(super::invalid(
                        "animation.order",
                        format!(
                            "entry {k} names blob {i}, which the fit switched off (B = 0); it \
                             is never shown"
                        ),
                    ));
                }
                Some(_) => {}
            }
        }
        Ok(())
    }

    /// The artist's steering of the display order.
    pub fn steering(&self) -> Steering {
        Steering {
            start: self.start,
            order: self.order.clone(),
        }
    }
}

/// A planned diffusion: display order and per-blob schedule.
#[derive(Clone, Debug)]
pub struct DiffusionPlan {
    target: Vec<Blob>,
    /// `B` of each blob before category III arrives (the early shape).
    early_b: Vec<f64>,
    order: Vec<usize>,
    category_ii: usize,
    /// Per blob (by index): category III?
    detail: Vec<bool>,
    /// Per blob (by index): the blob it grows out of, when it starts and how long it grows
    /// (seconds).
    parent: Vec<Option<usize>>,
    start: Vec<f64>,
    grow: Vec<f64>,
    /// When category III starts arriving and the early shape blends to the fitted one.
    blend_start: f64,
    blend_seconds: f64,
    /// The blend's path through (III's progress, I/II's progress to the fitted `B`) in eased
    /// time, so the volume never decreases and rises evenly (empty: both the eased time). Made
    /// on first need (a frame inside the blend): a process rendering frames outside it does not
    /// pay for the grid.
    path: OnceLock<BlendPath>,
    /// [`DiffusionPlan::blend_key`], formed on first call (the cache reads and writes it).
    key: OnceLock<Option<u64>>,
    /// The iso-level, for the path's volumes.
    threshold: f64,
    /// Category III arrives together (its growth follows the blend progress).
    together: bool,
    /// The artist steers the order: the blend's path is checked frame by frame
    /// ([`BlendPath::held_at_frames`]).
    steered: bool,
    /// Volume of categories I and II as shown, over the final volume (2 % lattice; NaN when
    /// not measured).
    early_share: f64,
    /// Per blob (by index): where on the way from its parent's centre to its own it emerges,
    /// as a share of the way (0: at the parent's centre; steered II blobs, `emerge.rs`).
    emerge: Vec<f64>,
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
        let strength = match cfg.early_shape {
            EarlyShape::Ellipsoids => 1.0,
            EarlyShape::Fitted => 0.0,
        };
        let mut plan = DiffusionPlan::with_strength(cfg, target, threshold, timeline, strength);
        // Where the early cloud would be fuller than the target, it would have to shrink into
        // it: weaken it (γ down to 0.5) until it holds at most 90 % of the final volume.
        let mut gamma = strength;
        while strength > 0.0
            && plan.early_share > EARLY_SHARE_MAX
            && gamma > MIN_EARLY_STRENGTH + 1e-9
        {
            gamma -= 0.05;
            plan = DiffusionPlan::with_strength(cfg, target, threshold, timeline, gamma);
        }
        plan
    }

    /// The blend's path (see the field), made on first call.
    fn blend_path(&self) -> &BlendPath {
        self.path.get_or_init(|| {
            if !self.together {
                return BlendPath::default();
            }
            let path = BlendPath::least_dropping(&self.blend_volumes(self.threshold));
            if self.steered {
                self.held_at_frames(path)
            } else {
                path
            }
        })
    }

    /// A key of everything the blend's path is made from — the blobs at each of the grid's
    /// `(detail, fitted)` points, the iso-level and the grid — for caching the path beside the
    /// target (`crate::scene`): two plans with one key have the same path. `None` when the
    /// blend needs no grid (category III not arriving together).
    pub fn blend_key(&self) -> Option<u64> {
        *self
            .key
            .get_or_init(|| self.together.then(|| self.hash_blend_inputs()))
    }

    /// FNV-1a of the blend's inputs ([`DiffusionPlan::blend_key`]).
    fn hash_blend_inputs(&self) -> u64 {
        // FNV-1a over the bits (not `Hash`: the key is stored in a file name, so it must be
        // the same in every build).
        let mut h = Fnv1a::new();
        h.write_u64(1); // the key's own version
        h.write_u64(GRID_STEPS as u64);
        h.write_u64(self.threshold.to_bits());
        if self.steered {
            // Only when steered, so the unsteered shots keep their cached paths: the frame check
            // depends on the frames' times.
            h.write_u64(2);
            h.write_u64(self.timeline.frames as u64);
            h.write_u64(self.timeline.fps.to_bits());
        }
        let t = self.blend_start + self.blend_seconds;
        for i in 0..=GRID_STEPS {
            for j in 0..=GRID_STEPS {
                let (detail, fitted) = (i as f64 / GRID_STEPS as f64, j as f64 / GRID_STEPS as f64);
                for b in self.frame_with(t, detail, fitted) {
                    let r = b.rotation;
                    for v in [b.center.x, b.center.y, b.center.z, r.x, r.y, r.z, r.w]
                        .into_iter()
                        .chain([b.semi_axes.x, b.semi_axes.y, b.semi_axes.z, b.a, b.b])
                    {
                        h.write_u64(v.to_bits());
                    }
                }
            }
        }
        h.finish()
    }

    /// The blend's path as knots `[u, detail, fitted]`, once made (by a frame inside the blend,
    /// [`DiffusionPlan::make_blend_path`], or [`DiffusionPlan::use_blend_knots`]).
    pub fn blend_knots(&self) -> Option<Vec<[f64; 3]>> {
        self.path.get().map(BlendPath::knots)
    }

    /// Make the blend's path now (about 0.3 s for the duck: 289 visible volumes), as the first
    /// frame inside the blend would.
    pub fn make_blend_path(&self) {
        self.blend_path();
    }

    /// Take `knots` — [`DiffusionPlan::blend_knots`] of a plan with the same
    /// [`DiffusionPlan::blend_key`] — as the blend's path instead of making it. False (and
    /// nothing taken) when they are not a path or a path is already made.
    pub fn use_blend_knots(&self, knots: &[[f64; 3]]) -> bool {
        match BlendPath::from_knots(knots) {
            Some(path) => self.path.set(path).is_ok(),
            None => false,
        }
    }

    /// `path` with the frames inside the blend checked on the statistics' lattice (1 % of the
    /// diagonal, what `render --stats` counts): a frame that would hold less volume than the
    /// frame before keeps an earlier fitted progress ([`BlendPath::held_at_frames`]). From a
    /// steered start (the duck's underside) the path chosen on the 17 × 17 grid lost 0.025 % of
    /// the final volume between two frames, between the grid's nodes (the same grid on the 1 %
    /// lattice still lost 0.04 %: the dip is the straight segment between nodes, not the
    /// lattice).
    fn held_at_frames(&self, path: BlendPath) -> BlendPath {
        let lattice = Lattice::for_target(&blob_bounds(&self.target), DEFAULT_CELL_FRACTION);
        let frames: Vec<(f64, f64)> = (0..self.timeline.frames)
            .map(|k| {
                let t = self.timeline.time(k);
                (t, self.eased_blend(t))
            })
            .collect();
        path.held_at_frames(&frames, |t, detail, fitted| {
            visible_volume(&self.frame_with(t, detail, fitted), self.threshold, lattice).voxels
        })
    }

    /// Eased progress of the blend at `t` seconds (half linear, half smoothstep: a peak rate
    /// 1.25× the mean), before the volume pace.
    fn eased_blend(&self, t: f64) -> f64 {
        let u = if self.blend_seconds > 0.0 {
            ((t - self.blend_start) / self.blend_seconds).clamp(0.0, 1.0)
        } else if t >= self.blend_start {
            1.0
        } else {
            0.0
        };
        lerp(u, smoothstep(u), 0.5)
    }

    /// Visible volume (cells of a 2 % lattice) on the `GRID_STEPS` grid of (III's progress,
    /// I/II's progress to the fitted `B`), at the blend's end time (III arriving `Together`
    /// depends on the progresses only).
    fn blend_volumes(&self, threshold: f64) -> Vec<Vec<f64>> {
        let lattice = Lattice::for_target(&blob_bounds(&self.target), 0.02);
        let t = self.blend_start + self.blend_seconds;
        let n = GRID_STEPS;
        (0..=n)
            .into_par_iter()
            .map(|i| {
                (0..=n)
                    .map(|j| {
                        let (detail, fitted) = (i as f64 / n as f64, j as f64 / n as f64);
                        let blobs = self.frame_with(t, detail, fitted);
                        visible_volume(&blobs, threshold, lattice).voxels as f64
                    })
                    .collect()
            })
            .collect()
    }

    /// [`DiffusionPlan::new`] with the early blobs' strength `γ` (`B = γ·(1+A)/A`; 0: the
    /// fitted `B`), before pacing the blend.
    fn with_strength(
        cfg: &DiffusionConfig,
        target: &[Blob],
        threshold: f64,
        timeline: Timeline,
        strength: f64,
    ) -> DiffusionPlan {
        let n = target.len();
        let n_live = target.iter().filter(|b| b.is_live()).count();
        let n_ii = category_ii_count(n_live, cfg.category_ii);
        let early = early_shape(target, strength);
        let early_b: Vec<f64> = early.iter().map(|b| b.b).collect();
        let connected = strength > 0.0;
        let (mut order, n_ii) = display_order(&early, threshold, n_ii, connected, &cfg.steering());
        // III nearest-first from the cloud of I and II: each III blob then has a parent nearer
        // the cloud than itself, so III grows out as chains, not as lone blobs.
        order_by_nearest(target, &mut order, 1 + n_ii);
        let mut detail = vec![false; n];
        for &i in order.iter().skip(1 + n_ii) {
            detail[i] = true;
        }
        // Parents: the nearest blob placed before (by its ellipsoidal radius).
        let mut parent = vec![None; n];
        for (pos, &i) in order.iter().enumerate() {
            parent[i] = nearest_blob(target, &order[..pos], target[i].center);
        }
        // Steered, a II blob emerges part way out (`emerge.rs`); unsteered, at its parent's
        // centre as before.
        let steered = !cfg.steering().is_none();
        let emerge = if steered && strength > 0.0 {
            emergence(
                &early,
                threshold,
                &order[..(1 + n_ii).min(order.len())],
                &parent,
            )
        } else {
            vec![0.0; n]
        };
        // Schedule: II paced by volume, III at the end.
        let motion = timeline.motion_seconds();
        let g2 = cfg.grow_seconds.min(motion / 3.0);
        let (finish, early_voxels) =
            volume_paced_finish(&early, threshold, &order[..(1 + n_ii).min(order.len())]);
        let mut early_share = f64::NAN;
        let g3 = match cfg.category_iii {
            DetailArrival::Together => {
                // The motion is split in proportion to the volume each part adds (the early
                // shape's share of the final volume, counted within [0.2, 0.8]), so both parts
                // grow at about the same rate; at least `final_grow_seconds`.
                let lattice = Lattice::for_target(&blob_bounds(&early), 0.02);
                let final_voxels = visible_volume(target, threshold, lattice).voxels.max(1);
                early_share = early_voxels as f64 / final_voxels as f64;
                let share = early_share.clamp(0.2, 0.8);
                cfg.final_grow_seconds
                    .max(motion * (1.0 - share))
                    .min(motion)
            }
            DetailArrival::Progressive => cfg.final_grow_seconds.max(motion / 2.0).min(motion),
        };
        let blend_start = motion - g3;
        let mut start = vec![0.0; n];
        let mut grow = vec![0.0; n];
        if let Some(&first) = order.first() {
            // Blob I is on screen from the first frame, small, and grows first.
            start[first] = 0.0;
            grow[first] = blend_start * finish[0];
        }
        for (k, &i) in order.iter().enumerate().skip(1) {
            if k <= n_ii {
                // From the previous blob's finish (or `grow_seconds` before its own, if
                // earlier), so the volume keeps rising between finishes.
                let end = blend_start * finish[k];
                start[i] = (end - g2).min(blend_start * finish[k - 1]).max(0.0);
                grow[i] = end - start[i];
            } else {
                match cfg.category_iii {
                    DetailArrival::Together => {
                        // Full size within the first part of the blend, so that from then on
                        // the field is the convex blend of the early field and the fitted one.
                        start[i] = blend_start;
                        grow[i] = DETAIL_GROWTH_SHARE * g3;
                    }
                    DetailArrival::Progressive => {
                        let n_iii = order.len() - 1 - n_ii;
                        let g = g2.min(g3);
                        let slot = (k - 1 - n_ii) as f64 / n_iii.max(1) as f64;
                        start[i] = blend_start + (g3 - g) * slot;
                        grow[i] = g;
                    }
                }
            }
        }
        DiffusionPlan {
            target: target.to_vec(),
            early_b,
            order,
            category_ii: n_ii,
            detail,
            parent,
            start,
            grow,
            blend_start,
            blend_seconds: g3,
            path: OnceLock::new(),
            key: OnceLock::new(),
            threshold,
            early_share,
            together: cfg.category_iii == DetailArrival::Together,
            steered,
            emerge,
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
        self.at(self.timeline.time(k))
    }

    /// The blobs at `t` seconds (any time; see [`crate::animate::Plan::at`]).
    pub fn at(&self, t: f64) -> Vec<Blob> {
        if self.timeline.progress_at(t) >= 1.0 {
            return self.target.clone();
        }
        self.frame_at(t)
    }

    /// The blobs at `t` seconds into the motion.
    fn frame_at(&self, t: f64) -> Vec<Blob> {
        // Progress of the blend: eased time mapped through the volume pace. Before and after
        // the blend the path's ends are known: no grid needed.
        let eased = self.eased_blend(t);
        let (detail, fitted) = if eased <= 0.0 {
            (0.0, 0.0)
        } else if eased >= 1.0 {
            (1.0, 1.0)
        } else {
            self.blend_path().at(eased)
        };
        self.frame_with(t, detail, fitted)
    }

    /// The blobs at `t` seconds with category III at progress `detail` (its `B²` weight, and
    /// its growth when it arrives `Together`) and categories I and II at progress `fitted`
    /// from their early `B²` to the fitted one.
    fn frame_with(&self, t: f64, detail: f64, fitted: f64) -> Vec<Blob> {
        let mut out = self.target.clone();
        // In display order, so a parent's current centre is known before its children's.
        for &i in &self.order {
            let blob = &self.target[i];
            let (s, g) = (self.start[i], self.grow[i]);
            let first = self.order.first() == Some(&i);
            let from = self.parent[i].map_or(blob.center, |p| out[p].center);
            let home = self.parent[i].map_or(DVec3::ZERO, |p| self.target[p].center);
            // Steered II: emerge part way out, scaled with the parent's own growth so the point
            // stays inside it while it grows (the shell's early frames split in 3D without).
            let k = match self.parent[i] {
                Some(p) if self.emerge[i] > 0.0 => {
                    let grown = out[p].semi_axes.max_element()
                        / self.target[p]
                            .semi_axes
                            .max_element()
                            .max(f64::MIN_POSITIVE);
                    self.emerge[i] * grown.min(1.0)
                }
                _ => 0.0,
            };
            if !first && (t < s || (t == s && g > 0.0)) {
                let center = if k > 0.0 {
                    from + (blob.center - home) * way_out(k, 0.0)
                } else {
                    from
                };
                out[i] = Blob {
                    center,
                    b: 0.0,
                    ..*blob
                };
                continue;
            }
            let mut e = if self.detail[i] && self.together {
                smoothstep(detail / DETAIL_GROWTH_SHARE)
            } else if g <= 0.0 {
                1.0
            } else {
                smoothstep((t - s) / g)
            };
            if first {
                // Volume (∝ size³) rising evenly from the seed's.
                let u = if g <= 0.0 {
                    1.0
                } else {
                    ((t - s) / g).clamp(0.0, 1.0)
                };
                e = lerp(SEED_SIZE.powi(3), 1.0, u).cbrt();
            }
            let b = if self.detail[i] {
                // III adds to the field gently: B² rises with the blend.
                blob.b * detail.sqrt()
            } else {
                blend_b(self.early_b[i], blob.b, fitted)
            };
            // The offset from the parent grows with the size: a chain of growing blobs is a
            // scaled copy of its final shape about its root.
            let center = if self.parent[i].is_some() {
                from + (blob.center - home) * way_out(k, e)
            } else {
                blob.center
            };
            out[i] = Blob {
                center,
                semi_axes: blob.semi_axes * e,
                b,
                ..*blob
            };
        }
        out
    }
}
