//! Scene files: defaults, syntax forms, located errors for malformed scenes, and the
//! `nephele render` command's exit status; rendering (pinned frame hashes, resume) once the
//! renderer is in.

use crate::temp_support;

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DQuat, DVec3};
use nephele::animate::Animation;
use nephele::blobby::model_file::MODEL_VERSION;
use nephele::blobby::{Blob, BlobModel, SourceInfo, save_model};
use nephele::decompose::Primitive;
use nephele::file_error::FileError;
use nephele::geometry::Aabb;
use nephele::hash::Fnv1a;
use nephele::scene::{self, CameraSpec, SceneError, Target};
use temp_support::TempDir;

/// A fresh temporary folder for one test.
fn temp_dir(name: &str) -> TempDir {
    temp_support::temp_dir(&format!("scene-{name}"))
}

/// A small "snowman" model: three stacked spheres plus a ring of small blobs.
fn small_model() -> BlobModel {
    let ball = |c: DVec3, r: f64| Blob {
        center: c,
        rotation: DQuat::IDENTITY,
        semi_axes: DVec3::splat(r),
        a: 1.0,
        b: 2.0,
    };
    let mut blobs = vec![
        ball(DVec3::new(0.0, 0.0, 0.0), 0.8),
        ball(DVec3::new(0.0, 1.0, 0.0), 0.6),
        ball(DVec3::new(0.0, 1.8, 0.0), 0.4),
    ];
    for i in 0..21 {
        let a = i as f64 / 21.0 * std::f64::consts::TAU;
        blobs.push(ball(
            DVec3::new(0.9 * a.cos(), 0.3 * (3.0 * a).sin(), 0.9 * a.sin()),
            0.25,
        ));
    }
    BlobModel {
        version: MODEL_VERSION,
        primitive: Primitive::Ellipsoid,
        threshold: 1.0,
        source: SourceInfo {
            mesh: "test:snowman".into(),
            bounds: Aabb {
                min: DVec3::new(-1.2, -0.8, -1.2),
                max: DVec3::new(1.2, 2.2, 1.2),
            },
            vertices: 0,
            faces: 0,
        },
        seed: 1,
        blobs,
    }
}

/// A folder with `model.ron` and a scene file `name` holding `text`.
fn scene_dir(test: &str, name: &str, text: &str) -> (TempDir, PathBuf) {
    let dir = temp_dir(test);
    save_model(&dir.join("model.ron"), &small_model()).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    (dir, path)
}

fn load_err(test: &str, text: &str) -> SceneError {
    let (_dir, path) = scene_dir(test, "bad.ron", text);
    scene::load_scene(&path).unwrap_err()
}

#[test]
fn minimal_scene_takes_the_defaults() {
    let (dir, path) = scene_dir("minimal", "snow.ron", "Scene(target: Model(\"model.ron\"))");
    let s = scene::load_scene(&path).unwrap();
    assert_eq!(s.name, "snow");
    assert_eq!(s.output_dir, Path::new("renders/snow"));
    assert_eq!(s.file.shot.frame_count(), 96);
    assert!(matches!(s.file.animation, Animation::Diffusion(_)));
    assert!(matches!(s.file.camera, CameraSpec::Auto(_)));
    match &s.file.target {
        Some(Target::Model(p)) => assert_eq!(Path::new(p), dir.join("model.ron")),
        t => panic!("{t:?}"),
    }
}

