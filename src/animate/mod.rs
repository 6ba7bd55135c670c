//! Cloud animation schemes (paper §5.2; docs/ARCHITECTURE.md, Animation): aggregation (pieces
//! of cloud gather into the target), diffusion (the target spreads from one piece) and morph
//! (one blob model turns into another, e.g. [`cumulus`] into a duck); [`stats`] measures a
//! frame's visible cloud.
//!
//! In: a fitted [`crate::blobby::BlobModel`], the scheme's settings and the shot's [`Timeline`].
//! Out: a [`Plan`] that gives, per frame, the full blob list (index = blob identity, same length
//! as the model — a morph appends the source blobs that merge away; hidden blobs have `B = 0`).
//! The last frame equals the model's blobs exactly (bit-equal), whatever the scheme (a morph's
//! merged blobs follow, hidden).
//!
//! Time: frame `k` (0-based) of a shot of `n` frames at `fps` is at `k / fps` seconds. The motion
//! ends `hold_seconds` before the last frame (the target then sits still); a shot shorter than
//! its hold shows the target throughout.

pub mod aggregation;
pub mod cumulus;
pub mod deform;
pub mod diffusion;
pub mod direct;
pub mod mattes;
pub mod morph;
pub mod pieces;
mod repulsion;
pub mod stats;
pub mod target_motion;
pub mod velocity;

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::blobby::{Blob, BlobModel};
use crate::geometry::Aabb;

pub use aggregation::{AggregationConfig, AggregationPlan, Easing, Plane, Planes};
pub use deform::Deformation;
pub use diffusion::{DetailArrival, DiffusionConfig, DiffusionPlan, EarlyShape};
pub use direct::{Direction, Ease, Timing, TimingKey, Wind};
pub use mattes::MatteNames;
pub use morph::{MorphConfig, MorphPlan};
pub use target_motion::{PlacementKey, Similarity, TargetMotion};
pub use velocity::{BlobMotion, VelocityField};

/// Errors of the animation stage: settings that cannot produce an animation.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AnimateError {
    /// A setting is out of range; `field` is its path in the scene file (`animation.speed`).
    #[error("{field}: {message}")]
    Invalid {
        /// Dotted path of the setting.
        field: String,
        /// What is wrong, with the value found.
        message: String,
    },
    /// The model has no blobs.
    #[error("the target model has no blobs")]
    EmptyModel,
    /// A morph was planned without its source model.
    #[error("animation.from: a morph needs its source model")]
    MissingSource,
}

/// Build an [`AnimateError::Invalid`].
pub(crate) fn invalid(field: &str, message: impl Into<String>) -> AnimateError {
    AnimateError::Invalid {
        field: field.to_string(),
        message: message.into(),
    }
}

/// Check that `animation.NAME` is a finite number of seconds ≥ 0.
pub(crate) fn check_seconds(name: &str, v: f64) -> Result<(), AnimateError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(invalid(
            &format!("animation.{name}"),
            format!("must be a finite number of seconds ≥ 0, got {v}"),
        ))
    }
}

/// Check that `animation.NAME` is a fraction in `[0, max]`.
pub(crate) fn check_fraction(name: &str, v: f64, max: f64) -> Result<(), AnimateError> {
    if v.is_finite() && (0.0..=max).contains(&v) {
        Ok(())
    } else {
        Err(invalid(
            &format!("animation.{name}"),
            format!("must be a fraction in [0, {max}], got {v}"),
        ))
    }
}

/// A round blob of radius `r` at `c` with `A = 1` (so `B = 2`), for the stage's unit tests.
#[cfg(test)]
pub(crate) fn sphere_blob(c: DVec3, r: f64) -> Blob {
    Blob::from_ellipsoid(
        &crate::geometry::Ellipsoid {
            center: c,
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
        },
        1.0,
    )
}

