//! A story of targets (issue 51, item 1): the shipped `scenes/cumulus-duck-torus-knot.ron`
//! measured over every frame (one piece, no jump in volume, each hold the target), continuity at
//! the hand-over between targets, and bad stories reported where they are written.

use std::path::{Path, PathBuf};

use nephele::animate::stats::{ALPHA_LEVEL, Lattice, VisibleVolume, visible_volume};
use nephele::animate::{Plan, StoryPlan};
use nephele::blobby::Blob;
use nephele::render::{FrameOptions, FrameRenderer};
use nephele::scene::{self, RenderOptions, Shot};

use crate::temp_support;

/// The shipped story opened at preview size, its fits cached between runs in cargo's
/// temporary folder for integration tests (the cache's key covers the mesh and every fit
/// setting, so a stale fit is never reused).
fn shipped_story(preview: bool) -> Shot {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = scene::load_scene(&root.join("scenes/cumulus-duck-torus-knot.ron")).unwrap();
    let out = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("story-cumulus-duck-torus-knot");
    let opts = RenderOptions {
        output: Some(out),
        preview,
        ..Default::default()
    };
    Shot::open(scene, &opts).unwrap()
}

fn story(shot: &Shot) -> &StoryPlan {
    match &shot.prepared().unwrap().plan {
        Plan::Story(s) => s,
        other => panic!("not a story: {other:?}"),
    }
}

/// Beat `i`'s target in its own blob order (the last pose of its own plan).
fn target(story: &StoryPlan, i: usize) -> Vec<Blob> {
    story.beat(i).0.at(1e9)
}

/// Pixels with alpha above the coverage level.
fn silhouette(alpha: &[f32]) -> Vec<bool> {
    alpha.iter().map(|&a| a > ALPHA_LEVEL).collect()
}

fn iou(a: &[bool], b: &[bool]) -> f64 {
    let both = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let either = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    both as f64 / either.max(1) as f64
}

/// Issue 51's numbers on the shipped story (cumulus → duck → torus knot), every frame at the
/// 1 % lattice of `--stats`: the largest 3D piece ≥ 95 % of the visible volume; no frame-to-frame
/// change of the visible volume above 3 % of the larger of the two targets it runs between (the
/// first target's own while it forms); at the middle of each hold the silhouette's IoU with the
/// target rendered on its own (its blobs in their own order, the same camera, look and frame
/// size) ≥ 0.85.
#[test]
fn the_shipped_story_stays_one_piece_and_holds_each_target() {
    check_the_shipped_story(true);
}

/// The same at the scene's own size and quality (640×360, `Final`; the holds' IoU for the
/// measurements: `cargo test --release --test it -- --ignored --nocapture story::`).
#[test]
#[ignore = "full-size renders of the holds; run for the measurements"]
fn the_shipped_story_at_full_size() {
    check_the_shipped_story(false);
}