#[test]
fn full_scene_syntax_forms_parse() {
    let text = r#"
        // Every section, in the forms scenes/README.md documents.
        Scene(
            target: Fit(mesh: "builtin:duck", blobs: 120, seed: 3),
            animation: Aggregation((keyframes: 5, speed: (0.1, 0.2), planes: Custom([
                (normal: (0.0, 1.0, 0.0), offset: 0.0),
                (normal: (1.0, 0.0, 0.0)),
            ]), easing: EaseOut)),
            camera: Fixed((position: (0.0, 1.0, 5.0), look_at: (0.0, 0.5, 0.0), orbit_deg: 30.0)),
            sun: (direction: (-1.0, -1.0, 0.0), intensity: 4.0),
            sky: Gradient(zenith: (0.2, 0.4, 0.8), horizon: (0.8, 0.8, 0.9)),
            cloud: (density: 30.0, noise: (octaves: 3)),
            shot: (width: 320, height: 180, fps: 12, seconds: 2.0),
            frames: (2, 10),
            exposure: 0.5,
            output: (dir: "out/x", name: "clip", formats: [Png]),
            seed: 9,
        )"#;
    let (_dir, path) = scene_dir("full", "full.ron", text);
    let s = scene::load_scene(&path).unwrap();
    assert_eq!(s.file.frames, Some((2, 10)));
    assert_eq!(s.file.shot.fps, 12.0);
    assert_eq!(s.name, "clip");
    assert_eq!(s.output_dir, Path::new("out/x"));
    let Animation::Aggregation(a) = &s.file.animation else {
        panic!()
    };
    assert_eq!(a.keyframes, 5);
    // Defaults inside newtype variants.
    let (_d, p) = scene_dir(
        "newtype",
        "n.ron",
        "Scene(target: Model(\"model.ron\"), camera: Auto((azimuth_deg: 10.0)), \
         animation: Diffusion((grow_seconds: 0.3)))",
    );
    let s = scene::load_scene(&p).unwrap();
    let CameraSpec::Auto(c) = s.file.camera else {
        panic!()
    };
    assert_eq!(c.azimuth_deg, 10.0);
    assert_eq!(c.fov_deg, 35.0);
    // Unnamed outer struct and all-default newtypes.
    let (_d, p) = scene_dir(
        "unnamed",
        "u.ron",
        "(target: Model(\"model.ron\"), camera: Auto(()), animation: Aggregation(()))",
    );
    let s = scene::load_scene(&p).unwrap();
    assert_eq!(s.file.camera, CameraSpec::default());
}

/// The error's text starts with `file:line:column:`.
fn assert_located(e: &SceneError, line: usize, needle: &str) {
    let msg = e.to_string();
    let SceneError::File(FileError::Parse { line: l, path, .. }) = e else {
        panic!("not a located parse error: {msg}")
    };
    assert_eq!(*l, line, "{msg}");
    assert!(
        msg.starts_with(&format!("{}:{line}:", path.display())),
        "{msg}"
    );
    assert!(msg.contains(needle), "{msg} should mention {needle}");
}

#[test]
fn unknown_field_is_located() {
    let e = load_err(
        "unknown",
        "Scene(\n  target: Model(\"model.ron\"),\n  shot: (width: 64, colour: 3),\n)",
    );
    assert_located(&e, 3, "colour");
}

#[test]
fn wrong_type_and_negative_resolution_are_located() {
    let e = load_err(
        "wrongtype",
        "Scene(\n  target: Model(\"model.ron\"),\n  seed: \"seven\",\n)",
    );
    assert_located(&e, 3, "");
    let e = load_err(
        "negative",
        "Scene(\n  target: Model(\"model.ron\"),\n\n  shot: (width: -640),\n)",
    );
    assert_located(&e, 4, "");
}

#[test]
fn missing_target_file_names_scene_and_path() {
    let e = load_err("missing", "Scene(target: Model(\"nowhere/horse.ron\"))");
    let msg = e.to_string();
    assert!(matches!(e, SceneError::MissingTarget { .. }), "{msg}");
    assert!(
        msg.contains("bad.ron") && msg.contains("nowhere/horse.ron"),
        "{msg}"
    );
    let e = load_err("missingmesh", "Scene(target: Fit(mesh: \"gone.ply\"))");
    assert!(e.to_string().contains("gone.ply"), "{e}");
}