/// One animation scheme with its settings (the scene file's `animation` field). `S` names a
/// morph's source model in the caller's terms (see [`MorphConfig`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Animation<S = ()> {
    /// Clusters of blobs fly in from outside and gather into the target (paper §5.2.1).
    Aggregation(AggregationConfig),
    /// The target grows from its largest blob outward (paper §5.2.2).
    Diffusion(DiffusionConfig),
    /// One blob model turns into another (metamorphosis).
    Morph(MorphConfig<S>),
}

impl<S> Default for Animation<S> {
    fn default() -> Self {
        Animation::Diffusion(DiffusionConfig::default())
    }
}

impl<S> Animation<S> {
    /// Check every setting; errors name the field as `animation.NAME`.
    pub fn validate(&self) -> Result<(), AnimateError> {
        match self {
            Animation::Aggregation(c) => c.validate(),
            Animation::Diffusion(c) => c.validate(),
            Animation::Morph(c) => c.validate(),
        }
    }

    /// Seconds the target holds still at the end of the shot.
    pub fn hold_seconds(&self) -> f64 {
        match self {
            Animation::Aggregation(c) => c.hold_seconds,
            Animation::Diffusion(c) => c.hold_seconds,
            Animation::Morph(c) => c.hold_seconds,
        }
    }
}

/// When each frame happens: frame count, rate, and the hold at the end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timeline {
    /// Frames in the shot (≥ 1).
    pub frames: usize,
    /// Frames per second (> 0).
    pub fps: f64,
    /// Seconds at the end during which the target sits still (≥ 0).
    pub hold_seconds: f64,
}

impl Timeline {
    /// Time of frame `k` (0-based) in seconds.
    pub fn time(&self, k: usize) -> f64 {
        k as f64 / self.fps
    }

    /// Seconds from the first frame to the end of the motion (0 when the hold covers the shot).
    pub fn motion_seconds(&self) -> f64 {
        (self.time(self.frames.saturating_sub(1)) - self.hold_seconds).max(0.0)
    }

    /// Progress of the motion at frame `k`, in `[0, 1]`; exactly 1 from the end of the motion on
    /// (so the last frame is always 1).
    pub fn progress(&self, k: usize) -> f64 {
        self.progress_at(self.time(k))
    }

    /// Progress of the motion at `t` seconds (any time, also between frames): 0 before the
    /// shot, exactly 1 from the end of the motion and from the last frame's time on.
    /// `progress_at(time(k)) == progress(k)` bit for bit.
    pub fn progress_at(&self, t: f64) -> f64 {
        let m = self.motion_seconds();
        if m <= 0.0 || t >= self.time(self.frames.saturating_sub(1)) {
            return 1.0;
        }
        (t / m).clamp(0.0, 1.0)
    }

    /// Time of the last frame in seconds (0 for a shot of one frame).
    pub fn end(&self) -> f64 {
        self.time(self.frames.saturating_sub(1))
    }
}

/// A planned animation: cheap to query for any frame, in any order.
#[derive(Clone, Debug)]
pub enum Plan {
    /// Aggregation keyframes.
    Aggregation(AggregationPlan),
    /// Diffusion order and schedule.
    Diffusion(DiffusionPlan),
    /// Morph pairing and schedule.
    Morph(MorphPlan),
}

/// Plan `animation` for `model` over `timeline`; every random choice derives from `seed`. A
/// morph needs [`plan_with_source`].
pub fn plan<S>(
    animation: &Animation<S>,
    model: &BlobModel,
    timeline: Timeline,
    seed: u64,
) -> Result<Plan, AnimateError> {
    plan_with_source(animation, model, None, timeline, seed)
}