fn check_the_shipped_story(preview: bool) {
    let shot = shipped_story(preview);
    let prep = shot.prepared().unwrap();
    let story = story(&shot);
    let threshold = prep.model.threshold;
    let lattice = Lattice::for_target(&prep.bounds, 0.01);
    let volumes: Vec<VisibleVolume> = (0..story.beats())
        .map(|i| visible_volume(&target(story, i), threshold, lattice))
        .collect();
    let fps = shot.scene().file.shot.fps;
    let (mut worst_piece, mut worst_step) = ((1.0, 0), (0.0, 0));
    let mut last: Option<VisibleVolume> = None;
    for k in 0..shot.total() {
        let v = visible_volume(&shot.blobs(k).unwrap(), threshold, lattice);
        if v.largest_share() < worst_piece.0 {
            worst_piece = (v.largest_share(), k);
        }
        if let Some(l) = last {
            let beat = story.beat_at(k as f64 / fps);
            let larger = volumes[beat.saturating_sub(1)]
                .voxels
                .max(volumes[beat].voxels);
            let step = (v.voxels as f64 - l.voxels as f64).abs() / larger as f64;
            if step > worst_step.0 {
                worst_step = (step, k);
            }
        }
        last = Some(v);
    }
    eprintln!(
        "story: smallest largest-piece share {:.4} (frame index {}), largest volume step {:.4} of \
         the larger target (frame index {}); targets' volumes {:?} cells",
        worst_piece.0,
        worst_piece.1,
        worst_step.0,
        worst_step.1,
        volumes.iter().map(|v| v.voxels).collect::<Vec<_>>()
    );
    assert!(worst_piece.0 >= 0.95, "{worst_piece:?}");
    assert!(worst_step.0 <= 0.03, "{worst_step:?}");
    // The holds: from each target's end to the next one's start (the last to the shot's end).
    let story_file = &shot.scene().file.story;
    let shot_end = (shot.total() - 1) as f64 / fps;
    for (i, entry) in story_file.iter().enumerate() {
        let hold_end = story_file
            .get(i + 1)
            .and_then(|e| e.start)
            .unwrap_or(shot_end);
        let k = ((entry.end + hold_end) / 2.0 * fps).round() as u32;
        let settings = shot.settings(k).unwrap();
        let options = FrameOptions::default();
        let frame = shot.render_frame(k).unwrap();
        let own = FrameRenderer::render_once(&settings, &target(story, i), &options).0;
        let score = iou(&silhouette(&frame.alpha), &silhouette(&own.alpha));
        let cover = silhouette(&own.alpha).iter().filter(|&&c| c).count();
        eprintln!(
            "story: hold of target {} (frame index {k}): silhouette IoU {score:.4} with its own \
             render ({cover} px)",
            i + 1
        );
        assert!(cover > 100, "target {} is too small on screen", i + 1);
        assert!(score >= 0.85, "target {}: IoU {score}", i + 1);
        // The hold shows exactly the target's blobs (in the story's slots).
        let live = |b: &[Blob]| b.iter().filter(|b| b.is_live()).count();
        assert_eq!(live(&shot.blobs(k).unwrap()), live(&target(story, i)));
    }
}

/// The hand-over between targets is seamless: just before and at a beat's start the blobs are
/// the same in the same slots (so the billows, seeded per slot, do not change), the cloud is
/// still in the holds (velocity 0) and moves during each change.
#[test]
fn targets_hand_over_without_a_pop() {
    let shot = shipped_story(true);
    let prep = shot.prepared().unwrap();
    let story = story(&shot);
    for i in 1..story.beats() {
        let start = story.beat(i).1;
        let (before, after) = (prep.plan.at(start - 1e-6), prep.plan.at(start));
        assert_eq!(before.len(), after.len());
        for (a, b) in before.iter().zip(&after) {
            assert_eq!(a.is_live(), b.is_live(), "beat {i}");
            if a.is_live() {
                assert!(a.center.distance(b.center) < 1e-9, "beat {i}");
                assert!(a.semi_axes.distance(b.semi_axes) < 1e-9, "beat {i}");
                assert!((a.b - b.b).abs() < 1e-9, "beat {i}");
            }
        }
        let speed = |t: f64| {
            prep.direction
                .velocity(&prep.plan, t)
                .motions()
                .iter()
                .map(|m| m.velocity.length())
                .fold(0.0, f64::max)
        };
        let (prev_end, end) = (
            shot.scene().file.story[i - 1].end,
            shot.scene().file.story[i].end,
        );
        assert_eq!(speed((prev_end + start) / 2.0), 0.0, "hold before beat {i}");
        assert!(speed((start + end) / 2.0) > 0.0, "beat {i} moves");
    }
}

