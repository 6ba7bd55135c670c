//! Bad input through the whole command line (issue 6): every malformed mesh, model and scene
//! given to `fit`, `eval`, `mesh` and `render` must exit non-zero with a message naming the file,
//! never panic, and leave no output file behind. Inputs with a sensible result (open mesh,
//! inside-out mesh, several components) must warn and succeed.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_nephele"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nephele-robust-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Run nephele in `dir` with `args`.
fn run_in(dir: &Path, args: &[&str]) -> Output {
    bin().args(args).current_dir(dir).output().unwrap()
}

/// Fail when `dir` holds anything besides `inputs`.
fn assert_nothing_left(dir: &Path, inputs: &[&str]) {
    assert_eq!(
        outputs(dir, inputs),
        Vec::<String>::new(),
        "files left behind"
    );
}

/// Files in `dir` other than the inputs.
fn outputs(dir: &Path, inputs: &[&str]) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| !inputs.contains(&n.as_str()))
        .collect();
    v.sort();
    v
}

/// Tiny unit cube as OBJ text, optionally with a face line replaced.
fn cube_obj() -> String {
    let mut s = String::new();
    for z in [0, 1] {
        for y in [0, 1] {
            for x in [0, 1] {
                s.push_str(&format!("v {x} {y} {z}\n"));
            }
        }
    }
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        s.push_str(&format!("f {} {} {} {}\n", f[0], f[1], f[2], f[3]));
    }
    s
}

