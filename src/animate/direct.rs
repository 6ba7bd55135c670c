//! How the shot plays a planned animation (issue 51): a [`Wind`] that carries the whole cloud,
//! a keyed retime curve ([`Timing`]) from the shot's time to the scheme's progress, and a
//! target that moves ([`TargetMotion`], the keyed `transform`).
//!
//! A [`Direction`] wraps the plan's own paths: the blobs at shot time `t` are the plan's blobs
//! at scheme time `s(t)` (the retime; `s(t) = t` without one), carried by the target's motion
//! `M(t)` (keyed in the shot's time, [`Direction::carry`]), then moved by `wind · t`. The
//! billows are anchored to the blobs' frames, so they drift with them. Velocities are the same
//! centred difference of these blobs in the shot's time ([`VelocityField::of_path`]), so they
//! hold the wind and follow the retimed speed (`v = ds/dt · v_scheme + wind`, the chain rule).
//! A deforming target ([`super::deform`]) carries each blob with the surface around it, at the
//! shot's time, before the wind. Without wind, retime and deformation the blobs and velocities
//! are the plan's own, bit for bit.
//!
//! The retime's progress is a fraction of the scheme's own motion (0 = its first pose, 1 = the
//! target formed: the end of the motion, `hold_seconds` before the shot's end as planned), so
//! one curve means the same for every scheme and shot length. Between keys the progress runs
//! linearly or eased (smoothstep) into the later key; a key equal to the one before holds, a
//! lower one runs the scheme backwards.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use super::target_motion::{Similarity, TargetMotion};
use super::{Plan, VelocityField};
use crate::blobby::Blob;

/// A steady wind (the scene file's `wind`): the whole cloud drifts at `velocity`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "WrittenWind")]
pub struct Wind {
    /// Drift in world units per second (the shot's units, after the target transform).
    pub velocity: DVec3,
}

/// The fields as written; checked into a [`Wind`].
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default, rename = "Wind")]
struct WrittenWind {
    velocity: DVec3,
}

impl Default for WrittenWind {
    fn default() -> Self {
        WrittenWind {
            velocity: DVec3::ZERO,
        }
    }
}

impl TryFrom<WrittenWind> for Wind {
    type Error = String;

    fn try_from(w: WrittenWind) -> Result<Self, String> {
        if !w.velocity.is_finite() {
            return Err(format!(
                "wind.velocity must be finite (world units per second), got {}",
                w.velocity
            ));
        }
        Ok(Wind {
            velocity: w.velocity,
        })
    }
}

/// How a retime curve runs from the key before to this one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Ease {
    /// At a constant rate.
    #[default]
    Linear,
    /// Smoothstep: starting and arriving at rest (zero slope at both keys).
    Smooth,
}

/// One key of a retime curve: at the shot's `time` (seconds from the first frame) the scheme
/// is at `progress` (0 = its first pose, 1 = the target formed, the end of its motion).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimingKey {
    /// Seconds from the shot's first frame.
    pub time: f64,
    /// The scheme's progress, a fraction of its motion in `[0, 1]`.
    pub progress: f64,
    /// How the curve runs from the key before to this one (ignored on the first key).
    #[serde(default)]
    pub ease: Ease,
}

/// A checked retime curve (the scene file's `timing`): at least two keys, finite, times
/// strictly increasing, progress in `[0, 1]`. Before the first key the scheme holds at its
/// progress, after the last at the last's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "Vec<TimingKey>")]
pub struct Timing(Vec<TimingKey>);

impl TryFrom<Vec<TimingKey>> for Timing {
    type Error = String;

    fn try_from(keys: Vec<TimingKey>) -> Result<Self, String> {
        if keys.len() < 2 {
            return Err(format!(
                "timing: need at least two keys (time, progress), got {}",
                keys.len()
            ));
        }
        for (i, k) in keys.iter().enumerate() {
            if !(k.time.is_finite() && k.progress.is_finite()) {
                return Err(format!(
                    "timing key {i}: time and progress must be finite, got time {} and progress {}",
                    k.time, k.progress
                ));
            }
            if !(0.0..=1.0).contains(&k.progress) {
                return Err(format!(
                    "timing key {i}: progress is a fraction of the scheme's motion in [0, 1], got {}",
                    k.progress
                ));
            }
        }
        crate::spline::check_increasing("timing key", keys.iter().map(|k| k.time))?;
        Ok(Timing(keys))
    }
}

impl Timing {
    /// The keys, in time order.
    pub fn keys(&self) -> &[TimingKey] {
        &self.0
    }

