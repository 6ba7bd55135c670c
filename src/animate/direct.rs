//! How the shot plays a planned animation (issue 51): a [`Wind`] that carries the whole cloud,
//! and a keyed retime curve ([`Timing`]) from the shot's time to the scheme's progress.
//!
//! A [`Direction`] wraps the plan's own paths: the blobs at shot time `t` are the plan's blobs
//! at scheme time `s(t)` (the retime; `s(t) = t` without one), each moved by `wind · t`. The
//! billows are anchored to the blobs' frames, so they drift with them. Velocities are the same
//! centred difference of these blobs in the shot's time ([`VelocityField::of_path`]), so they
//! hold the wind and follow the retimed speed (`v = ds/dt · v_scheme + wind`, the chain rule).
//! Without wind and retime the blobs and velocities are the plan's own, bit for bit.

use glam::DVec3;
use serde::{Deserialize, Serialize};

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

/// How the shot plays its plan: wind and retime (both optional).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Direction {
    /// The wind, if any.
    pub wind: Option<Wind>,
}

impl Direction {
    /// True when the shot plays the plan as planned (the blobs are the plan's, bit for bit).
    pub fn is_plain(&self) -> bool {
        self.wind.is_none()
    }

    /// The scheme's time at the shot's time `t` (seconds).
    pub fn scheme_time(&self, t: f64) -> f64 {
        t
    }

    /// How far the wind has carried the cloud at `t` seconds (0 without wind).
    pub fn drift(&self, t: f64) -> DVec3 {
        self.wind.map_or(DVec3::ZERO, |w| w.velocity * t)
    }

    /// The blobs at the shot's time `t` seconds (any time, also between frames).
    pub fn at(&self, plan: &Plan, t: f64) -> Vec<Blob> {
        let mut blobs = plan.at(self.scheme_time(t));
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