/// The bad meshes: (file name, bytes).
fn bad_meshes() -> Vec<(&'static str, Vec<u8>)> {
    let mut huge_ply = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 2000000000\nproperty list uchar int vertex_indices\nend_header\n".to_vec();
    huge_ply.extend_from_slice(&[0u8; 36]);
    let mut lying_stl = vec![0u8; 80];
    lying_stl.extend_from_slice(&1_000_000u32.to_le_bytes());
    lying_stl.extend_from_slice(&[0u8; 50]);
    vec![
        ("empty.obj", Vec::new()),
        ("empty.ply", Vec::new()),
        ("empty.stl", Vec::new()),
        ("empty.off", Vec::new()),
        ("garbage.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n1 2 \xff\xfe zz\n".to_vec()),
        ("truncated.ply", b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n".to_vec()),
        ("huge.ply", huge_ply),
        ("lying.stl", lying_stl),
        ("nan.obj", cube_obj().replacen("v 1 0 0", "v nan 0 0", 1).into_bytes()),
        ("inf.obj", cube_obj().replacen("v 1 0 0", "v inf 0 0", 1).into_bytes()),
        ("out_of_range.obj", format!("{}f 1 2 99\n", cube_obj()).into_bytes()),
        ("negative.obj", format!("{}f -1 -2 -40\n", cube_obj()).into_bytes()),
        ("two_vertex_face.obj", format!("{}f 1 2\n", cube_obj()).into_bytes()),
        ("zero_area.obj", b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n".to_vec()),
        ("bad.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n".to_vec()),
        ("unknown.xyz", b"1 2 3\n".to_vec()),
    ]
}

#[test]
fn bad_meshes_fail_cleanly_in_fit_and_eval() {
    let dir = scratch("mesh");
    let model = dir.join("m.ron");
    for (name, bytes) in bad_meshes() {
        std::fs::write(dir.join(name), &bytes).unwrap();
        let out = run_in(
            &dir,
            &[
                "fit",
                name,
                "-o",
                "m.ron",
                "--blobs",
                "5",
                "--candidates",
                "20",
                "--samples",
                "500",
            ],
        );
        let t = text(&out);
        assert!(!out.status.success(), "fit {name} succeeded:\n{t}");
        assert!(!t.contains("panicked"), "fit {name} panicked:\n{t}");
        assert!(
            t.contains(name),
            "fit {name}: message does not name the file:\n{t}"
        );
        assert!(!model.exists(), "fit {name} left an output file");
        let out = run_in(&dir, &["eval", name, "missing.ron"]);
        assert!(
            !out.status.success() && !text(&out).contains("panicked"),
            "eval {name}: {}",
            text(&out)
        );
    }
    let inputs: Vec<&str> = bad_meshes().iter().map(|m| m.0).collect();
    assert_nothing_left(&dir, &inputs);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn recoverable_meshes_warn_and_fit() {
    let dir = scratch("warn");
    // Open: the cube without its top face; inside-out: every face reversed.
    let open: String = cube_obj()
        .lines()
        .filter(|l| *l != "f 3 7 8 4")
        .map(|l| format!("{l}\n"))
        .collect();
    let inverted: String = cube_obj()
        .lines()
        .map(|l| match l.strip_prefix("f ") {
            Some(f) => format!("f {}\n", f.split(' ').rev().collect::<Vec<_>>().join(" ")),
            None => format!("{l}\n"),
        })
        .collect();
    let two = {
        let shifted: String = cube_obj()
            .lines()
            .map(|l| match l.strip_prefix("v ") {
                Some(v) => {
                    let c: Vec<f64> = v.split(' ').map(|x| x.parse().unwrap()).collect();
                    format!("v {} {} {}\n", c[0] + 3.0, c[1], c[2])
                }
                None => l.replace(|c: char| c.is_ascii_digit(), "#"),
            })
            .collect();
        let faces: String = cube_obj()
            .lines()
            .filter_map(|l| l.strip_prefix("f "))
            .map(|f| {
                let ids: Vec<String> = f
                    .split(' ')
                    .map(|i| (i.parse::<u32>().unwrap() + 8).to_string())
                    .collect();
                format!("f {}\n", ids.join(" "))
            })
            .collect();
        format!(
            "{}{}{}",
            cube_obj(),
            shifted
                .lines()
                .filter(|l| l.starts_with("v "))
                .map(|l| format!("{l}\n"))
                .collect::<String>(),
            faces
        )
    };
    for (name, body, warning) in [
        ("open.obj", open, Some("open")),
        ("inverted.obj", inverted, Some("flipped")),
        ("two.obj", two, None),
    ] {
        std::fs::write(dir.join(name), body).unwrap();
        let out = run_in(
            &dir,
            &[
                "fit",
                name,
                "-o",
                "m.ron",
                "--blobs",
                "8",
                "--candidates",
                "40",
                "--samples",
                "2000",
                "--optimiser",
                "faithful",
            ],
        );
        let t = text(&out);
        assert!(out.status.success(), "fit {name} failed:\n{t}");
        if let Some(w) = warning {
            assert!(
                t.contains("warning") && t.contains(w),
                "fit {name}: no '{w}' warning:\n{t}"
            );
        }
        assert!(dir.join("m.ron").exists());
        std::fs::remove_file(dir.join("m.ron")).unwrap();
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_models_fail_cleanly_in_mesh_and_eval() {
    let dir = scratch("model");
    let models: Vec<(&str, &[u8])> = vec![
        ("empty.ron", b""),
        (
            "garbage.ron",
            b"BlobModel(version: 1, primitive: Ellipsoid, blobs: [ nope",
        ),
        ("future.ron", b"BlobModel(version: 99, something_new: 1)"),
        ("binary.blob", b"NPHB\x01\x00\xff\xff\xff\xff"),
        ("noise.blob", b"\x00\x01\x02\x03garbage"),
    ];
    std::fs::write(dir.join("cube.obj"), cube_obj()).unwrap();
    for (name, bytes) in &models {
        std::fs::write(dir.join(name), bytes).unwrap();
        let out = run_in(&dir, &["mesh", name, "-o", "out.obj"]);
        let t = text(&out);
        assert!(
            !out.status.success() && !t.contains("panicked") && t.contains(name),
            "mesh {name}:\n{t}"
        );
        let out = run_in(&dir, &["eval", "cube.obj", name]);
        let t = text(&out);
        assert!(
            !out.status.success() && !t.contains("panicked") && t.contains(name),
            "eval {name}:\n{t}"
        );
        if *name == "future.ron" {
            assert!(
                t.contains("version 99"),
                "future version not reported:\n{t}"
            );
        }
    }
    let mut inputs: Vec<&str> = models.iter().map(|m| m.0).collect();
    inputs.push("cube.obj");
    assert_nothing_left(&dir, &inputs);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_scenes_fail_cleanly_in_render() {
    let dir = scratch("scene");
    let scenes: Vec<(&str, &str)> = vec![
        (
            "unknown_field.ron",
            "Scene(target: Fit(mesh: \"builtin:sphere\"), colour: 3)",
        ),
        (
            "wrong_type.ron",
            "Scene(target: Fit(mesh: \"builtin:sphere\", blobs: \"many\"))",
        ),
        (
            "missing_model.ron",
            "Scene(target: Model(\"nowhere/model.ron\"))",
        ),
        (
            "missing_mesh.ron",
            "Scene(target: Fit(mesh: \"nowhere.obj\"))",
        ),
        (
            "negative_size.ron",
            "Scene(target: Fit(mesh: \"builtin:sphere\"), shot: (width: -5))",
        ),
        (
            "zero_fps.ron",
            "Scene(target: Fit(mesh: \"builtin:sphere\"), shot: (fps: 0))",
        ),
        (
            "nan.ron",
            "Scene(target: Fit(mesh: \"builtin:sphere\"), shot: (seconds: NaN))",
        ),
        ("empty.ron", ""),
    ];
    for (name, body) in &scenes {
        std::fs::write(dir.join(name), body).unwrap();
        let out = run_in(&dir, &["render", name, "--output", "out"]);
        let t = text(&out);
        assert!(!out.status.success(), "render {name} succeeded:\n{t}");
        assert!(
            !t.contains("panicked") && t.contains(name),
            "render {name}:\n{t}"
        );
        assert!(!dir.join("out").exists(), "render {name} created output");
    }
    // An empty frame range on a valid scene is refused before any work.
    std::fs::write(
        dir.join("ok.ron"),
        "Scene(target: Fit(mesh: \"builtin:sphere\", blobs: 10))",
    )
    .unwrap();
    let out = run_in(
        &dir,
        &["render", "ok.ron", "--frames", "5..2", "--output", "out"],
    );
    assert!(
        !out.status.success() && !text(&out).contains("panicked"),
        "{}",
        text(&out)
    );
    assert!(!dir.join("out").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn interrupted_render_leaves_no_finished_looking_partial_frame() {
    let dir = scratch("kill");
    std::fs::write(
        dir.join("shot.ron"),
        "Scene(target: Fit(mesh: \"builtin:sphere\", blobs: 20, candidates: 200, samples: 5000), \
         shot: (width: 160, height: 90, fps: 24, seconds: 1.0), output: (formats: [Exr, Png]))",
    )
    .unwrap();
    // Fit first (cached), so the kill lands while frames are being written.
    let out = run_in(
        &dir,
        &["render", "shot.ron", "--output", "out", "--frames", "1..1"],
    );
    assert!(out.status.success(), "{}", text(&out));
    for delay_ms in [150u64, 400, 900] {
        let mut child = bin()
            .args(["render", "shot.ron", "--output", "out", "--force"])
            .current_dir(&dir)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill();
        let _ = child.wait();
        // Every file that looks like a finished frame must decode completely.
        for entry in std::fs::read_dir(dir.join("out")).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if name.starts_with('.') || name.ends_with(".tmp") {
                continue;
            }
            if name.ends_with(".png") {
                image::open(&path).unwrap_or_else(|e| panic!("{name} is not a complete PNG: {e}"));
            } else if name.ends_with(".exr") {
                exr::prelude::read_all_data_from_file(&path)
                    .unwrap_or_else(|e| panic!("{name} is not a complete EXR: {e}"));
            }
        }
    }
    // Resuming after the kills completes the shot.
    let out = run_in(&dir, &["render", "shot.ron", "--output", "out"]);
    assert!(out.status.success(), "{}", text(&out));
    let pngs = std::fs::read_dir(dir.join("out"))
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".png")
        })
        .count();
    assert_eq!(pngs, 24);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_farm_requests_fail_before_any_work() {
    let dir = scratch("farm");
    std::fs::write(
        dir.join("ok.ron"),
        "Scene(target: Fit(mesh: \"builtin:sphere\", blobs: 10), shot: (fps: 4, seconds: 1.0))",
    )
    .unwrap();
    std::fs::write(dir.join("file"), b"not a folder").unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["render", "ok.ron", "--output", "out", "--task", "4/4"],
            "below 4",
        ),
        (
            vec!["render", "ok.ron", "--output", "out", "--task", "0/0"],
            "at least 1",
        ),
        (
            vec!["render", "ok.ron", "--output", "out", "--task", "auto/4"],
            "SLURM_ARRAY_TASK_ID",
        ),
        (
            vec!["render", "ok.ron", "--output", "out", "--task", "0/5"],
            "at most 4 tasks",
        ),
        (
            vec!["render", "ok.ron", "--output", "out", "--task", "1"],
            "not I/N",
        ),
        (
            vec![
                "farm", "ok.ron", "--engine", "slurm", "--output", "out", "--chunk", "5",
            ],
            "--chunk 5",
        ),
        (
            vec![
                "farm", "ok.ron", "--engine", "slurm", "--output", "out", "--chunk", "0",
            ],
            "--chunk 0",
        ),
        (
            vec![
                "farm", "ok.ron", "--engine", "k8s", "--output", "out", "--submit",
            ],
            "kubectl",
        ),
        (
            vec!["render", "ok.ron", "--output", "file/out"],
            "not writable",
        ),
        (
            vec!["render", "ok.ron", "--output", "file/out", "--task", "0/2"],
            "not writable",
        ),
        (
            vec!["prepare", "ok.ron", "--output", "file/out"],
            "not writable",
        ),
        (
            vec![
                "farm", "ok.ron", "--engine", "slurm", "--output", "file/out",
            ],
            "not writable",
        ),
    ];
    for (args, expect) in &cases {
        let mut cmd = bin();
        for v in nephele::scene::chunk::ARRAY_INDEX_VARS {
            cmd.env_remove(v);
        }
        let out = cmd.args(args).current_dir(&dir).output().unwrap();
        let t = text(&out);
        assert!(!out.status.success(), "{args:?} succeeded:\n{t}");
        assert!(
            !t.contains("panicked") && t.contains(expect),
            "{args:?}: expected {expect:?} in:\n{t}"
        );
        assert_nothing_left(&dir, &["ok.ron", "file"]);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Run nephele in `dir` with `args`, killed (and the test failed) if it runs past `secs`
/// seconds: an input that blocks (a FIFO with no writer) must fail fast, not hang.
fn run_within(dir: &Path, args: &[&str], secs: u64) -> Output {
    let mut child = bin()
        .args(args)
        .current_dir(dir)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(secs) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("nephele {args:?} still running after {secs} s (blocked or unbounded read)");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// A FIFO at `path` (no writer ever opens it).
fn fifo(path: &Path) {
    use std::os::unix::ffi::OsStrExt;
    let c = std::ffi::CString::new(path.as_os_str().as_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path; mkfifo only reads it.
    assert_eq!(
        unsafe { libc::mkfifo(c.as_ptr(), 0o600) },
        0,
        "mkfifo {path:?}"
    );
}

/// [`cube_obj`] with every coordinate multiplied by `scale`.
fn scaled_cube(scale: f64) -> String {
    cube_obj()
        .lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(v) => {
                let c: Vec<String> = v
                    .split(' ')
                    .map(|x| format!("{:e}", x.parse::<f64>().unwrap() * scale))
                    .collect();
                format!("v {}\n", c.join(" "))
            }
            None => format!("{l}\n"),
        })
        .collect()
}

/// Devices, FIFOs, oversize files and targets too large or too small to render (issue 48):
/// each fails fast (no unbounded read, no read blocked forever), exits non-zero with a message
/// naming the file, and leaves no output behind.
#[test]
fn unreadable_and_unrenderable_inputs_fail_fast_naming_the_file() {
    let dir = scratch("inputs");
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.obj")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", dir.join("zero.ron")).unwrap();
    fifo(&dir.join("fifo.ron"));
    fifo(&dir.join("fifo.obj"));
    // Sparse: 16 MiB + 1 byte on paper, nothing on disk.
    std::fs::File::create(dir.join("big.ron"))
        .unwrap()
        .set_len((16 << 20) + 1)
        .unwrap();
    std::fs::write(dir.join("huge.obj"), scaled_cube(1e20)).unwrap();
    std::fs::write(dir.join("tiny.obj"), scaled_cube(1e-20)).unwrap();
    std::fs::write(dir.join("cube.obj"), cube_obj()).unwrap();
    let fit = "blobs: 10, candidates: 200, samples: 5000";
    let scenes = [
        (
            "zero_mesh.ron",
            format!("Scene(target: Fit(mesh: \"zero.obj\", {fit}))"),
        ),
        (
            "dev_zero_mesh.ron",
            format!("Scene(target: Fit(mesh: \"/dev/zero\", {fit}))"),
        ),
        (
            "fifo_mesh.ron",
            format!("Scene(target: Fit(mesh: \"fifo.obj\", {fit}))"),
        ),
        (
            "huge_mesh.ron",
            format!("Scene(target: Fit(mesh: \"huge.obj\", {fit}))"),
        ),
        (
            "tiny_mesh.ron",
            format!("Scene(target: Fit(mesh: \"tiny.obj\", {fit}))"),
        ),
        (
            "cube_far_too_big.ron",
            format!("Scene(target: Fit(mesh: \"cube.obj\", {fit}), transform: (scale: 1e20))"),
        ),
        (
            "cube_far_too_small.ron",
            format!("Scene(target: Fit(mesh: \"cube.obj\", {fit}), transform: (scale: 1e-20))"),
        ),
        (
            "huge_model.ron",
            "Scene(target: Model(\"builtin:cumulus\"), transform: (scale: 1e20))".to_string(),
        ),
        (
            "far_model.ron",
            "Scene(target: Model(\"builtin:cumulus\"), transform: (translate: (1e9, 0.0, 0.0)))"
                .to_string(),
        ),
    ];
    for (name, body) in &scenes {
        std::fs::write(dir.join(name), body).unwrap();
    }
    let size = ["--frames", "1", "--preview", "--output", "out"];
    let mut cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            vec!["render", "/dev/zero"],
            vec!["/dev/zero", "not a regular file"],
        ),
        (
            vec!["render", "zero.ron"],
            vec!["zero.ron", "not a regular file"],
        ),
        (
            vec!["render", "fifo.ron"],
            vec!["fifo.ron", "not a regular file"],
        ),
        (
            vec!["render", "big.ron"],
            vec!["big.ron", "more than the 16 MiB"],
        ),
        (
            vec!["render", "zero_mesh.ron"],
            vec!["zero.obj", "not a regular file"],
        ),
        (
            vec!["render", "dev_zero_mesh.ron"],
            vec!["/dev/zero", "not a regular file"],
        ),
        (
            vec!["render", "fifo_mesh.ron"],
            vec!["fifo.obj", "not a regular file"],
        ),
        (
            vec!["render", "huge_mesh.ron"],
            vec![
                "huge_mesh.ron",
                "target",
                "huge.obj",
                "diagonal 1.732e20",
                "by 1e-20",
            ],
        ),
        (
            vec!["render", "tiny_mesh.ron"],
            vec![
                "tiny_mesh.ron",
                "target",
                "tiny.obj",
                "diagonal 1.732e-20",
                "by 1e20",
            ],
        ),
        (
            vec!["render", "cube_far_too_big.ron"],
            vec![
                "cube_far_too_big.ron",
                "cube.obj",
                "diagonal 1.732e20",
                "1e-4 to 1e10",
            ],
        ),
        (
            vec!["render", "cube_far_too_small.ron"],
            vec![
                "cube_far_too_small.ron",
                "cube.obj",
                "diagonal 1.732e-20",
                "scale: 1.0)",
            ],
        ),
        (
            vec!["render", "huge_model.ron"],
            vec!["huge_model.ron", "target", "1e-4 to 1e10", "transform"],
        ),
        (
            vec!["render", "far_model.ron"],
            vec!["far_model.ron", "transform.translate", "origin"],
        ),
        (
            vec!["fit", "zero.obj", "-o", "m.ron"],
            vec!["zero.obj", "not a regular file"],
        ),
        (
            vec!["fit", "fifo.obj", "-o", "m.ron"],
            vec!["fifo.obj", "not a regular file"],
        ),
        (
            vec!["decode", "/dev/zero", "-o", "m.ron"],
            vec!["/dev/zero", "not a regular file"],
        ),
        (
            vec!["decode", "fifo.ron", "-o", "m.ron"],
            vec!["fifo.ron", "not a regular file"],
        ),
        (
            vec!["encode", "zero.ron", "-o", "m.blob"],
            vec!["zero.ron", "not a regular file"],
        ),
        (
            vec!["prepare", "fifo_mesh.ron", "--output", "out"],
            vec!["fifo.obj"],
        ),
        (
            vec!["usd", "huge_mesh.ron", "-o", "out/s.usda"],
            vec!["huge.obj", "diagonal"],
        ),
    ];
    for (args, _) in cases.iter_mut() {
        if args[0] == "render" {
            args.extend(size);
        }
    }
    let mut inputs = vec![
        "zero.obj", "zero.ron", "fifo.ron", "fifo.obj", "big.ron", "huge.obj",
    ];
    inputs.extend(["tiny.obj", "cube.obj"]);
    inputs.extend(scenes.iter().map(|s| s.0));
    for (args, expect) in &cases {
        let out = run_within(&dir, args, 60);
        let t = text(&out);
        assert!(!out.status.success(), "{args:?} succeeded:\n{t}");
        assert!(!t.contains("panicked"), "{args:?} panicked:\n{t}");
        for e in expect {
            assert!(t.contains(e), "{args:?}: expected {e:?} in:\n{t}");
        }
        assert_nothing_left(&dir, &inputs);
    }
    // The transform the error suggests renders the target, and not an empty frame.
    let out = run_within(
        &dir,
        &["render", "cube_far_too_small.ron", "--output", "out"],
        60,
    );
    let t = text(&out);
    let scale = t
        .split("transform: (scale: ")
        .nth(1)
        .and_then(|r| r.split(')').next())
        .unwrap_or_else(|| panic!("no transform suggested:\n{t}"));
    std::fs::write(
        dir.join("fixed.ron"),
        format!(
            "Scene(target: Fit(mesh: \"cube.obj\", {fit}), transform: (scale: {scale}), \
             shot: (width: 64, height: 36, fps: 4, seconds: 1.0))"
        ),
    )
    .unwrap();
    let out = run_within(
        &dir,
        &[
            "render",
            "fixed.ron",
            "--frames",
            "4",
            "--output",
            "out",
            "--stats",
        ],
        300,
    );
    assert!(out.status.success(), "{}", text(&out));
    let stats = std::fs::read_to_string(dir.join("out/fixed_stats.csv")).unwrap();
    let row: Vec<&str> = stats.lines().nth(1).unwrap().split(',').collect();
    let coverage: f64 = row[6].parse().unwrap();
    assert!(
        coverage > 0.05,
        "the rescaled target renders empty:\n{stats}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
