//! The scene file's `story`: targets in turn, each formed from the one before (issue 51;
//! planned by [`crate::animate::story`]). `scenes/README.md` documents the fields.
//!
//! ```ron
//! story: [
//!     (target: Model("builtin:cumulus"), animation: Diffusion(()), end: 3.0),
//!     (target: Fit(mesh: "builtin:duck"), start: 4.0, end: 7.0),
//!     (target: Fit(mesh: "builtin:torus-knot"), transform: (scale: 0.8), start: 8.0, end: 11.0),
//! ],
//! ```
//!
//! The first entry's target forms by its `animation` (any scheme; default `Diffusion(())`)
//! between its `start` (default 0) and `end`; each later one is a morph from the target before,
//! from its `start` (default: the `end` before, no hold) to its `end`. A target holds from its
//! `end` until the next `start`, the last one to the end of the shot. Each target is placed by
//! its own `transform`, then by the scene's `transform` (the whole story's place in the shot).

use serde::{Deserialize, Serialize};

use super::transform::TargetTransform;
use super::{SceneFile, Target};
use crate::animate::{AnimateError, Animation, BeatTimes};

/// One target of a story as written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoryEntry {
    /// The shape, as the scene's `target` names one.
    pub target: Target,
    /// Where it stands in the shot (before the scene's `transform`; default: as fitted).
    #[serde(default)]
    pub transform: TargetTransform,
    /// Seconds from the shot's first frame at which the change into it starts (default: the
    /// first at 0, a later one when the target before is formed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
    /// Seconds from the shot's first frame at which it is formed (required).
    pub end: f64,
    /// First entry only: the scheme that forms it (default `Diffusion(())`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<Animation<Target>>,
    /// Later entries only: the morph's `stagger` (default 0: every blob moves at once).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stagger: Option<f64>,
}

/// A story morph's default `stagger`: none. Every blob moves at once, which (with the pulls
/// that keep it whole) kept the builtin story in one piece at every frame; staggered starts
/// (0.1 to 0.9) broke a loop off the torus knot half way (a quarter of the volume apart).
pub const DEFAULT_STAGGER: f64 = 0.0;

impl StoryEntry {
    /// The scheme that forms the first target.
    pub fn first_animation(&self) -> Animation<Target> {
        self.animation.clone().unwrap_or_default()
    }

    /// The morph's stagger of a later entry.
    pub fn stagger(&self) -> f64 {
        self.stagger.unwrap_or(DEFAULT_STAGGER)
    }
}

/// Each entry's start and end in shot seconds, the defaults filled in.
pub fn times(story: &[StoryEntry]) -> Vec<BeatTimes> {
    let mut out: Vec<BeatTimes> = Vec::with_capacity(story.len());
    for e in story {
        let start = e
            .start
            .unwrap_or_else(|| out.last().map_or(0.0, |before| before.end));
        out.push(BeatTimes { start, end: e.end });
    }
    out
}

/// An error of the story as `(field, message)`, the field named as the file writes it
/// (`story[1].end`).
pub type Invalid = (String, String);

fn invalid(field: impl Into<String>, message: impl Into<String>) -> Invalid {
    (field.into(), message.into())
}

/// `animation.NAME` of the first entry's scheme (or of a morph) as `story[i].animation.NAME`.
fn animate_error(prefix: &str, e: AnimateError) -> Invalid {
    match e {
        AnimateError::Invalid { field, message } => invalid(
            format!(
                "{prefix}{}",
                field.strip_prefix("animation").unwrap_or(&field)
            ),
            message,
        ),
        other => invalid(prefix, other.to_string()),
    }
}

/// Check the scene's story (nothing to check without one) and that a scene has a target or a
/// story: entries, times, schemes and targets (builtin names, fit settings).
pub fn validate(s: &SceneFile) -> Result<(), Invalid> {
    let story = &s.story;
    if story.is_empty() {
        return match s.target {
            Some(_) => Ok(()),
            None => Err(invalid(
                "target",
                "a scene needs a `target` (or a `story` of targets in turn)",
            )),
        };
    }
    if s.target.is_some() {
        return Err(invalid(
            "target",
            "a scene with a `story` names its targets there; leave `target` out",
        ));
    }
    if s.animation != Animation::default() {
        return Err(invalid(
            "animation",
            "a scene with a `story` forms its first target by `story[0].animation`; leave the \
             scene's `animation` out",
        ));
    }
    let shot_end = (s.shot.frame_count() - 1) as f64 / s.shot.fps;
    crate::animate::story::check_times(&times(story), shot_end, s.shot.fps)
        .map_err(|e| animate_error("", e))?;
    for (i, e) in story.iter().enumerate() {
        let at = |name: &str| format!("story[{i}].{name}");
        check_target(&e.target).map_err(|m| invalid(at("target"), m))?;
        if i == 0 {
            if e.stagger.is_some() {
                return Err(invalid(
                    at("stagger"),
                    "the first target forms by its `animation`; `stagger` is for the morphs \
                     into the later ones",
                ));
            }
            let anim = e.first_animation();
            anim.validate()
                .map_err(|err| animate_error(&at("animation"), err))?;
            if anim.hold_seconds() != Animation::<Target>::default().hold_seconds() {
                return Err(invalid(
                    at("animation.hold_seconds"),
                    "in a story a target holds from its `end` until the next one's `start`; \
                     leave the scheme's hold_seconds out",
                ));
            }
            if let Animation::Morph(m) = &anim {
                check_target(&m.from).map_err(|msg| invalid(at("animation.from"), msg))?;
            }
        } else {
            if e.animation.is_some() {
                return Err(invalid(
                    at("animation"),
                    "a later target is reached by a morph from the one before; set its \
                     `stagger` (the scheme is the first target's only)",
                ));
            }
            crate::animate::story::morph_config(e.stagger())
                .validate()
                .map_err(|err| animate_error(&format!("story[{i}]"), err))?;
        }
    }
    Ok(())
}

/// A target's builtin name and fit settings, checked before anything is loaded.
pub fn check_target(t: &Target) -> Result<(), String> {
    match t {
        Target::Model(p) => match p.strip_prefix("builtin:") {
            Some(name) if crate::animate::cumulus::builtin_model(name).is_none() => Err(format!(
                "no builtin model {p:?}; the builtin model is builtin:cumulus (builtin meshes \
                 are fitted: Fit(mesh: \"builtin:duck\"))"
            )),
            _ => Ok(()),
        },
        Target::Fit {
            mesh,
            blobs,
            candidates,
            samples,
            ..
        } => {
            if let Some(name) = mesh.strip_prefix("builtin:")
                && !crate::mesh::builtin::NAMES.contains(&name)
            {
                return Err(format!(
                    "no builtin mesh {mesh:?}; the builtin meshes are {}",
                    crate::mesh::builtin::NAMES
                        .iter()
                        .map(|n| format!("builtin:{n}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ));
            }
            crate::pipeline::FitConfig {
                blobs: *blobs,
                candidates: *candidates,
                samples: *samples,
                ..Default::default()
            }
            .validate()
            .map_err(|e| e.to_string())
        }
    }
}
