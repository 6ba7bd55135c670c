//! A story (issue 51): a shot that forms one target, holds, then turns into the next target,
//! and so on — a cumulus that becomes a duck and then a torus knot (Fattal & Lischinski 2004
//! drive smoke through a sequence of targets in turn).
//!
//! A story is a plan made of consecutive plans, its *beats*. Beat 0 forms the first target by
//! any scheme (aggregation, diffusion, or a morph from a source of its own); each later beat is
//! a [`MorphPlan::in_place`] from the target before into its own (no alignment and no lead: the
//! target before is on screen, where it is), kept in one piece and paced by volume
//! ([`MorphPlan::kept_in_one_piece`], [`MorphPlan::paced_by_volume`]). Each beat's motion runs from its `start` to its
//! `end` (shot seconds); the target then holds until the next beat's start (the last one to
//! the end of the shot). The blobs at shot time `t` are the blobs of the beat `t` falls in, at
//! `t − start` of its own plan.
//!
//! **One cloud throughout.** The story's blob list is a list of *slots*, and a blob keeps its
//! slot from one beat to the next: a morph's paired and merged blobs take the slot of the
//! source blob they start as ([`MorphPlan::sources`]); a split blob (it grows from zero size)
//! and a target blob that is dead get new slots. So when a beat starts, its blobs are the last
//! beat's final blobs in the same slots: the shape, the billows (seeded per blob index and
//! anchored to each blob) and the velocities run on without a pop. Slots the current beat does
//! not use are hidden ([`HIDDEN`]). The slots are numbered from the last beat back, so the last
//! beat's entries keep their own indices: the last frame starts with the last target's blobs
//! exactly, as every scheme's does (the hidden slots follow).
//!
//! **Time.** The story's [`Timeline`] is the shot's, with the motion ending at the last beat's
//! `end` (progress 1 = the last target formed), so a scene's `timing` retimes the whole story as
//! one scheme: its progress is a fraction of the story from the first pose to the last target
//! formed, the holds between beats counting as story time.

use super::blob_bounds;
use super::stats::Lattice;
use super::{
    AnimateError, Animation, MorphConfig, MorphPlan, Plan, Timeline, invalid, plan_with_source,
};
use crate::blobby::{Blob, BlobModel};

/// Lattice cell (fraction of the target's diagonal) on which a story's morphs are paced by
/// volume ([`MorphPlan::paced_by_volume`]).
pub const PACE_CELL: f64 = 0.02;

/// What a slot holds while its blob is not in the story's current beat: nothing (`B = 0`, zero
/// size, at the origin), the same bits in every frame.
pub const HIDDEN: Blob = Blob {
    center: glam::DVec3::ZERO,
    rotation: glam::DQuat::IDENTITY,
    semi_axes: glam::DVec3::ZERO,
    a: 0.0,
    b: 0.0,
};

/// When a beat's motion runs, in shot seconds: from `start` to `end`, when its target is formed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeatTimes {
    /// Seconds from the shot's first frame at which the motion starts.
    pub start: f64,
    /// Seconds from the shot's first frame at which the target is formed.
    pub end: f64,
}

/// A later beat: a morph, in place, from the target before into `target`.
#[derive(Clone, Copy, Debug)]
pub struct MorphBeat<'a> {
    /// The target it turns into (placed in the shot).
    pub target: &'a BlobModel,
    /// Fraction of the motion over which the blobs' starts are spread (as a morph's `stagger`).
    pub stagger: f64,
    /// When it runs.
    pub times: BeatTimes,
}

/// Check a story's beat times against a shot whose last frame is at `shot_end` seconds, with
/// frames `1/fps` apart: at least two beats, every time finite, each motion at least one frame
/// long and ending by the shot's end, and each beat starting no earlier than the one before
/// ends (the hold between may be empty). Errors name the field as `story[i].start` / `.end`.
pub fn check_times(times: &[BeatTimes], shot_end: f64, fps: f64) -> Result<(), AnimateError> {
    if times.len() < 2 {
        return Err(invalid(
            "story",
            format!(
                "a story is a sequence of at least two targets, got {}; a single target is \
                 written `target:` with its `animation`",
                times.len()
            ),
        ));
    }
    let frame = 1.0 / fps;
    for (i, t) in times.iter().enumerate() {
        let field = |name: &str| format!("story[{i}].{name}");
        for (name, v) in [("start", t.start), ("end", t.end)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(
                    &field(name),
                    format!("must be a finite number of seconds ≥ 0, got {v}"),
                ));
            }
        }
        if i > 0 && t.start < times[i - 1].end {
            return Err(invalid(
                &field("start"),
                format!(
                    "times must increase: this target starts at {} s, before the one before is \
                     formed ({} s)",
                    t.start,
                    times[i - 1].end
                ),
            ));
        }
        // Less than a frame would jump from one target to the next between two frames.
        if t.end - t.start < frame * (1.0 - 1e-9) {
            return Err(invalid(
                &field("end"),
                format!(
                    "times must increase: the motion from {} s to {} s is shorter than one frame \
                     ({frame:.4} s); a change of target needs frames to happen in",
                    t.start, t.end
                ),
            ));
        }
        if t.end > shot_end + 1e-9 {
            return Err(invalid(
                &field("end"),
                format!(
                    "{} s is after the shot's last frame ({shot_end} s); lengthen shot.seconds \
                     or end the story sooner",
                    t.end
                ),
            ));
        }
    }
    Ok(())
}

