//! Frames a compositor and a pipeline can use (issue 23): frame provenance and the resume rule,
//! frame numbers from `shot.start_frame` end to end (files, `--frames` lists, EXR, USD, farm
//! chunks, stats), colour metadata and ACEScg, and bad input refused with located errors. The
//! EXR headers are read with the `exr` crate and, where installed, with OpenImageIO's
//! `oiiotool --info -v` (Debian `openimageio-tools`; the check says it skipped when absent, or
//! fails under `NEPHELE_REQUIRE_READERS=1`: `readers_support`).
//! Every scene is the procedural `builtin:cumulus` at a few dozen pixels.

use crate::cli_support;
use crate::exr_support;
use crate::readers_support::skip_or_fail;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use cli_support::{nephele_in as nephele, run, text};

use exr::meta::attribute::{AttributeValue, Text};

fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nephele-frames-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Run `c`, assert it failed with exit code 1, return its output text.
fn fails(c: &mut Command) -> String {
    let o = c.output().unwrap();
    let t = text(&o);
    assert_eq!(o.status.code(), Some(1), "{t}");
    assert!(!t.contains("panicked"), "{t}");
    t
}

/// A cumulus shot (`extra` adds scene fields; the frames go to `dir/out` unless it gives an
/// `output`) in `dir/NAME.ron`.
fn write_scene(dir: &Path, name: &str, shot: &str, extra: &str) {
    let output = if extra.contains("output:") {
        ""
    } else {
        "output: (dir: \"out\"), "
    };
    std::fs::write(
        dir.join(format!("{name}.ron")),
        format!(
            "Scene(target: Model(\"builtin:cumulus\"), shot: ({shot}), {output}seed: 3, {extra})"
        ),
    )
    .unwrap();
}

/// The `nephele/…` and standard text attributes of an EXR.
fn text_attr(path: &Path, key: &str) -> String {
    let layer = exr_support::read_first_layer(path);
    match layer.attributes.other.get(&Text::new_or_panic(key)) {
        Some(AttributeValue::Text(t)) => t.to_string(),
        other => panic!("{}: {key}: {other:?}", path.display()),
    }
}

/// `oiiotool --info -v PATH`, or `None` (after [`skip_or_fail`]) when OpenImageIO is not
/// installed.
fn oiiotool_info(path: &Path) -> Option<String> {
    match Command::new("oiiotool")
        .args(["--info", "-v"])
        .arg(path)
        .output()
    {
        Ok(o) if o.status.success() => Some(String::from_utf8_lossy(&o.stdout).into_owned()),
        Ok(o) => panic!("oiiotool failed: {}", text(&o)),
        Err(e) => {
            skip_or_fail(
                "oiiotool",
                &format!("{e} (install Debian openimageio-tools)"),
            );
            None
        }
    }
}

/// Every channel of an EXR by name.
fn channels(path: &Path) -> BTreeMap<String, Vec<f32>> {
    exr_support::read_first_layer(path)
        .channel_data
        .list
        .iter()
        .map(|c| {
            let values = match &c.sample_data {
                exr::prelude::FlatSamples::F32(v) => v.clone(),
                other => panic!("{}: not f32: {other:?}", c.name),
            };
            (c.name.to_string(), values)
        })
        .collect()
}

/// The frame numbers whose manifest is in `dir`, with their files' hashes.
fn manifests(dir: &Path) -> BTreeMap<u32, String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            let name = e.unwrap().file_name().to_string_lossy().into_owned();
            name.ends_with(".manifest.json").then_some(name)
        })
        .map(|name| {
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(dir.join(&name)).unwrap()).unwrap();
            let hashes: Vec<&str> = v["files"]
                .as_array()
                .unwrap()
                .iter()
                .map(|f| f["hash"].as_str().unwrap())
                .collect();
            (v["frame"].as_u64().unwrap() as u32, hashes.join(" "))
        })
        .collect()
}