/// [`plan`] with the morph's source model (ignored by the other schemes).
pub fn plan_with_source<S>(
    animation: &Animation<S>,
    model: &BlobModel,
    source: Option<&BlobModel>,
    timeline: Timeline,
    seed: u64,
) -> Result<Plan, AnimateError> {
    animation.validate()?;
    if model.blobs.is_empty() {
        return Err(AnimateError::EmptyModel);
    }
    if timeline.frames == 0 || !(timeline.fps.is_finite() && timeline.fps > 0.0) {
        return Err(invalid(
            "shot",
            format!(
                "need at least one frame and a positive frame rate, got {} frames at {} fps",
                timeline.frames, timeline.fps
            ),
        ));
    }
    Ok(match animation {
        Animation::Aggregation(c) => Plan::Aggregation(AggregationPlan::new(
            c,
            &model.blobs,
            model.threshold,
            timeline,
            seed,
        )),
        Animation::Diffusion(c) => Plan::Diffusion({
            c.check_target(&model.blobs)?;
            DiffusionPlan::new(c, &model.blobs, model.threshold, timeline)
        }),
        Animation::Morph(c) => {
            let source = source.ok_or(AnimateError::MissingSource)?;
            Plan::Morph(MorphPlan::new(c, &source.blobs, &model.blobs, timeline))
        }
    })
}

impl Plan {
    /// The diffusion's plan, when the animation is one.
    pub fn diffusion(&self) -> Option<&DiffusionPlan> {
        match self {
            Plan::Diffusion(p) => Some(p),
            _ => None,
        }
    }

    /// The blobs of frame `k` (0-based; frames past the end give the target).
    pub fn frame(&self, k: usize) -> Vec<Blob> {
        match self {
            Plan::Aggregation(p) => p.frame(k),
            Plan::Diffusion(p) => p.frame(k),
            Plan::Morph(p) => p.frame(k),
        }
    }

    /// The blobs at `t` seconds from the first frame, at any time (between frames for motion
    /// blur and velocities; before the shot the first pose, from the end of the motion on the
    /// target). `at(timeline().time(k))` equals `frame(k)` bit for bit.
    pub fn at(&self, t: f64) -> Vec<Blob> {
        match self {
            Plan::Aggregation(p) => p.at(t),
            Plan::Diffusion(p) => p.at(t),
            Plan::Morph(p) => p.at(t),
        }
    }

    /// The shot's timeline.
    pub fn timeline(&self) -> Timeline {
        match self {
            Plan::Aggregation(p) => p.timeline(),
            Plan::Diffusion(p) => p.timeline(),
            Plan::Morph(p) => p.timeline(),
        }
    }
}

/// Axis-aligned bounds of the blobs' ellipsoids (`ρ = 1`), live blobs only. This is "the
/// target's bounding box" of the animation and of the scene's camera framing and length unit.
pub fn blob_bounds(blobs: &[Blob]) -> Aabb {
    crate::blobby::ellipsoid_bounds(blobs)
}

/// Linear interpolation of `a` to `b` at `t ∈ [0, 1]`.
#[inline]
pub(crate) fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// Interpolate the shape of two blobs (semi-axes, A, B linearly; rotation by slerp) with the
/// given centre.
pub(crate) fn blend_shape(a: &Blob, b: &Blob, t: f64, center: DVec3) -> Blob {
    Blob {
        center,
        rotation: slerp(a.rotation, b.rotation, t),
        semi_axes: a.semi_axes.lerp(b.semi_axes, t),
        a: lerp(a.a, b.a, t),
        b: lerp(a.b, b.b, t),
    }
}

/// Shortest-path slerp that renormalises, robust to slightly non-unit inputs.
fn slerp(a: DQuat, b: DQuat, t: f64) -> DQuat {
    a.normalize().slerp(b.normalize(), t).normalize()
}

/// `smoothstep` on `[0, 1]`: zero slope at both ends.
#[inline]
pub(crate) fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn progress_reaches_one_at_the_hold_and_last_frame() {
        let t = Timeline {
            frames: 25,
            fps: 24.0,
            hold_seconds: 0.5,
        };
        assert_eq!(t.progress(0), 0.0);
        assert!((t.motion_seconds() - 0.5).abs() < 1e-12);
        assert!((t.progress(6) - 0.5).abs() < 1e-12);
        assert_eq!(t.progress(12), 1.0);
        assert_eq!(t.progress(24), 1.0);
        let one = Timeline {
            frames: 1,
            fps: 24.0,
            hold_seconds: 0.0,
        };
        assert_eq!(one.progress(0), 1.0);
    }
}