#[test]
fn out_of_range_values_name_the_field() {
    let cases = [
        ("zero-width", "shot: (width: 0)", "shot"),
        ("zero-fps", "shot: (fps: 0.0)", "shot.fps"),
        ("tiny-fps", "shot: (fps: 1e-9)", "shot.fps"),
        ("huge-fps", "shot: (fps: 1e6)", "shot.fps"),
        ("neg-seconds", "shot: (seconds: -1.0)", "shot.seconds"),
        ("empty-range", "frames: (5, 2)", "frames"),
        ("past-end", "frames: (1, 500)", "frames"),
        ("nan", "exposure: NaN", "exposure"),
        (
            "nan-sun",
            "sun: (direction: (0.0, NaN, 0.0))",
            "sun.direction",
        ),
        ("fov", "camera: Auto((fov_deg: 0.0))", "camera.fov_deg"),
        (
            "speed",
            "animation: Aggregation((speed: (2.0, 1.0)))",
            "animation.speed",
        ),
        ("formats", "output: (formats: [])", "output.formats"),
        // The shot's frame would need about 1 TB: refused before any work, with the size.
        ("huge", "shot: (width: 100000, height: 100000)", "shot"),
        ("sun-low", "sun: (elevation_deg: -5.0)", "sun.elevation_deg"),
        (
            "sun-high",
            "sun: (elevation_deg: 95.0)",
            "sun.elevation_deg",
        ),
        ("neg-density", "cloud: (density: -1.0)", "cloud.density"),
        (
            "neg-noise",
            "cloud: (noise: (frequency: -2.0))",
            "cloud.noise.frequency",
        ),
        (
            "base-high",
            "cloud: (base: Some((height: 1.5, softness: 0.1)))",
            "cloud.base.height",
        ),
        (
            "base-soft",
            "cloud: (base: Some((height: 0.2, softness: -0.1)))",
            "cloud.base.softness",
        ),
        (
            "turbidity",
            "sky: HosekWilkie(turbidity: 0.5, ground_albedo: 0.3)",
            "sky.turbidity",
        ),
    ];
    for (name, field_text, field) in cases {
        let text = format!("Scene(target: Model(\"model.ron\"), {field_text})");
        let e = load_err(name, &text);
        let msg = e.to_string();
        // Located like a parse error: the line and column of the field's own name.
        match &e {
            SceneError::InvalidAt {
                field: f,
                line,
                column,
                ..
            } => {
                assert_eq!(f, field, "{msg}");
                let at: String = text
                    .lines()
                    .nth(line - 1)
                    .unwrap_or("")
                    .chars()
                    .skip(column - 1)
                    .collect();
                let last = field.rsplit('.').next().unwrap();
                assert!(
                    at.starts_with(&format!("{last}:")),
                    "{name}: {msg} points at {at:?}"
                );
            }
            other => panic!("{name}: expected a located validation error, got {other}"),
        }
        assert!(msg.contains("bad.ron"), "{msg}");
        if name == "huge" {
            assert!(msg.contains("700.3 GB"), "{msg}");
        }
    }
}

fn nephele() -> Command {
    Command::new(env!("CARGO_BIN_EXE_nephele"))
}

