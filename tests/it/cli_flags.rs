//! The renderer's command-line conventions, run through the binary: `--set`/`--size` (the same
//! scene, bits and provenance as the edit in the file), `--threads` (the same bits), `--progress
//! json` (lines a farm manager parses) and `-q`/`-v`.

use std::path::Path;
use std::process::Output;

use crate::cli_support::{nephele_in, run, text};
use crate::temp_support::temp_dir;

/// A two-frame 64×36 shot of the procedural cumulus (nothing to fit).
const SCENE: &str = r#"Scene(
    target: Model("builtin:cumulus"),
    camera: Auto((azimuth_deg: 20.0)),
    shot: (width: 64, height: 36, fps: 2, seconds: 1.0),
    seed: 3,
)
"#;

/// The frames' manifests in `dir`, in frame order (inputs' hashes and the files' hashes).
fn manifests(dir: &Path) -> Vec<serde_json::Value> {
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".manifest.json"))
        .collect();
    names.sort();
    assert!(!names.is_empty(), "no frames in {}", dir.display());
    names
        .iter()
        .map(|p| serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap())
        .collect()
}

/// Render `scene` (written as `s.ron` in `dir`) with `args` into `dir/out`; its manifests.
fn render(dir: &Path, scene: &str, args: &[&str]) -> Vec<serde_json::Value> {
    std::fs::write(dir.join("s.ron"), scene).unwrap();
    run(nephele_in(dir)
        .args(["render", "s.ron", "-o", "out", "-q"])
        .args(args));
    manifests(&dir.join("out"))
}

#[test]
fn set_is_the_same_edit_in_the_file() {
    let tmp = temp_dir("cli-flags-set");
    let (a, b, c) = (tmp.join("a"), tmp.join("b"), tmp.join("c"));
    for d in [&a, &b, &c] {
        std::fs::create_dir_all(d).unwrap();
    }
    let overridden = render(
        &a,
        SCENE,
        &[
            "--set",
            "cloud.density=30",
            "--size",
            "80x40",
            "--set",
            "camera.fov_deg=25",
        ],
    );
    let edited = SCENE
        .replace("width: 64, height: 36", "width: 80, height: 40")
        .replace("azimuth_deg: 20.0", "azimuth_deg: 20.0, fov_deg: 25.0")
        .replace("seed: 3,", "seed: 3,\n    cloud: (density: 30.0),");
    let in_file = render(&b, &edited, &[]);
    let plain = render(&c, SCENE, &[]);
    // Same inputs' hashes and the same bytes (the files' blake3) as the edit in the file.
    assert_eq!(overridden, in_file);
    assert_eq!(overridden.len(), 2);
    // And not the scene without them: the provenance sees the overrides.
    for (o, p) in overridden.iter().zip(&plain) {
        for part in ["image", "camera", "look"] {
            assert_ne!(o["inputs"][part], p["inputs"][part], "{part}");
        }
        assert_eq!(o["inputs"]["light"], p["inputs"]["light"]);
        assert_ne!(o["files"], p["files"]);
    }
    // Rendering the overridden shot again finds its frames up to date (the same hash).
    let again = nephele_in(&a)
        .args(["render", "s.ron", "-o", "out", "--set", "cloud.density=30"])
        .args(["--size", "80x40", "--set", "camera.fov_deg=25"])
        .output()
        .unwrap();
    let t = text(&again);
    assert!(again.status.success(), "{t}");
    assert!(t.contains("0 frames rendered, 2 already done"), "{t}");
}

/// Exit code and text of `render s.ron ARGS` in a fresh folder; asserts no output folder.
fn refused(args: &[&str]) -> (Option<i32>, String) {
    let tmp = temp_dir("cli-flags-bad");
    std::fs::write(tmp.join("s.ron"), SCENE).unwrap();
    let o: Output = nephele_in(&tmp)
        .args(["render", "s.ron", "-o", "out"])
        .args(args)
        .output()
        .unwrap();
    assert!(
        !tmp.join("out").exists(),
        "{args:?} left an output folder: {}",
        text(&o)
    );
    (o.status.code(), text(&o))
}

#[test]
fn a_bad_override_is_refused_with_its_place_and_no_file() {
    let (code, t) = refused(&["--set", "shot.width=abc"]);
    assert_eq!(code, Some(1), "{t}");
    assert!(
        t.contains("error: --set shot.width=abc: shot.width: expected an integer, got abc"),
        "{t}"
    );
    let (code, t) = refused(&["--set", "shot.widht=100"]);
    assert_eq!(code, Some(1), "{t}");
    assert!(
        t.contains("no field named `widht` in shot; nearest: width"),
        "{t}"
    );
    let (code, t) = refused(&["--set", "clouds.density=30"]);
    assert_eq!(code, Some(1), "{t}");
    assert!(t.contains("nearest: cloud"), "{t}");
    // A value the scene refuses: the scene's message, said of the override.
    let (code, t) = refused(&["--size", "64x36", "--set", "cloud.albedo=2"]);
    assert_eq!(code, Some(1), "{t}");
    assert!(
        t.contains("error: --set cloud.albedo=2: cloud.albedo:"),
        "{t}"
    );
    let (code, t) = refused(&["--set", "sun.intensity=-1"]);
    assert_eq!(code, Some(1), "{t}");
    assert!(
        t.contains("error: --set sun.intensity=-1: sun.intensity:"),
        "{t}"
    );
    // Not one value, or not a size: refused as a usage error.
    let (code, t) = refused(&["--set", "shot.width=1), seed: (3"]);
    assert_eq!(code, Some(2), "{t}");
    assert!(t.contains("unbalanced"), "{t}");
    let (code, t) = refused(&["--size", "64"]);
    assert_eq!(code, Some(2), "{t}");
    let (code, t) = refused(&["--threads", "5000"]);
    assert_eq!(code, Some(1), "{t}");
    assert!(t.contains("at most 1024"), "{t}");
}