/// A later beat's morph: its `stagger`, no lead and no hold (the holds are the gaps between
/// beats).
pub fn morph_config(stagger: f64) -> MorphConfig {
    MorphConfig {
        from: (),
        stagger,
        lead_seconds: 0.0,
        hold_seconds: 0.0,
    }
}

/// One beat: its plan (in its own time, 0 at its start), when it starts, and the slot of each
/// entry of its blob list.
#[derive(Clone, Debug)]
struct Beat {
    plan: Plan,
    start: f64,
    slots: Vec<usize>,
}

/// A planned story (see the module doc).
#[derive(Clone, Debug)]
pub struct StoryPlan {
    beats: Vec<Beat>,
    slots: usize,
    timeline: Timeline,
}

/// The timeline of a beat's own plan: its motion lasts exactly `seconds` (the frames cover it,
/// the rest is a hold), so its plan's progress is 1 at `seconds` on.
fn beat_timeline(seconds: f64, fps: f64) -> Timeline {
    let frames = (seconds * fps).ceil().max(1.0);
    Timeline {
        frames: frames as usize + 1,
        fps,
        hold_seconds: (frames / fps - seconds).max(0.0),
    }
}

impl StoryPlan {
    /// Plan a story over a shot of `frames` frames at `fps`: beat 0 forms `first_target` by
    /// `first` (a morph's source is `first_source`) over `first_times`; each of `later` morphs
    /// the target before into its own. Every random choice derives from `seed` (beat 0's
    /// scheme; the morphs draw none).
    #[allow(clippy::too_many_arguments)]
    pub fn new<S>(
        first: &Animation<S>,
        first_target: &BlobModel,
        first_source: Option<&BlobModel>,
        first_times: BeatTimes,
        later: &[MorphBeat<'_>],
        frames: usize,
        fps: f64,
        seed: u64,
    ) -> Result<StoryPlan, AnimateError> {
        let end = frames.saturating_sub(1) as f64 / fps;
        let times: Vec<BeatTimes> = std::iter::once(first_times)
            .chain(later.iter().map(|b| b.times))
            .collect();
        check_times(&times, end, fps)?;
        for (i, b) in later.iter().enumerate() {
            morph_config(b.stagger).validate().map_err(|e| match e {
                AnimateError::Invalid { message, .. } => {
                    invalid(&format!("story[{}].stagger", i + 1), message)
                }
                other => other,
            })?;
            if b.target.blobs.is_empty() {
                return Err(AnimateError::EmptyModel);
            }
        }
        let seconds = first_times.end - first_times.start;
        let plan = plan_with_source(
            first,
            first_target,
            first_source,
            beat_timeline(seconds, fps),
            seed,
        )?;
        let mut plans = vec![(plan, first_times.start)];
        // Per later beat, the blob of the target before that each entry starts as.
        let mut sources: Vec<Vec<Option<usize>>> = Vec::with_capacity(later.len());
        let mut before = &first_target.blobs;
        for b in later {
            let lattice = Lattice::for_target(&blob_bounds(&b.target.blobs), PACE_CELL);
            let morph = MorphPlan::in_place(
                &morph_config(b.stagger),
                before,
                &b.target.blobs,
                beat_timeline(b.times.end - b.times.start, fps),
            )
            .kept_in_one_piece(b.target.threshold)
            .paced_by_volume(b.target.threshold, lattice);
            sources.push(morph.sources().to_vec());
            plans.push((Plan::Morph(morph), b.times.start));
            before = &b.target.blobs;
        }
        // Slots, numbered from the last beat back: its entries keep their own indices (so the
        // last target's hold is its own blob list), and each target's blob takes the slot of
        // the entry of the next beat that starts as it (the target before sits in the first
        // entries of a beat's list); entries nothing continues get new slots.
        let lengths: Vec<usize> = plans.iter().map(|(p, _)| p.at(0.0).len()).collect();
        let last = plans.len() - 1;
        let mut slots_of: Vec<Vec<usize>> = vec![Vec::new(); plans.len()];
        slots_of[last] = (0..lengths[last]).collect();
        let mut slots = lengths[last];
        for i in (0..last).rev() {
            let mut own = vec![usize::MAX; lengths[i]];
            for (entry, source) in sources[i].iter().enumerate() {
                if let Some(s) = *source {
                    own[s] = slots_of[i + 1][entry];
                }
            }
            for slot in own.iter_mut().filter(|s| **s == usize::MAX) {
                *slot = slots;
                slots += 1;
            }
            slots_of[i] = own;
        }
        let beats = plans
            .into_iter()
            .zip(slots_of)
            .map(|((plan, start), slots)| Beat { plan, start, slots })
            .collect();
        let motion_end = times[times.len() - 1].end;
        Ok(StoryPlan {
            beats,
            slots,
            timeline: Timeline {
                frames,
                fps,
                hold_seconds: (end - motion_end).max(0.0),
            },
        })
    }

    /// The shot's timeline (its motion ends when the last target is formed).
    pub fn timeline(&self) -> Timeline {
        self.timeline
    }

    /// Slots in the story's blob list (every frame has this many entries).
    pub fn slots(&self) -> usize {
        self.slots
    }

    /// The number of beats (targets).
    pub fn beats(&self) -> usize {
        self.beats.len()
    }

    /// Beat `i`'s own plan (0 at its start) and its start in shot seconds.
    pub fn beat(&self, i: usize) -> (&Plan, f64) {
        (&self.beats[i].plan, self.beats[i].start)
    }

    /// The slot of each entry of beat `i`'s blob list.
    pub fn beat_slots(&self, i: usize) -> &[usize] {
        &self.beats[i].slots
    }

    /// The beat that shot time `t` falls in: the last one started by `t` (the first before it).
    pub fn beat_at(&self, t: f64) -> usize {
        self.beats
            .iter()
            .rposition(|b| b.start <= t)
            .unwrap_or_default()
    }

    /// The blobs of frame `k` (0-based).
    pub fn frame(&self, k: usize) -> Vec<Blob> {
        self.at(self.timeline.time(k))
    }

    /// The blobs at `t` seconds (any time): the current beat's blobs in their slots, the other
    /// slots [`HIDDEN`].
    pub fn at(&self, t: f64) -> Vec<Blob> {
        let beat = &self.beats[self.beat_at(t)];
        let mut out = vec![HIDDEN; self.slots];
        for (blob, &slot) in beat.plan.at(t - beat.start).into_iter().zip(&beat.slots) {
            out[slot] = blob;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::{DiffusionConfig, sphere_blob};
    use crate::blobby::model_file::MODEL_VERSION;
    use crate::blobby::{BlobField, SourceInfo};
    use crate::decompose::Primitive;
    use glam::DVec3;

    fn model(blobs: Vec<Blob>) -> BlobModel {
        BlobModel {
            version: MODEL_VERSION,
            primitive: Primitive::Ellipsoid,
            threshold: 1.0,
            source: SourceInfo {
                mesh: "test".into(),
                bounds: crate::animate::blob_bounds(&blobs),
                vertices: 0,
                faces: 0,
            },
            seed: 1,
            blobs,
        }
    }

    /// A row of `n` spheres along `axis`.
    fn row(n: usize, axis: DVec3, r: f64) -> BlobModel {
        model(
            (0..n)
                .map(|i| sphere_blob(axis * (i as f64 - (n - 1) as f64 / 2.0) * r, r))
                .collect(),
        )
    }

    fn story() -> (StoryPlan, [BlobModel; 3]) {
        let targets = [
            row(5, DVec3::X, 0.5),
            row(8, DVec3::Y, 0.4),
            row(3, DVec3::Z, 0.7),
        ];
        let anim: Animation = Animation::Diffusion(DiffusionConfig::default());
        let plan = StoryPlan::new(
            &anim,
            &targets[0],
            None,
            BeatTimes {
                start: 0.0,
                end: 2.0,
            },
            &[
                MorphBeat {
                    target: &targets[1],
                    stagger: 0.4,
                    times: BeatTimes {
                        start: 2.5,
                        end: 4.0,
                    },
                },
                MorphBeat {
                    target: &targets[2],
                    stagger: 0.2,
                    times: BeatTimes {
                        start: 4.0,
                        end: 5.5,
                    },
                },
            ],
            145,
            24.0,
            1,
        )
        .unwrap();
        (plan, targets)
    }

    fn live(blobs: &[Blob]) -> Vec<Blob> {
        let mut v: Vec<Blob> = blobs.iter().copied().filter(Blob::is_live).collect();
        v.sort_by(|a, b| {
            a.center
                .to_array()
                .partial_cmp(&b.center.to_array())
                .unwrap()
        });
        v
    }

    #[test]
    fn holds_show_each_target_and_beats_hand_over_in_place() {
        let (plan, targets) = story();
        assert_eq!(plan.beats(), 3);
        // Every frame has every slot; the holds are the targets (as sets of blobs).
        let fps = 24.0;
        assert!((0..145).all(|k| plan.frame(k).len() == plan.slots()));
        for (t, target) in [(2.2, &targets[0]), (4.0, &targets[1]), (6.0, &targets[2])] {
            assert_eq!(live(&plan.at(t)), live(&target.blobs), "at {t} s");
        }
        // At a beat's start its blobs are the last beat's final blobs, slot for slot (the
        // rotation through a slerp at 0 may differ in the last bits).
        for start in [2.5, 4.0] {
            let (before, after) = (plan.at(start - 1e-9), plan.at(start));
            for (a, b) in before.iter().zip(&after) {
                assert_eq!(a.is_live(), b.is_live());
                if a.is_live() {
                    assert!(a.center.distance(b.center) < 1e-12);
                    assert!(a.semi_axes.distance(b.semi_axes) < 1e-12);
                    assert!((a.b - b.b).abs() < 1e-12);
                }
            }
        }
        // The motion is continuous: the field at a probe changes little from one 1/240 s step
        // to the next through the morphs.
        let probe = DVec3::new(0.3, 0.2, 0.0);
        let mut last: Option<f64> = None;
        for i in 0..=(6.0 * 10.0 * fps) as usize {
            let t = i as f64 / (10.0 * fps);
            if t < 2.0 {
                continue;
            }
            let f = BlobField::new(&plan.at(t), 1.0).value(probe);
            if let Some(l) = last {
                assert!((f - l).abs() < 0.2, "field jumps at {t} s: {l} → {f}");
            }
            last = Some(f);
        }
    }

    #[test]
    fn the_story_timeline_ends_its_motion_at_the_last_target() {
        let (plan, targets) = story();
        let tl = plan.timeline();
        assert!((tl.motion_seconds() - 5.5).abs() < 1e-12);
        assert_eq!(live(&plan.frame(144)), live(&targets[2].blobs));
        // The last target keeps its own indices: the last frame starts with it, bit for bit.
        let n = targets[2].blobs.len();
        assert_eq!(&plan.frame(144)[..n], &targets[2].blobs[..]);
        assert_eq!(plan.beat_at(0.0), 0);
        assert_eq!(plan.beat_at(2.49), 0);
        assert_eq!(plan.beat_at(2.5), 1);
        assert_eq!(plan.beat_at(5.0), 2);
    }

    #[test]
    fn timing_retimes_the_whole_story_and_wind_carries_it() {
        use crate::animate::{Direction, Timing, TimingKey, Wind};
        let (plan, targets) = story();
        let plan = Plan::Story(plan);
        // Progress 1 at 1 s: the last target formed (the story's end, 5.5 s of it); 0.4 is
        // 2.2 s of the story, in the first target's hold (2 to 2.5 s).
        let key = |time, progress| TimingKey {
            time,
            progress,
            ease: Default::default(),
        };
        let timing = Timing::try_from(vec![key(0.0, 0.0), key(1.0, 1.0)]).unwrap();
        let wind = Wind {
            velocity: DVec3::new(0.5, 0.0, 0.0),
        };
        let d = Direction::new(&plan, Some(wind), Some(timing));
        let moved = |blobs: &[Blob], by: DVec3| -> Vec<Blob> {
            blobs
                .iter()
                .map(|b| Blob {
                    center: b.center + by,
                    ..*b
                })
                .collect()
        };
        assert_eq!(
            live(&d.at(&plan, 1.0)),
            live(&moved(&targets[2].blobs, DVec3::new(0.5, 0.0, 0.0)))
        );
        assert_eq!(
            live(&d.at(&plan, 0.4)),
            live(&moved(&targets[0].blobs, DVec3::new(0.2, 0.0, 0.0)))
        );
    }

    #[test]
    fn bad_times_are_refused_with_their_field() {
        let t = |start, end| BeatTimes { start, end };
        let cases = [
            (vec![t(0.0, 1.0)], "story"),
            (vec![t(0.0, 1.0), t(0.5, 2.0)], "story[1].start"),
            (vec![t(0.0, 1.0), t(1.0, 1.0)], "story[1].end"),
            (vec![t(0.0, 1.0), t(1.0, 9.0)], "story[1].end"),
            (vec![t(0.0, f64::NAN), t(1.0, 2.0)], "story[0].end"),
        ];
        for (times, field) in cases {
            match check_times(&times, 5.0, 24.0) {
                Err(AnimateError::Invalid { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{times:?}: {other:?}"),
            }
        }
        assert!(check_times(&[t(0.0, 1.0), t(1.0, 2.0)], 5.0, 24.0).is_ok());
    }
}