/// A story written wrong is reported at its place in the file, before anything is loaded.
#[test]
fn bad_stories_are_located() {
    let dir = temp_support::temp_dir("story-errors");
    let entry = |t: &str, rest: &str| format!("(target: {t}, {rest})");
    let cumulus = "Model(\"builtin:cumulus\")";
    let duck = "Fit(mesh: \"builtin:duck\")";
    let cases: Vec<(&str, String, usize, &str)> = vec![
        (
            "one entry",
            entry(cumulus, "end: 1.0"),
            2,
            "at least two targets",
        ),
        (
            "unknown builtin mesh",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 1.0"),
                entry("Fit(mesh: \"builtin:swan\")", "end: 2.0")
            ),
            4,
            "story[1].target: no builtin mesh \"builtin:swan\"",
        ),
        (
            "unknown builtin model",
            format!(
                "{},\n    {}",
                entry("Model(\"builtin:nimbus\")", "end: 1.0"),
                entry(duck, "end: 2.0")
            ),
            3,
            "story[0].target: no builtin model",
        ),
        (
            "missing file",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 1.0"),
                entry("Model(\"swan.ron\")", "end: 2.0")
            ),
            4,
            "story[1].target: ",
        ),
        (
            "start before the one before is formed",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 2.0"),
                entry(duck, "start: 1.5, end: 3.0")
            ),
            4,
            "story[1].start: times must increase",
        ),
        (
            "end not after start",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 1.0"),
                entry(duck, "start: 2.0, end: 2.0")
            ),
            4,
            "story[1].end: times must increase",
        ),
        (
            "end after the shot",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 1.0"),
                entry(duck, "end: 9.0")
            ),
            4,
            "after the shot's last frame",
        ),
        (
            "stagger on the first",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 1.0, stagger: 0.2"),
                entry(duck, "end: 2.0")
            ),
            3,
            "story[0].stagger",
        ),
        (
            "animation on a later one",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 1.0"),
                entry(duck, "end: 2.0, animation: Aggregation(())")
            ),
            4,
            "story[1].animation: a later target is reached by a morph",
        ),
        (
            "a scheme's own hold",
            format!(
                "{},\n    {}",
                entry(
                    cumulus,
                    "end: 1.0, animation: Diffusion((hold_seconds: 1.0))"
                ),
                entry(duck, "end: 2.0")
            ),
            3,
            "story[0].animation.hold_seconds",
        ),
        (
            "a scheme's bad setting",
            format!(
                "{},\n    {}",
                entry(
                    cumulus,
                    "end: 1.0, animation: Diffusion((category_ii: 2.0))"
                ),
                entry(duck, "end: 2.0")
            ),
            3,
            "story[0].animation.category_ii",
        ),
        (
            "bad stagger",
            format!(
                "{},\n    {}",
                entry(cumulus, "end: 1.0"),
                entry(duck, "end: 2.0, stagger: 1.5")
            ),
            4,
            "story[1].stagger",
        ),
    ];
    for (what, entries, line, needle) in cases {
        let path = dir.join("bad.ron");
        let text = format!("Scene(\n  story: [\n    {entries},\n  ],\n  shot: (seconds: 4.0),\n)");
        std::fs::write(&path, &text).unwrap();
        let e = scene::load_scene(&path).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("{}:{line}:", path.display())),
            "{what}: {e}\n{text}"
        );
        assert!(e.contains(needle), "{what}: {e} should mention {needle}");
    }
    // A story beside a target, and a scene with neither.
    let path = dir.join("both.ron");
    std::fs::write(
        &path,
        "Scene(\n  target: Model(\"builtin:cumulus\"),\n  story: [(target: Model(\"builtin:cumulus\"), end: 1.0), (target: Fit(mesh: \"builtin:duck\"), end: 2.0)],\n)",
    )
    .unwrap();
    let e = scene::load_scene(&path).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}:2:3: target: ", path.display())),
        "{e}"
    );
    std::fs::write(&path, "Scene(seed: 2)").unwrap();
    let e = scene::load_scene(&path).unwrap_err().to_string();
    assert!(e.contains("target: a scene needs a `target`"), "{e}");
}