    /// The scheme's progress at the shot's time `t` (seconds).
    pub fn progress(&self, t: f64) -> f64 {
        let k = &self.0;
        let n = k.len();
        if t <= k[0].time {
            return k[0].progress;
        }
        if t >= k[n - 1].time {
            return k[n - 1].progress;
        }
        let i = k.windows(2).position(|w| t <= w[1].time).unwrap_or(n - 2);
        let (a, b) = (k[i], k[i + 1]);
        let u = ((t - a.time) / (b.time - a.time)).clamp(0.0, 1.0);
        let u = match b.ease {
            Ease::Linear => u,
            Ease::Smooth => super::smoothstep(u),
        };
        super::lerp(a.progress, b.progress, u)
    }
}

/// How the shot plays its plan: wind, retime, a deforming target and the target's keyed motion
/// (all optional).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Direction {
    /// The wind, if any.
    pub wind: Option<Wind>,
    /// The retime curve, if any.
    pub timing: Option<Timing>,
    /// The keyed target transform's motion, if the target moves.
    pub motion: Option<TargetMotion>,
    /// Seconds of the scheme's motion (progress 1), from the plan's timeline.
    pub motion_seconds: f64,
    /// The deforming target's motion of the blobs (in the shot's time, not the retimed
    /// scheme's: the mesh sequence plays at the shot's frames), if the target bends.
    pub deform: Option<std::sync::Arc<super::Deformation>>,
}

impl Direction {
    /// The direction of a plan with `wind` and `timing` (the scheme's motion length from
    /// `plan`'s timeline).
    pub fn new(plan: &Plan, wind: Option<Wind>, timing: Option<Timing>) -> Direction {
        Direction {
            wind,
            timing,
            motion: None,
            motion_seconds: plan.timeline().motion_seconds(),
            deform: None,
        }
    }

    /// This direction with the target moving by `motion` (`None`: it stays put).
    pub fn with_motion(self, motion: Option<TargetMotion>) -> Direction {
        Direction { motion, ..self }
    }

    /// True when the shot plays the plan as planned (the blobs are the plan's, bit for bit).
    pub fn is_plain(&self) -> bool {
        self.wind.is_none()
            && self.timing.is_none()
            && self.motion.is_none()
            && self.deform.is_none()
    }

    /// The target's motion at `t` seconds (the identity when it stays put).
    pub fn target_motion(&self, t: f64) -> Similarity {
        self.motion
            .as_ref()
            .map_or(Similarity::IDENTITY, |m| m.carry(t))
    }

    /// Where a point `p` of the plan's cloud is at the shot's time `t`: carried by the target's
    /// motion and the wind (`p` itself when neither moves it).
    pub fn carry(&self, t: f64, p: DVec3) -> DVec3 {
        let p = match &self.motion {
            Some(m) => m.carry(t).apply_point(p),
            None => p,
        };
        if self.wind.is_some() {
            p + self.drift(t)
        } else {
            p
        }
    }

    /// The scheme's time at the shot's time `t` (seconds): `t` without a retime, else the
    /// curve's progress times the scheme's motion.
    pub fn scheme_time(&self, t: f64) -> f64 {
        match &self.timing {
            Some(curve) => curve.progress(t) * self.motion_seconds,
            None => t,
        }
    }

    /// How far the wind has carried the cloud at `t` seconds (0 without wind).
    pub fn drift(&self, t: f64) -> DVec3 {
        self.wind.map_or(DVec3::ZERO, |w| w.velocity * t)
    }

    /// The blobs at the shot's time `t` seconds (any time, also between frames).
    pub fn at(&self, plan: &Plan, t: f64) -> Vec<Blob> {
        let mut blobs = plan.at(self.scheme_time(t));
        if let Some(d) = &self.deform {
            d.apply(&mut blobs, t);
        }
        if let Some(m) = &self.motion {
            m.carry(t).apply(&mut blobs);
        }
        if self.wind.is_some() {
            let d = self.drift(t);
            for b in &mut blobs {
                b.center += d;
            }
        }
        blobs
    }

    /// The blobs of 0-based frame `k`.
    pub fn frame(&self, plan: &Plan, k: usize) -> Vec<Blob> {
        if self.is_plain() {
            plan.frame(k)
        } else {
            self.at(plan, plan.timeline().time(k))
        }
    }

    /// The velocity of the density at the shot's time `t`.
    pub fn velocity(&self, plan: &Plan, t: f64) -> VelocityField {
        if self.is_plain() {
            VelocityField::of_plan(plan, t)
        } else {
            VelocityField::of_path(plan.timeline(), t, |t| self.at(plan, t))
        }
    }
}