#[test]
fn a_1001_based_shot_agrees_in_files_exr_usd_farm_chunks_and_stats() {
    let dir = temp_dir("start");
    write_scene(
        &dir,
        "c",
        "width: 48, height: 27, fps: 6, seconds: 2.0, start_frame: 1001",
        "output: (dir: \"out\", padding: 5, formats: [Exr, Png]), frames: (1001, 1012)",
    );
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1001..1002,1012", "--stats"]));
    assert!(t.contains("3 frames rendered, 0 already done"), "{t}");
    let out = dir.join("out");
    for f in ["c_01001", "c_01002", "c_01012"] {
        for ext in ["exr", "png", "manifest.json"] {
            assert!(out.join(format!("{f}.{ext}")).is_file(), "{f}.{ext}: {t}");
        }
    }
    assert!(!out.join("c_01003.exr").exists());
    assert_eq!(text_attr(&out.join("c_01012.exr"), "nephele/frame"), "1012");
    let csv = std::fs::read_to_string(out.join("c_stats.csv")).unwrap();
    let rows: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(rows, ["1001", "1002", "1012"]);
    // The last of 12 frames is 11/6 s into the shot.
    assert!(
        csv.lines().last().unwrap().starts_with("1012,1.8333"),
        "{csv}"
    );

    // USD: time codes are the frame numbers, each pointing at that frame's VDB file name.
    run(nephele(&dir).args(["usd", "c.ron", "-o", "out/c.usda"]));
    let usda = std::fs::read_to_string(out.join("c.usda")).unwrap();
    for line in [
        "startTimeCode = 1001",
        "endTimeCode = 1012",
        "1001: ( (",
        "1012: @./c_01012.vdb@",
    ] {
        assert!(usda.contains(line), "missing {line:?} in\n{usda}");
    }
    assert!(!usda.contains("    1: "), "{usda}");

    // Farm: the chunks are frame numbers, and a task renders its chunk of them.
    let t = run(nephele(&dir).args([
        "farm", "c.ron", "--engine", "slurm", "--chunk", "5", "--output", "out",
    ]));
    assert!(
        t.contains("3 tasks of at most 5 frames (frames 1001..1012)"),
        "{t}"
    );
    let script = std::fs::read_to_string(out.join("c.sbatch")).unwrap();
    assert!(script.contains("'--frames' '1001..1012'"), "{script}");
    assert!(script.contains("#SBATCH --array=0-2"), "{script}");
    let t = run(nephele(&dir).args([
        "render",
        "c.ron",
        "--frames",
        "1001..1012",
        "--task",
        "2/3",
        "--formats",
        "png",
    ]));
    assert!(
        t.contains("task 2/3: frames 1009..1012 of 1001..1012"),
        "{t}"
    );
    assert!(t.contains("frame 1009/1012"), "{t}");
    // A list is cut by position.
    let t = run(nephele(&dir).args([
        "render",
        "c.ron",
        "--frames",
        "1001,1005..1006,1012",
        "--task",
        "1/2",
        "--formats",
        "png",
    ]));
    assert!(
        t.contains("task 1/2: frames 1006,1012 of 1001,1005..1006,1012"),
        "{t}"
    );

    // Frame numbers outside the shot are refused, naming where they came from.
    let t = fails(nephele(&dir).args(["render", "c.ron", "--frames", "1..3"]));
    assert!(
        t.contains("c.ron: --frames: 1..3: need 1001 ≤ first"),
        "{t}"
    );
    write_scene(
        &dir,
        "d",
        "width: 48, height: 27, fps: 6, seconds: 2.0, start_frame: 1001",
        "frames: (1, 3)",
    );
    let t = fails(nephele(&dir).args(["render", "d.ron"]));
    assert!(
        t.contains("d.ron:1:144: frames: need 1001 ≤ first ≤ last ≤ 1012"),
        "{t}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_scene_edit_rerenders_exactly_the_frames_it_changes() {
    let dir = temp_dir("edit");
    // A morph whose source holds still for its first 0.5 s and whose target holds for the
    // last 0.5 s: `stagger` changes only the frames in between.
    let morph = |stagger: f64| {
        format!(
            "animation: Morph((from: Model(\"builtin:cumulus\"), stagger: {stagger}, \
             lead_seconds: 0.5, hold_seconds: 0.5)), transform: (rotate_deg: (0.0, 60.0, 0.0))"
        )
    };
    let shot = "width: 40, height: 24, fps: 6, seconds: 2.0";
    write_scene(&dir, "m", shot, &morph(0.4));
    let out = dir.join("out");
    let t = run(nephele(&dir).args(["render", "m.ron", "--formats", "exr"]));
    assert!(t.contains("12 frames rendered, 0 already done"), "{t}");
    let before = manifests(&out);
    let pixels = |f: u32| channels(&out.join(format!("m_{f:04}.exr")));
    let old: Vec<_> = (1..=12).map(pixels).collect();
    // Unchanged scene: nothing to do.
    let t = run(nephele(&dir).args(["render", "m.ron", "--formats", "exr"]));
    assert!(t.contains("0 frames rendered, 12 already done"), "{t}");

    write_scene(&dir, "m", shot, &morph(0.8));
    let t = run(nephele(&dir).args(["render", "m.ron", "--formats", "exr"]));
    let after = manifests(&out);
    let rerendered: Vec<u32> = (1..=12).filter(|f| before[f] != after[f]).collect();
    let changed: Vec<u32> = (1..=12)
        .filter(|&f| pixels(f) != old[f as usize - 1])
        .collect();
    assert_eq!(rerendered, changed, "{t}");
    let n = changed.len();
    assert!((3..12).contains(&n), "{changed:?}");
    assert!(
        t.contains(&format!("{n} frames rendered, {} already done", 12 - n)),
        "{t}"
    );
    assert!(
        t.contains(&format!(
            "{n} of the rendered frames were out of date: {n} changed: cloud shape (blobs)"
        )),
        "{t}"
    );
    // A lost file or manifest is redone and said; `--force` redoes everything.
    std::fs::remove_file(out.join("m_0001.manifest.json")).unwrap();
    std::fs::remove_file(out.join("m_0012.exr")).unwrap();
    let t = run(nephele(&dir).args(["render", "m.ron", "--formats", "exr"]));
    assert!(t.contains("2 frames rendered, 10 already done"), "{t}");
    assert!(
        t.contains("1 interrupted (files without their manifest)") && t.contains("1 files missing"),
        "{t}"
    );
    let t = run(nephele(&dir).args(["render", "m.ron", "--formats", "exr", "--force"]));
    assert!(t.contains("12 frames rendered, 0 already done"), "{t}");
    assert_eq!(
        manifests(&out),
        after,
        "the same scene gives the same hashes"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_frame_that_cannot_be_written_stops_the_shot_there() {
    // Frames are written on their own thread while the next renders: frame 2's PNG path is
    // taken by a directory, so its write fails; the shot must stop with that path, frame 1
    // finished, frames 2.. without a manifest (and frame 3, rendered meanwhile, not written).
    let dir = temp_dir("unwritable");
    write_scene(&dir, "w", "width: 32, height: 18, fps: 4, seconds: 1.0", "");
    let out = dir.join("out");
    std::fs::create_dir_all(out.join("w_0002.png")).unwrap();
    let t = fails(nephele(&dir).args(["render", "w.ron"]));
    assert!(t.contains("w_0002.png"), "{t}");
    assert_eq!(manifests(&out).into_keys().collect::<Vec<_>>(), [1], "{t}");
    assert!(!out.join("w_0003.exr").exists() && !out.join("w_0003.png").exists());
    // Once the path is free the shot resumes from frame 2.
    std::fs::remove_dir(out.join("w_0002.png")).unwrap();
    let t = run(nephele(&dir).args(["render", "w.ron"]));
    assert!(t.contains("3 frames rendered, 1 already done"), "{t}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exr_frames_carry_colour_and_rate_and_acescg_is_the_exact_conversion() {
    let dir = temp_dir("colour");
    let shot = "width: 40, height: 24, fps: 23.976, seconds: 0.2";
    write_scene(
        &dir,
        "c",
        shot,
        "output: (dir: \"rec\", formats: [Exr, Png])",
    );
    write_scene(
        &dir,
        "a",
        shot,
        "output: (dir: \"aces\", name: \"c\", formats: [Exr, Png], colorspace: ACEScg)",
    );
    run(nephele(&dir).args(["render", "c.ron", "--frames", "3"]));
    run(nephele(&dir).args(["render", "a.ron", "--frames", "3"]));
    let (rec, aces) = (dir.join("rec/c_0003.exr"), dir.join("aces/c_0003.exr"));
    let layer = exr_support::read_first_layer(&rec);
    assert_eq!(layer.attributes.frames_per_second, Some((24000, 1001)));
    let read_chroma = |p: &Path| {
        let img = exr::meta::MetaData::read_from_file(p, false).unwrap();
        let c = img.headers[0].shared_attributes.chromaticities.unwrap();
        [c.red, c.green, c.blue, c.white].map(|v| [v.0, v.1])
    };
    assert_eq!(
        read_chroma(&rec),
        [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06], [0.3127, 0.3290]]
    );
    assert_eq!(
        read_chroma(&aces),
        [
            [0.713, 0.293],
            [0.165, 0.830],
            [0.128, 0.044],
            [0.32168, 0.33767]
        ]
    );
    assert_eq!(text_attr(&aces, "nephele/colorspace"), "ACEScg");
    // ACEScg = M · Rec.709 with the published matrix; alpha and depth untouched; the PNG (sRGB
    // display-referred from the renderer's Rec.709) is the same file.
    let m = [
        [0.613_097_4, 0.339_523_1, 0.047_379_5],
        [0.070_193_7, 0.916_353_9, 0.013_452_4],
        [0.020_615_6, 0.109_569_8, 0.869_814_6],
    ];
    let (r, a) = (channels(&rec), channels(&aces));
    assert_eq!(r["A"], a["A"]);
    assert_eq!(r["Z"], a["Z"]);
    let mut lit = 0;
    for i in 0..r["R"].len() {
        let src = [r["R"][i], r["G"][i], r["B"][i]].map(f64::from);
        for (row, name) in m.iter().zip(["R", "G", "B"]) {
            let want: f64 = row.iter().zip(src).map(|(w, v)| w * v).sum();
            let got = a[name][i] as f64;
            assert!(
                (got - want).abs() <= 1e-5 * want.abs() + 1e-9,
                "{name}[{i}] {got} vs {want}"
            );
        }
        lit += usize::from(src[1] > 0.01);
    }
    assert!(lit > 20, "too few cloud pixels to test ({lit})");
    assert_eq!(
        std::fs::read(dir.join("rec/c_0003.png")).unwrap(),
        std::fs::read(dir.join("aces/c_0003.png")).unwrap()
    );
    // Switching the colour space changes the EXR only: it is redone and says so, the PNG kept.
    std::fs::copy(&rec, &aces).unwrap();
    std::fs::copy(
        dir.join("rec/c_0003.manifest.json"),
        dir.join("aces/c_0003.manifest.json"),
    )
    .unwrap();
    let t = run(nephele(&dir).args(["render", "a.ron", "--frames", "3"]));
    assert!(
        t.contains("1 changed: EXR header (scene, seed, colour space, fps)"),
        "{t}"
    );
    if let Some(info) = oiiotool_info(&aces) {
        for line in [
            "chromaticities: 0.713, 0.293, 0.165, 0.83, 0.128, 0.044, 0.32168, 0.33767",
            "framesPerSecond: 24000/1001",
            "nephele/colorspace: \"ACEScg\"",
            "nephele/frame: \"3\"",
            "nephele/hash: \"",
            "worldToCamera:",
        ] {
            assert!(info.contains(line), "oiiotool: missing {line:?} in\n{info}");
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_is_refused_before_any_work_with_each_cause_once() {
    let dir = temp_dir("bad");
    write_scene(&dir, "huge", "fps: 1000, seconds: 1e9", "");
    let t = fails(nephele(&dir).args(["render", "huge.ron"]));
    assert!(
        t.contains("huge.ron:1:41: shot: ") && t.contains("more than the limit of 1000000"),
        "{t}"
    );
    assert!(!dir.join("out").exists(), "nothing is written");
    for (fields, what) in [
        (
            "output: (padding: 0)",
            "c.ron:1:50: output.padding: must be 1 to 10 digits",
        ),
        (
            "shot: (start_frame: 4294967295)",
            "c.ron:1:48: shot.start_frame: 4294967295 + 96 frames",
        ),
    ] {
        std::fs::write(
            dir.join("c.ron"),
            format!("Scene(target: Model(\"builtin:cumulus\"), {fields})"),
        )
        .unwrap();
        let t = fails(nephele(&dir).args(["render", "c.ron"]));
        assert!(t.contains(what), "{t}");
    }
    std::fs::write(
        dir.join("c.ron"),
        "Scene(\n  target: Model(\"builtin:cumulus\"),\n  output: (colorspace: sRGB),\n)",
    )
    .unwrap();
    let t = fails(nephele(&dir).args(["render", "c.ron"]));
    assert!(t.contains("c.ron:3:"), "{t}");
    // Each cause once: the library's message already holds its source.
    let t = fails(nephele(&dir).args(["fit", "builtin:duk", "-o", "x.ron"]));
    assert_eq!(t.matches("unknown builtin shape 'duk'").count(), 1, "{t}");
    let t = fails(nephele(&dir).args(["render", "missing.ron"]));
    let cause = std::io::Error::from(std::io::ErrorKind::NotFound).to_string();
    assert!(t.matches("No such file").count() == 1, "{t} ({cause})");
    assert!(!dir.join("out").exists(), "nothing is written");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `output.motion_vectors: true`: the EXR gains `forward.u` and `forward.v` (Nuke's forward
/// layer), the beauty keeps its bits, the vectors are 0 where there is no cloud and show the
/// cloud moving where it is; the frame's hash moves only with the setting.
#[test]
fn motion_vectors_are_a_forward_layer_beside_an_unchanged_beauty() {
    let dir = temp_dir("motion");
    let shot = "width: 48, height: 27, fps: 24, seconds: 1.0";
    let flying = "animation: Aggregation((hold_seconds: 0.25)), ";
    write_scene(
        &dir,
        "c",
        shot,
        &format!("{flying}output: (dir: \"plain\", formats: [Exr])"),
    );
    write_scene(
        &dir,
        "m",
        shot,
        &format!(
            "{flying}output: (dir: \"motion\", name: \"c\", formats: [Exr], \
             motion_vectors: true)"
        ),
    );
    run(nephele(&dir).args(["render", "c.ron", "--frames", "12"]));
    run(nephele(&dir).args(["render", "m.ron", "--frames", "12"]));
    // `--motion-vectors` is the same as `output.motion_vectors: true`.
    run(nephele(&dir).args([
        "render",
        "c.ron",
        "--frames",
        "12",
        "--motion-vectors",
        "--output",
        "cli",
    ]));
    let (plain, with) = (dir.join("plain/c_0012.exr"), dir.join("motion/c_0012.exr"));
    let (a, b) = (channels(&plain), channels(&with));
    assert_eq!(channels(&dir.join("cli/c_0012.exr")), b);
    let names: Vec<&str> = b.keys().map(|k| k.as_str()).collect();
    assert_eq!(names, ["A", "B", "G", "R", "Z", "forward.u", "forward.v"]);
    for c in ["R", "G", "B", "A", "Z"] {
        assert_eq!(a[c], b[c], "{c}: the beauty changed with motion vectors");
    }
    let (u, v, alpha) = (&b["forward.u"], &b["forward.v"], &b["A"]);
    let mut moving = 0;
    for i in 0..alpha.len() {
        assert!(u[i].is_finite() && v[i].is_finite());
        if alpha[i] == 0.0 {
            assert_eq!((u[i], v[i]), (0.0, 0.0), "pixel {i} has no cloud");
        } else if alpha[i] > 0.5 && u[i].hypot(v[i]) > 0.05 {
            moving += 1;
        }
    }
    // Frame 12 of 24: the blobs are still flying in.
    let covered = alpha.iter().filter(|&&a| a > 0.5).count();
    let fastest = u
        .iter()
        .zip(v)
        .map(|(a, b)| a.hypot(*b))
        .fold(0.0f32, f32::max);
    eprintln!("{covered} pixels with alpha > 0.5, {moving} moving, fastest {fastest} px a frame");
    assert!(moving > 20, "only {moving} covered pixels move");
    // The plain scene's frame is current (its hash did not take the new setting); the one
    // with vectors is not the plain one's.
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "12"]));
    assert!(t.contains("0 frames rendered"), "{t}");
    if let Some(info) = oiiotool_info(&with) {
        assert!(
            info.contains("channel list: R, G, B, A, Z, forward.u, forward.v"),
            "{info}"
        );
    }
}

#[test]
fn passes_sum_to_the_beauty_which_keeps_its_bits() {
    let dir = temp_dir("passes");
    let shot = "width: 48, height: 27, fps: 6, seconds: 1.0";
    write_scene(&dir, "c", shot, "output: (dir: \"plain\", formats: [Exr])");
    write_scene(
        &dir,
        "p",
        shot,
        "output: (dir: \"passes\", name: \"c\", formats: [Exr], passes: true)",
    );
    run(nephele(&dir).args(["render", "c.ron", "--frames", "6"]));
    run(nephele(&dir).args(["render", "p.ron", "--frames", "6"]));
    // `--passes` is the same as `output.passes: true`.
    let t = run(nephele(&dir).args([
        "render", "c.ron", "--frames", "6", "--passes", "--output", "cli",
    ]));
    assert!(t.contains("1 frames rendered"), "{t}");
    let (plain, with) = (dir.join("plain/c_0006.exr"), dir.join("passes/c_0006.exr"));
    let (a, b) = (channels(&plain), channels(&with));
    assert_eq!(channels(&dir.join("cli/c_0006.exr")), b);
    let names: Vec<&str> = b.keys().map(|k| k.as_str()).collect();
    assert_eq!(
        names,
        [
            "A",
            "B",
            "CryptoObject00.A",
            "CryptoObject00.B",
            "CryptoObject00.G",
            "CryptoObject00.R",
            "CryptoObject01.A",
            "CryptoObject01.B",
            "CryptoObject01.G",
            "CryptoObject01.R",
            "CryptoObject02.A",
            "CryptoObject02.B",
            "CryptoObject02.G",
            "CryptoObject02.R",
            "G",
            "R",
            "Z",
            "multiple.B",
            "multiple.G",
            "multiple.R",
            "sky.B",
            "sky.G",
            "sky.R",
            "sun.B",
            "sun.G",
            "sun.R"
        ]
    );
    for c in ["R", "G", "B", "A", "Z"] {
        assert_eq!(a[c], b[c], "{c}: the beauty changed with passes");
    }
    // The default animation (diffusion) has the paper's categories as mattes (those with
    // blobs: this small cumulus has no category II).
    let (manifest, ranks) = cryptomatte(&with);
    let names: Vec<&str> = manifest.keys().map(|k| k.as_str()).collect();
    assert_eq!(names, ["category_I", "category_III"]);
    let alpha = &b["A"];
    for (i, r) in ranks.iter().enumerate() {
        let sum: f32 = r.iter().map(|&(_, c)| c).sum();
        assert!(
            (sum - alpha[i]).abs() < 1e-5,
            "pixel {i}: {r:?} vs A = {}",
            alpha[i]
        );
    }
    let (mut worst, mut lit) = (0.0f64, 0);
    for c in ["R", "G", "B"] {
        let (sun, sky, ms) = (
            &b[&format!("sun.{c}")],
            &b[&format!("sky.{c}")],
            &b[&format!("multiple.{c}")],
        );
        for (i, &beauty) in b[c].iter().enumerate() {
            let sum = sun[i] as f64 + sky[i] as f64 + ms[i] as f64;
            let beauty = beauty as f64;
            if beauty > 1e-3 {
                worst = worst.max((sum - beauty).abs() / beauty);
                lit += 1;
            } else {
                assert!((sum - beauty).abs() < 1e-8, "{c}[{i}] {sum} vs {beauty}");
            }
        }
    }
    assert!(lit > 60, "too few cloud pixels ({lit})");
    assert!(
        worst <= 1e-5,
        "pass sum off the beauty by {worst:e} (relative)"
    );
    // Every pass carries light somewhere.
    for layer in ["sun", "sky", "multiple"] {
        let max = b[&format!("{layer}.G")]
            .iter()
            .copied()
            .fold(0.0f32, f32::max);
        assert!(max > 1e-3, "{layer} is black");
    }
    eprintln!(
        "EXR 48×27: {} bytes without passes, {} with; pass sum within {worst:.1e} of the beauty",
        std::fs::metadata(&plain).unwrap().len(),
        std::fs::metadata(&with).unwrap().len()
    );
    if let Some(info) = oiiotool_info(&with) {
        assert!(
            info.contains(
                "channel list: R, G, B, A, Z, CryptoObject00.R, CryptoObject00.G, \
                 CryptoObject00.B, CryptoObject00.A, CryptoObject01.R, CryptoObject01.G, \
                 CryptoObject01.B, CryptoObject01.A, CryptoObject02.R, CryptoObject02.G, \
                 CryptoObject02.B, CryptoObject02.A, multiple.R, multiple.G, multiple.B, sky.R, \
                 sky.G, sky.B, sun.R, sun.G, sun.B"
            ),
            "{info}"
        );
        // OpenImageIO's own sum of the three layers against the beauty.
        let f = with.to_string_lossy().into_owned();
        let o = Command::new("oiiotool")
            .args([
                &f,
                "--ch",
                "sun.R,sun.G,sun.B",
                &f,
                "--ch",
                "sky.R,sky.G,sky.B",
                "--add",
            ])
            .args([&f, "--ch", "multiple.R,multiple.G,multiple.B", "--add"])
            .args([&f, "--ch", "R,G,B", "--fail", "1e-5", "--diff"])
            .output()
            .unwrap();
        let t = text(&o);
        assert!(
            o.status.success() && t.contains("PASS"),
            "oiiotool --diff: {t}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The EXR at `path`: its display window `(origin, size)`, its data window's origin and size,
/// and its channels by name (over the data window, row-major).
#[allow(clippy::type_complexity)]
fn windows_and_channels(
    path: &Path,
) -> (
    ((i32, i32), (usize, usize)),
    ((i32, i32), (usize, usize)),
    BTreeMap<String, Vec<f32>>,
) {
    let image = exr_support::read_image(path);
    let d = image.attributes.display_window;
    let layer = &image.layer_data[0];
    let p = layer.attributes.layer_position;
    (
        ((d.position.0, d.position.1), (d.size.0, d.size.1)),
        ((p.0, p.1), (layer.size.0, layer.size.1)),
        channels(path),
    )
}

#[test]
fn a_region_renders_the_full_frames_pixels_and_a_full_render_redoes_it() {
    let dir = temp_dir("region");
    // Production (the edge anti-aliased, a finer light grid); an open shutter on a moving
    // aggregation: the blurred path, 8 rays a pixel.
    let shot = "width: 48, height: 27, fps: 6, seconds: 1.0, shutter: 0.5";
    let extra = "animation: Aggregation(()), quality: Production, \
                 output: (dir: \"out\", formats: [Exr, Png], passes: true)";
    write_scene(&dir, "c", shot, extra);
    let region = ["--region", "5,3,37,20"];
    run(nephele(&dir).args(["render", "c.ron", "--frames", "3"]));
    let (full, part) = (
        dir.join("out/c_0003.exr"),
        dir.join("out/c_0003.region.exr"),
    );
    let finished = std::fs::read(&full).unwrap();
    // A look test over a finished frame goes beside it, under its own name.
    let t = run(nephele(&dir)
        .args(["render", "c.ron", "--frames", "3"])
        .args(region));
    assert!(t.contains("1 frames rendered"), "{t}");
    assert_eq!(
        std::fs::read(&full).unwrap(),
        finished,
        "the frame is untouched"
    );
    assert!(dir.join("out/c_0003.region.manifest.json").is_file());
    let (display, data, got) = windows_and_channels(&part);
    assert_eq!(
        display,
        ((0, 0), (48, 27)),
        "display window: the full frame"
    );
    assert_eq!(data, ((5, 3), (32, 17)), "data window: the region");
    let (_, _, all) = windows_and_channels(&full);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        all.keys().collect::<Vec<_>>()
    );
    let mut cloud = 0;
    for (name, values) in &got {
        for (k, v) in values.iter().enumerate() {
            let (x, y) = (5 + k % 32, 3 + k / 32);
            let w = all[name][y * 48 + x];
            assert_eq!(v.to_bits(), w.to_bits(), "{name} at ({x}, {y}): {v} vs {w}");
            cloud += (name == "A" && *v > 0.5) as u32;
        }
    }
    assert!(cloud > 50, "the region shows cloud ({cloud} pixels)");
    // The PNG: full size, the full frame's pixels inside the region, transparent outside.
    let png = image::open(dir.join("out/c_0003.region.png"))
        .unwrap()
        .to_rgba8();
    let whole = image::open(dir.join("out/c_0003.png")).unwrap().to_rgb8();
    assert_eq!(png.dimensions(), (48, 27));
    for (x, y, p) in png.enumerate_pixels() {
        if (5..37).contains(&x) && (3..20).contains(&y) {
            assert_eq!(p.0[3], 255);
            assert_eq!(p.0[..3], whole.get_pixel(x, y).0, "({x}, {y})");
        } else {
            assert_eq!(p.0[3], 0, "({x}, {y}) is outside the region");
        }
    }
    if let Some(info) = oiiotool_info(&part) {
        for line in [
            "32 x   17",
            "pixel data origin: x=5, y=3",
            "full/display size: 48 x 27",
        ] {
            assert!(info.contains(line), "oiiotool: missing {line:?} in\n{info}");
        }
    }
    // The same region again is up to date, and so is the full frame beside it.
    let t = run(nephele(&dir)
        .args(["render", "c.ron", "--frames", "3"])
        .args(region));
    assert!(t.contains("0 frames rendered, 1 already done"), "{t}");
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "3"]));
    assert!(t.contains("0 frames rendered, 1 already done"), "{t}");
    assert_eq!(channels(&full), all);
    // Bad regions: located errors, exit 1, nothing written.
    for (bad, says) in [
        ("5,3,37", "is not x0,y0,x1,y1"),
        ("5,3,5,20", "is empty"),
        ("5,3,49,20", "is outside the 48×27 frame"),
    ] {
        let e = fails(nephele(&dir).args([
            "render", "c.ron", "--frames", "3", "--output", "bad", "--region", bad,
        ]));
        assert!(
            e.contains("c.ron: --region: ") && e.contains(says),
            "{bad}: {e}"
        );
    }
    assert!(!dir.join("bad").exists(), "nothing is written");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Per pixel, the `(id, coverage)` ranks of a Cryptomatte layer.
type Ranks = Vec<Vec<(f32, f32)>>;

/// The Cryptomatte layer of an EXR decoded: the manifest (name → id), and per pixel the
/// `(id, coverage)` ranks; checks the header's keys and that every id is the hash of its name.
fn cryptomatte(path: &Path) -> (BTreeMap<String, f32>, Ranks) {
    use nephele::render::output::cryptomatte::{layer_key, name_id};
    let layer = exr_support::read_first_layer(path);
    let key = layer_key("CryptoObject");
    let attr = |what: &str| text_attr(path, &format!("cryptomatte/{key}/{what}"));
    assert_eq!(attr("name"), "CryptoObject");
    assert_eq!(attr("hash"), "MurmurHash3_32");
    assert_eq!(attr("conversion"), "uint32_to_float32");
    let manifest: BTreeMap<String, String> = serde_json::from_str(&attr("manifest")).unwrap();
    let manifest: BTreeMap<String, f32> = manifest
        .into_iter()
        .map(|(name, hex)| {
            let id = f32::from_bits(u32::from_str_radix(&hex, 16).unwrap());
            assert_eq!(hex.len(), 8, "{name}: {hex}");
            assert_eq!(id.to_bits(), name_id(&name).to_bits(), "{name}: {hex}");
            (name, id)
        })
        .collect();
    let c = channels(path);
    let n = layer.size.0 * layer.size.1;
    let mut ranks = vec![Vec::new(); n];
    for set in 0..3 {
        let ch = |s: &str| &c[&format!("CryptoObject{set:02}.{s}")];
        for (i, r) in ranks.iter_mut().enumerate() {
            r.push((ch("R")[i], ch("G")[i]));
            r.push((ch("B")[i], ch("A")[i]));
        }
    }
    assert!(
        !c.contains_key("CryptoObject03.R"),
        "6 ranks, 3 channel sets"
    );
    (manifest, ranks)
}

#[test]
fn cryptomatte_mattes_name_the_clusters_and_cover_the_alpha() {
    let dir = temp_dir("cryptomatte");
    let shot = "width: 64, height: 36, fps: 6, seconds: 1.0";
    write_scene(
        &dir,
        "a",
        shot,
        "animation: Aggregation(()), output: (dir: \"out\", formats: [Exr], passes: true)",
    );
    run(nephele(&dir).args(["render", "a.ron", "--frames", "1,6"]));
    for frame in [1, 6] {
        let path = dir.join(format!("out/a_{frame:04}.exr"));
        let (manifest, ranks) = cryptomatte(&path);
        assert!(manifest.len() >= 8, "one matte per cluster: {manifest:?}");
        assert!(
            manifest.keys().all(|n| n.starts_with("cluster_")),
            "{manifest:?}"
        );
        let alpha = &channels(&path)["A"];
        let (mut worst, mut seen) = (0.0f32, BTreeMap::new());
        for (i, r) in ranks.iter().enumerate() {
            let sum: f32 = r.iter().map(|&(_, c)| c).sum();
            worst = worst.max((sum - alpha[i]).abs());
            for w in r.windows(2) {
                assert!(w[0].1 >= w[1].1, "pixel {i}: ranks by coverage {r:?}");
            }
            for &(id, c) in r {
                if c > 0.0 {
                    let name = manifest.iter().find(|(_, m)| m.to_bits() == id.to_bits());
                    let (name, _) = name.unwrap_or_else(|| panic!("id {id} not in the manifest"));
                    if alpha[i] > 0.5 && c == r[0].1 {
                        *seen.entry(name.clone()).or_insert(0) += 1;
                    }
                } else {
                    assert_eq!(id, 0.0, "an empty rank's id is 0");
                }
            }
        }
        assert!(
            worst < 1e-5,
            "frame {frame}: coverage sums off alpha by {worst}"
        );
        eprintln!(
            "frame {frame}: pixels per leading cluster {seen:?}; |Σ coverage − A| ≤ {worst:.1e}"
        );
        assert!(
            seen.len() >= 3,
            "frame {frame}: several clusters show: {seen:?}"
        );
        if frame == 6
            && let Some(info) = oiiotool_info(&path)
        {
            for line in [
                "CryptoObject00.R, CryptoObject00.G, CryptoObject00.B, CryptoObject00.A",
                "CryptoObject02.A",
                "cryptomatte/3ae39a5/name: \"CryptoObject\"",
                "cryptomatte/3ae39a5/hash: \"MurmurHash3_32\"",
                "cryptomatte/3ae39a5/conversion: \"uint32_to_float32\"",
                "cryptomatte/3ae39a5/manifest: \"{\"cluster_00\":\"",
            ] {
                assert!(info.contains(line), "oiiotool: missing {line:?} in\n{info}");
            }
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