#[test]
fn one_thread_renders_the_same_bits() {
    let tmp = temp_dir("cli-flags-threads");
    let (a, b) = (tmp.join("a"), tmp.join("b"));
    for d in [&a, &b] {
        std::fs::create_dir_all(d).unwrap();
    }
    let all = render(&a, SCENE, &[]);
    let one = render(&b, SCENE, &["--threads", "1"]);
    assert_eq!(all, one);
    let v = nephele_in(&b)
        .args(["render", "s.ron", "-o", "out", "-j", "1", "-v"])
        .output()
        .unwrap();
    let t = text(&v);
    assert!(t.contains("worker threads: 1\n"), "{t}");
    // Verbose: the skipped frames too.
    assert!(t.contains("frame    2/2: up to date, skipped"), "{t}");
}

/// The JSON lines of `out`'s stdout (every line one object), checked against the schema.
fn progress_lines(out: &Output) -> Vec<serde_json::Value> {
    let stdout = String::from_utf8(out.stdout.clone()).unwrap();
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l:?}: {e}")))
        .collect();
    let mut last = 0.0;
    for l in &lines {
        for key in [
            "stage", "frame", "percent", "elapsed", "eta", "done", "total",
        ] {
            assert!(l.get(key).is_some(), "{l} has no {key}");
        }
        let p = l["percent"].as_f64().unwrap();
        assert!(
            (last..=100.0).contains(&p),
            "percent went from {last} to {p}"
        );
        last = p;
        assert!(l["elapsed"].as_f64().unwrap() >= 0.0);
    }
    lines
}

#[test]
fn progress_json_is_one_object_a_line_up_to_100_percent() {
    let tmp = temp_dir("cli-flags-progress");
    std::fs::write(tmp.join("s.ron"), SCENE).unwrap();
    let out = nephele_in(&tmp)
        .args(["render", "s.ron", "-o", "out", "--progress", "json", "-q"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    assert!(out.stderr.is_empty(), "-q: {}", text(&out));
    let lines = progress_lines(&out);
    let stages: Vec<&str> = lines.iter().map(|l| l["stage"].as_str().unwrap()).collect();
    assert_eq!(stages, ["start", "frame", "frame", "done"]);
    let frames: Vec<u64> = lines[1..3]
        .iter()
        .map(|l| l["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(frames, [1, 2]);
    assert_eq!(lines[2]["percent"], 100.0);
    assert_eq!(lines[3]["percent"], 100.0);
    assert_eq!(lines[2]["eta"], 0.0);
    assert_eq!(lines[1]["skipped"], false);
    assert!(lines[1]["seconds"].as_f64().unwrap() > 0.0);

    // The turntable preview: its frames at the size asked for, and its progress.
    let out = nephele_in(&tmp)
        .args([
            "preview",
            "builtin:sphere",
            "--blobs",
            "12",
            "-o",
            "tt",
            "--frames",
            "2",
        ])
        .args(["--size", "40x24", "-j", "1", "--progress", "json", "-q"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    assert!(out.stderr.is_empty(), "-q: {}", text(&out));
    let lines = progress_lines(&out);
    assert_eq!(lines.last().unwrap()["percent"], 100.0);
    assert_eq!(lines.len(), 4);
    let png = image::open(tmp.join("tt/turntable_0002.png")).unwrap();
    assert_eq!((png.width(), png.height()), (40, 24));

    // prepare: its stages.
    let out = nephele_in(&tmp)
        .args(["prepare", "s.ron", "-o", "out2", "--size", "80x40"])
        .args(["--progress", "json", "-q"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let stages: Vec<String> = progress_lines(&out)
        .iter()
        .map(|l| l["stage"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(stages, ["prepare", "done"]);

    // A failure: the last line says why, as stderr does, and the exit status is 1.
    std::fs::write(tmp.join("bad.ron"), SCENE.replace("seed", "sede")).unwrap();
    let out = nephele_in(&tmp)
        .args(["render", "bad.ron", "-o", "out3", "--progress", "json"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let stdout = String::from_utf8(out.stdout.clone()).unwrap();
    let last: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    assert_eq!(last["stage"], "error");
    let message = last["message"].as_str().unwrap();
    assert!(message.contains("bad.ron:"), "{message}");
    let stderr = String::from_utf8(out.stderr.clone()).unwrap();
    assert!(stderr.contains(message), "{stderr}");
    assert!(!tmp.join("out3").exists());
}