#[test]
fn cli_rejects_malformed_scenes_with_nonzero_exit() {
    let (dir, path) = scene_dir(
        "cli-bad",
        "bad.ron",
        "Scene(\n  target: Model(\"model.ron\"),\n  animaton: Diffusion(()),\n)",
    );
    let out = nephele()
        .arg("render")
        .arg(&path)
        .arg("--output")
        .arg(dir.join("out"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.ron:3:"), "{err}");
    assert!(!dir.join("out").exists(), "nothing written for a bad scene");
    // A missing scene file and a bad --frames value fail too.
    let out = nephele()
        .args(["render", "no-such-scene.ron"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let (_d, ok) = scene_dir(
        "cli-frames",
        "ok.ron",
        "Scene(target: Model(\"model.ron\"))",
    );
    let out = nephele()
        .arg("render")
        .arg(&ok)
        .args(["--frames", "5..2"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("frames"));
}

#[test]
fn shipped_scenes_load() {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes"));
    let shared = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/models"));
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "ron") {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        if text.contains("shared/models") && !shared.exists() {
            eprintln!("skipping {}: ../shared/models is absent", path.display());
            continue;
        }
        scene::load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        n += 1;
    }
    assert!(n >= 3, "at least the builtin scenes load");
}

// ---- Rendering. Pinned hashes are of the renderer at branch `render` ea4fdc9: a change to the
// renderer's look changes them (update them then, after looking at the frames). ----

/// A tiny shot of the small model with the given animation.
fn tiny_scene(test: &str, animation: &str) -> (TempDir, PathBuf) {
    scene_dir(
        test,
        "tiny.ron",
        &format!(
            "Scene(target: Model(\"model.ron\"), animation: {animation}, \
             shot: (width: 64, height: 36, fps: 12, seconds: 1.0), seed: 5)"
        ),
    )
}

/// FNV-1a of a frame's RGB and alpha bits.
fn frame_hash(f: &nephele::render::Frame) -> u64 {
    let mut h = Fnv1a::new();
    let words = f
        .rgb
        .iter()
        .flat_map(|p| p.iter().copied())
        .chain(f.alpha.iter().copied());
    for w in words {
        h.write(&w.to_bits().to_le_bytes());
    }
    h.finish()
}

fn render_tiny(test: &str, animation: &str, k: u32) -> nephele::render::Frame {
    let (dir, path) = tiny_scene(test, animation);
    let opts = scene::RenderOptions {
        output: Some(dir.to_path_buf()),
        ..scene::RenderOptions::default()
    };
    let shot = scene::Shot::open(scene::load_scene(&path).unwrap(), &opts).unwrap();
    shot.render_frame(k).unwrap()
}

/// The seeded frames' pinned hashes: (test, animation, FNV-1a of the frame's bits).
const PINNED_FRAMES: [(&str, &str, u64); 2] = [
    ("hash-agg", "Aggregation(())", 14865161002833518730u64),
    ("hash-dif", "Diffusion(())", 10158717632434718009u64),
];

/// Every render version with the fingerprint of [`pinned_hashes`] it was pinned with, oldest
/// first. When a change moves the pinned hashes, raise `nephele::RENDER_VERSION` and append a
/// row here (resumed shots then re-render frames of the older renderer). Rows 1 and 2 were
/// taken over [`PINNED_FRAMES`] alone; from 3 on the renderer test's hash is in (the same
/// pixels as version 3's first row, `0x46c5_c82e_8f00_9e6e`).
const RENDER_VERSIONS: [(u32, u64); 8] = [
    (1, 0x8bed_76dd_4500_a4c5),
    (2, 0x817d_116f_269f_e5e4),
    (3, 0x0fc4_7ef2_d7b6_9892),
    // The fluence grid's multiple scattering at `Final` (and `render::FLUENCE_PINNED` in).
    (4, 0xe98f_1a9f_e1b0_0bbf),
    // Sunlight scattered once closed about its own flux (issue 53); the sky depths shifted one
    // light-grid cell toward the light, not two (issue 50).
    (5, 0xe7be_8957_9304_f150),
    // The sky depths stored as cube roots, not shifted (issue 50); the fluence lookup weighing
    // each node by `1 + σ/σ_max` (issue 53).
    (6, 0xd539_9e36_96e2_c0a9),
    // The forward cone: once-scattered sunlight within 20° of the sun from the march's sun
    // depth (issue 53).
    (7, 0x0557_6542_ea95_8074),
    // The sun's sub-cell detail on the fluence grid's orders ≥ 2 (issue 53).
    (8, 0x4a80_8c8e_60b8_cd78),
];

/// Every pinned hash of a seeded frame: [`PINNED_FRAMES`]' and the renderer test's
/// (`render::PINNED`, the test cloud at 64×36).
fn pinned_hashes() -> impl Iterator<Item = u64> {
    PINNED_FRAMES
        .iter()
        .map(|&(_, _, pinned)| pinned)
        .chain([crate::render::PINNED, crate::render::FLUENCE_PINNED])
}

/// FNV-1a over the pinned hashes.
fn pinned_fingerprint() -> u64 {
    let mut h = Fnv1a::new();
    for pinned in pinned_hashes() {
        h.write_u64(pinned);
    }
    h.finish()
}

#[test]
fn pinned_hashes_move_only_with_the_render_version() {
    let (version, fingerprint) = *RENDER_VERSIONS.last().unwrap();
    assert_eq!(
        pinned_fingerprint(),
        fingerprint,
        "the pinned frame hashes changed: raise nephele::RENDER_VERSION to {} and append \
         ({}, {:#x}) to RENDER_VERSIONS",
        version + 1,
        version + 1,
        pinned_fingerprint()
    );
    assert_eq!(
        nephele::RENDER_VERSION,
        version,
        "RENDER_VERSIONS' last row"
    );
    for w in RENDER_VERSIONS.windows(2) {
        assert!(w[0].0 < w[1].0, "render versions only go up");
    }
    let mut seen: Vec<u64> = RENDER_VERSIONS.iter().map(|r| r.1).collect();
    seen.sort();
    seen.dedup();
    assert_eq!(
        seen.len(),
        RENDER_VERSIONS.len(),
        "a version per pinned state"
    );
}

#[test]
fn seeded_frames_have_pinned_hashes() {
    for (name, anim, pinned) in PINNED_FRAMES {
        let a = render_tiny(name, anim, 4);
        let b = render_tiny(name, anim, 4);
        assert_eq!((a.width, a.height), (64, 36));
        assert!(
            a.alpha.iter().any(|&x| x > 0.05),
            "{name}: some cloud is visible"
        );
        assert_eq!(frame_hash(&a), frame_hash(&b), "{name}: deterministic");
        assert_eq!(frame_hash(&a), pinned, "{name}: pinned hash");
    }
}

fn run_render(scene: &Path, out: &Path, extra: &[&str]) -> String {
    let o = nephele()
        .arg("render")
        .arg(scene)
        .arg("--output")
        .arg(out)
        .args(extra)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

/// A diffusion's blend path is left beside the target by the render that made it and read by
/// the next; a damaged cache file is ignored. The frames are the same bits every way.
#[test]
fn the_blend_path_cache_changes_no_frame() {
    let (dir, path) = tiny_scene("blend-cache", "Diffusion(())");
    let out = dir.join("out");
    let frames = |out: &std::path::Path| -> Vec<Vec<u8>> {
        (1..=12)
            .map(|f| std::fs::read(out.join(format!("tiny_{f:04}.png"))).unwrap())
            .collect()
    };
    let cached = || -> Vec<std::path::PathBuf> {
        std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                p.file_name()
                    .unwrap()
                    .to_string_lossy()
                    .starts_with("blend-")
            })
            .collect()
    };
    run_render(&path, &out, &[]);
    let made = frames(&out);
    let cache = cached();
    assert_eq!(cache.len(), 1, "one blend path cached: {cache:?}");
    let knots: Vec<[f64; 3]> = ron::from_str(&std::fs::read_to_string(&cache[0]).unwrap()).unwrap();
    assert!(knots.len() >= 2 && knots[0] == [0.0; 3], "{knots:?}");
    // Read back from the cache.
    run_render(&path, &out, &["--force"]);
    assert_eq!(frames(&out), made, "with the cached path");
    // A damaged cache is ignored, and replaced.
    std::fs::write(&cache[0], "[(0.0, 0.0").unwrap();
    run_render(&path, &out, &["--force"]);
    assert_eq!(frames(&out), made, "with a damaged cache file");
    let repaired: Vec<[f64; 3]> =
        ron::from_str(&std::fs::read_to_string(&cache[0]).unwrap()).unwrap();
    assert_eq!(repaired, knots);
    // No cache: made again, and cached again.
    std::fs::remove_file(&cache[0]).unwrap();
    run_render(&path, &out, &["--force"]);
    assert_eq!(frames(&out), made, "made anew");
    assert_eq!(cached().len(), 1);
}

#[test]
fn cli_resumes_and_force_rerenders() {
    let (dir, path) = tiny_scene("resume", "Diffusion(())");
    let out = dir.join("out");
    let err = run_render(&path, &out, &["--frames", "1..2", "--dump-blobs"]);
    assert!(err.contains("2 frames rendered, 0 already done"), "{err}");
    for f in [
        "tiny_0001.exr",
        "tiny_0001.png",
        "tiny_0002.png",
        "tiny_0002.blobs.ron",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    assert!(!out.join("tiny_0003.png").exists());
    // The blob dump is the frame's full blob list.
    let text = std::fs::read_to_string(out.join("tiny_0001.blobs.ron")).unwrap();
    let blobs: Vec<Blob> = ron::from_str(&text).unwrap();
    assert_eq!(blobs.len(), small_model().blobs.len());
    // Second run: nothing to do; deleting one file re-renders just that frame.
    let err = run_render(&path, &out, &["--frames", "1..2", "--dump-blobs"]);
    assert!(err.contains("0 frames rendered, 2 already done"), "{err}");
    std::fs::remove_file(out.join("tiny_0002.exr")).unwrap();
    let err = run_render(&path, &out, &["--frames", "1..2", "--dump-blobs"]);
    assert!(err.contains("1 frames rendered, 1 already done"), "{err}");
    let err = run_render(&path, &out, &["--frames", "1..2", "--force"]);
    assert!(err.contains("2 frames rendered, 0 already done"), "{err}");
    // No temporary files are left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    // Preview: a quarter of the width but at least 64 px, in preview/.
    run_render(&path, &out, &["--frames", "12", "--preview"]);
    let png = out.join("preview/tiny_0012.png");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (64, 36));
}

#[test]
fn run_until_stops_after_a_frame_with_its_files_and_resumes() {
    use std::ops::ControlFlow;
    let (dir, path) = tiny_scene("run-until", "Diffusion(())");
    let out = dir.join("out");
    let opts = scene::RenderOptions {
        frames: Some("1..3".parse().unwrap()),
        output: Some(out.clone()),
        ..scene::RenderOptions::default()
    };
    let shot = scene::Shot::open(scene::load_scene(&path).unwrap(), &opts).unwrap();
    let mut seen = Vec::new();
    let report = shot
        .run_until(&mut |f| {
            seen.push(f.frame);
            if f.frame == 2 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
    assert_eq!(seen, [1, 2]);
    assert_eq!((report.rendered, report.skipped), (2, 0));
    // Frame 2 is finished (its manifest is written last), frame 3 not started.
    for f in ["tiny_0001.exr", "tiny_0002.exr", "tiny_0002.manifest.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    assert!(!out.join("tiny_0003.exr").exists());
    let report = shot.run(&mut |_| {}).unwrap();
    assert_eq!((report.rendered, report.skipped), (1, 2));
}

/// Seeded mutation fuzzing of the scene parser (the always-run tier; see fuzz/README.md):
/// byte flips, insertions and truncations of every shipped scene never panic, and every error
/// names the file.
#[test]
fn mutated_scenes_never_panic() {
    use rand::{RngExt, SeedableRng};
    let path = Path::new("mutant.ron");
    let originals: Vec<Vec<u8>> = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .map(|p| std::fs::read(p).unwrap())
        .collect();
    assert!(!originals.is_empty());
    let alphabet = b"(){}[],:\"0123456789.-+eE_abcxyzNaNinf \n/";
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(20261122);
    for round in 0..3000 {
        let mut bytes = originals[round % originals.len()].clone();
        for _ in 0..rng.random_range(1..6) {
            let at = rng.random_range(0..bytes.len().max(1));
            match rng.random_range(0..4) {
                0 => bytes.truncate(at),
                1 => bytes.insert(
                    at.min(bytes.len()),
                    alphabet[rng.random_range(0..alphabet.len())],
                ),
                2 if at < bytes.len() => bytes[at] = rng.random::<u8>(),
                _ if at < bytes.len() => {
                    bytes.remove(at);
                }
                _ => {}
            }
        }
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let result = std::panic::catch_unwind(|| nephele::scene::scene_from_str(path, &text));
        match result {
            Err(_) => panic!("round {round}: the parser panicked on:\n{text}"),
            Ok(Err(e)) => assert!(e.to_string().contains("mutant.ron"), "round {round}: {e}"),
            Ok(Ok(_)) => {}
        }
    }
}

// ---- Target transform, camera keyframes, morph sources: bad input is located. ----

#[test]
fn bad_transforms_keyframes_and_morph_sources_are_located() {
    let cases = [
        (
            "scale-zero",
            "Scene(\n  target: Model(\"model.ron\"),\n  transform: (scale: 0.0),\n)",
            3,
            "scale",
        ),
        (
            "scale-neg",
            "Scene(\n  target: Model(\"model.ron\"),\n  transform: (up: Z, scale: -2.0),\n)",
            3,
            "scale",
        ),
        (
            "scale-nan",
            "Scene(\n  target: Model(\"model.ron\"),\n  transform: (scale: NaN),\n)",
            3,
            "scale",
        ),
        (
            "rot-inf",
            "Scene(\n  target: Model(\"model.ron\"),\n  transform: (rotate_deg: (0.0, inf, 0.0)),\n)",
            3,
            "rotate_deg",
        ),
        (
            "up",
            "Scene(\n  target: Model(\"model.ron\"),\n  transform: (up: W),\n)",
            3,
            "W",
        ),
        (
            "keys-order",
            "Scene(\n  target: Model(\"model.ron\"),\n  camera: Keyframes([\n    (time: 1.0, position: (0.0, 0.0, 5.0), look_at: (0.0, 0.0, 0.0)),\n    (time: 0.5, position: (1.0, 0.0, 5.0), look_at: (0.0, 0.0, 0.0)),\n  ]),\n)",
            6,
            "increase",
        ),
        (
            "keys-one",
            "Scene(\n  target: Model(\"model.ron\"),\n  camera: Keyframes([(time: 0.0, position: (0.0, 0.0, 5.0), look_at: (0.0, 0.0, 0.0))]),\n)",
            3,
            "two",
        ),
        (
            "morph-from",
            "Scene(\n  target: Model(\"model.ron\"),\n  animation: Morph((\n    from: Model(\"missing/cloud.ron\"),\n  )),\n)",
            4,
            "missing/cloud.ron",
        ),
    ];
    for (name, text, line, needle) in cases {
        let e = load_err(name, text);
        assert_located(&e, line, needle);
    }
    // An unknown builtin model is named.
    let (dir, path) = scene_dir(
        "builtin-model",
        "s.ron",
        "Scene(target: Model(\"builtin:cirrus\"))",
    );
    let s = scene::load_scene(&path).unwrap();
    let e = scene::load_target(&s, &dir).unwrap_err().to_string();
    assert!(
        e.contains("builtin:cirrus") && e.contains("builtin:cumulus"),
        "{e}"
    );
}

#[test]
fn transform_keyframes_and_morph_parse_and_apply() {
    let (dir, path) = scene_dir(
        "new-fields",
        "s.ron",
        "Scene(\n  target: Model(\"model.ron\"),\n  transform: (up: NegZ, rotate_deg: (0.0, 90.0, 0.0), scale: 2.0, translate: (1.0, 0.0, 0.0)),\n  animation: Morph((from: Model(\"builtin:cumulus\"), stagger: 0.3)),\n  camera: Keyframes([\n    (time: 0.0, position: (0.0, 1.0, 6.0), look_at: (0.0, 1.0, 0.0), fov_deg: 30.0),\n    (time: 2.0, position: (6.0, 1.0, 0.0), look_at: (0.0, 1.0, 0.0)),\n  ]),\n  shot: (width: 64, height: 36, fps: 12, seconds: 1.0),\n)",
    );
    let s = scene::load_scene(&path).unwrap();
    assert!(matches!(s.file.animation, Animation::Morph(_)));
    let (model, _) = scene::load_target(&s, &dir).unwrap();
    let opts = scene::RenderOptions {
        output: Some(dir.to_path_buf()),
        ..scene::RenderOptions::default()
    };
    let shot = scene::Shot::open(s, &opts).unwrap();
    let prep = shot.prepared().unwrap();
    // Twice the size (blob bounds scale with the transform).
    let before = nephele::animate::blob_bounds(&model.blobs).diagonal();
    assert!((prep.bounds.diagonal() - 2.0 * before).abs() < 1e-9 * before);
    let last = prep.plan.frame(11);
    assert!(last.len() >= model.blobs.len());
}

#[test]
fn cli_stats_writes_one_csv_row_per_frame() {
    let (dir, path) = tiny_scene("stats-csv", "Diffusion(())");
    let out = dir.join("out");
    run_render(&path, &out, &["--stats"]);
    let csv = std::fs::read_to_string(out.join("tiny_stats.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        "frame,time_s,visible_blobs,volume_fraction,components_3d,largest_3d,coverage,components_2d,largest_2d"
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 12);
    let last: Vec<&str> = rows[11].split(',').collect();
    assert_eq!(last[0], "12");
    assert_eq!(last[3], "1.00000", "the last frame is the final volume");
}

/// A Nuke `.chan` camera drives the shot's frames by frame number: its positions, its
/// rotations in the asked order and its vertical angle of view; a frame without a line, or a bad
/// line, is a located error naming the `.chan` file; an edited line re-renders its frame only.
#[test]
fn a_chan_camera_drives_the_shot_by_frame_number() {
    use glam::Vec3;
    let dir = temp_dir("chan");
    let chan = dir.join("cam.chan");
    // Frames 1001..1004 (a 1001-based shot of 4 frames at 4 fps): moving along +X, panned
    // 90° left at 1003 (so looking down −X), the angle of view from the file or the default.
    std::fs::write(
        &chan,
        "# frame tx ty tz rx ry rz vfov\n1001 0 0 4 0 0 0 30\n1002 0.5 0 4 0 0 0 30\n\
         1003 1 0 4 0 90 0\n1004 1.5 0 4 10 0 0 40\n",
    )
    .unwrap();
    let scene_text = "Scene(target: Model(\"builtin:cumulus\"),\n  shot: (width: 32, height: 18, fps: 4, \
                      seconds: 1.0, start_frame: 1001),\n  camera: Chan((file: \"cam.chan\", fov_deg: 25.0)),\n  \
                      output: (dir: \"out\", name: \"c\", formats: [Png]))";
    let path = dir.join("c.ron");
    std::fs::write(&path, scene_text).unwrap();
    let scene = scene::load_scene(&path).unwrap();
    let shot = scene::Shot::open(scene, &scene::RenderOptions::default()).unwrap();
    let cam = |k: u32| shot.settings(k).unwrap().camera;
    let close = |a: Vec3, b: Vec3| (a - b).length() < 1e-5;
    assert!(close(cam(0).position, Vec3::new(0.0, 0.0, 4.0)));
    assert!(close(cam(0).look_at - cam(0).position, Vec3::NEG_Z));
    assert_eq!(cam(0).fov_deg, 30.0);
    assert!(close(cam(1).position, Vec3::new(0.5, 0.0, 4.0)));
    assert!(close(cam(2).look_at - cam(2).position, Vec3::NEG_X));
    assert_eq!(
        cam(2).fov_deg,
        25.0,
        "no eighth column: the scene's fov_deg"
    );
    assert_eq!(cam(3).fov_deg, 40.0);
    // A frame without its line, and a bad line: located at `file:` in the scene, naming the
    // .chan file and where in it.
    std::fs::write(
        &chan,
        "1001 0 0 4 0 0 0\n1002 0 0 4 0 0 0\n1004 0 0 4 0 0 0\n",
    )
    .unwrap();
    let e = scene::load_scene(&path).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("{}:3:17: camera.file: ", path.display())),
        "{e}"
    );
    assert!(e.contains("cam.chan: no line for frame 1003"), "{e}");
    std::fs::write(&chan, "1001 0 0 4 0 0\n").unwrap();
    let e = scene::load_scene(&path).unwrap_err().to_string();
    assert!(e.contains("cam.chan:1:1: 6 numbers"), "{e}");
    // Rendered, then one line edited: only that frame is redone, for its camera.
    let lines =
        "1001 0 0 4 0 0 0 30\n1002 0.5 0 4 0 0 0 30\n1003 1 0 4 0 5 0\n1004 1.5 0 4 0 0 0\n";
    std::fs::write(&chan, lines).unwrap();
    let render = || {
        let out = nephele()
            .current_dir(&*dir)
            .args(["render", "c.ron"])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{text}");
        text
    };
    render();
    std::fs::write(&chan, lines.replace("1003 1 0 4 0 5 0", "1003 1 0 4 0 6 0")).unwrap();
    let t = render();
    assert!(t.contains("1 frames rendered, 3 already done"), "{t}");
    assert!(t.contains("changed: camera"), "{t}");
}

// ---- Wind and timing (issue 51): bad input is located. ----

#[test]
fn bad_wind_and_timing_are_located() {
    let cases = [
        (
            "wind-inf",
            "Scene(\n  target: Model(\"model.ron\"),\n  wind: (velocity: (1.0, inf, 0.0)),\n)",
            3,
            "wind.velocity",
        ),
        (
            "wind-nan",
            "Scene(\n  target: Model(\"model.ron\"),\n  wind: (velocity: (NaN, 0.0, 0.0)),\n)",
            3,
            "finite",
        ),
        (
            "wind-field",
            "Scene(\n  target: Model(\"model.ron\"),\n  wind: (speed: 2.0),\n)",
            3,
            "speed",
        ),
        (
            "timing-order",
            "Scene(\n  target: Model(\"model.ron\"),\n  timing: [\n    (time: 1.0, progress: 0.0),\n    (time: 1.0, progress: 1.0),\n  ],\n)",
            6,
            "timing key 1: times must increase",
        ),
        (
            "timing-one",
            "Scene(\n  target: Model(\"model.ron\"),\n  timing: [(time: 0.0, progress: 0.0)],\n)",
            3,
            "at least two keys",
        ),
        (
            "timing-nan",
            "Scene(\n  target: Model(\"model.ron\"),\n  timing: [(time: 0.0, progress: 0.0), (time: NaN, progress: 1.0)],\n)",
            3,
            "finite",
        ),
        (
            "timing-range",
            "Scene(\n  target: Model(\"model.ron\"),\n  timing: [(time: 0.0, progress: 0.0), (time: 2.0, progress: 1.5)],\n)",
            3,
            "[0, 1]",
        ),
        (
            "timing-ease",
            "Scene(\n  target: Model(\"model.ron\"),\n  timing: [(time: 0.0, progress: 0.0), (time: 2.0, progress: 1.0, ease: Bouncy)],\n)",
            3,
            "Bouncy",
        ),
    ];
    for (name, text, line, needle) in cases {
        let e = load_err(name, text);
        assert_located(&e, line, needle);
    }
    // A wind is optional; one written parses.
    let (_d, p) = scene_dir(
        "wind-ok",
        "w.ron",
        "Scene(target: Model(\"model.ron\"), wind: (velocity: (0.5, 0.0, -0.25)))",
    );
    let s = scene::load_scene(&p).unwrap();
    assert_eq!(
        s.file.wind.map(|w| w.velocity),
        Some(glam::DVec3::new(0.5, 0.0, -0.25))
    );
    assert!(s.file.timing.is_none());
    let (_d, p) = scene_dir(
        "timing-ok",
        "t.ron",
        "Scene(target: Model(\"model.ron\"), timing: [(time: 0.0, progress: 0.0), \
         (time: 1.0, progress: 0.5, ease: Smooth), (time: 2.0, progress: 0.2)])",
    );
    let s = scene::load_scene(&p).unwrap();
    let keys = s.file.timing.unwrap();
    assert_eq!(keys.keys().len(), 3);
    assert_eq!(keys.keys()[1].ease, nephele::animate::Ease::Smooth);
    assert_eq!(keys.keys()[2].ease, nephele::animate::Ease::Linear);
}
