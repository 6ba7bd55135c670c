//! A frame on disk is what its manifest says (issue 38): resume never counts a frame that mixes
//! two scene states as done — after a scene edit between format changes, after a kill between
//! the files and the manifest, with two renders into one folder, with an edited or damaged
//! manifest — stale temporaries of killed renders are removed, formats come and go without
//! touching the other files, and farm scripts cannot be injected. The kill cases run nephele as
//! a child stopped at a chosen point by its test hook (`NEPHELE_TEST_HOOK`) and killed by PID.
//! Every scene is the procedural `builtin:cumulus` at a few dozen pixels.

use crate::cli_support;

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use cli_support::{nephele_in as nephele, run, text};

fn temp_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nephele-integrity-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A 40×24 cumulus shot of 4 frames at `fps` in `dir/NAME.ron`, frames in `dir/out` named `s`.
fn write_scene(dir: &Path, name: &str, sun: &str, fps: u32, formats: &str) {
    std::fs::write(
        dir.join(format!("{name}.ron")),
        format!(
            "Scene(target: Model(\"builtin:cumulus\"), shot: (width: 40, height: 24, fps: {fps}, \
             seconds: 1.0), sun: (direction: {sun}), seed: 3, \
             output: (dir: \"out\", name: \"s\", formats: [{formats}]))"
        ),
    )
    .unwrap();
}

fn fails(c: &mut Command) -> String {
    let o = c.output().unwrap();
    let t = text(&o);
    assert_eq!(o.status.code(), Some(1), "{t}");
    assert!(!t.contains("panicked"), "{t}");
    t
}

/// The `nephele/hash` of an EXR's header.
fn exr_hash(path: &Path) -> String {
    nephele::scene::provenance::exr_hash(path).unwrap_or_else(|| panic!("{}", path.display()))
}

/// The manifest's listed hash of file `name`.
fn listed_hash(manifest: &Path, name: &str) -> Option<String> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(manifest).ok()?).ok()?;
    v["files"]
        .as_array()?
        .iter()
        .find(|f| f["name"] == name)
        .map(|f| f["hash"].as_str().unwrap().to_string())
}

/// Start `c` with the test hook at `point`; return it once it has stopped there.
fn stopped_at(c: &mut Command, point: &str) -> Child {
    let mut child = c
        .env("NEPHELE_TEST_HOOK", point)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stderr.take().unwrap()).lines();
    let marker = format!("nephele test hook: stopped at {point}");
    loop {
        match lines.next() {
            Some(Ok(l)) if l.contains(&marker) => break,
            Some(_) => {}
            None => panic!("nephele ended before reaching {point}: {:?}", child.wait()),
        }
    }
    // Keep draining stderr so the child never blocks on a full pipe.
    std::thread::spawn(move || for _ in lines {});
    child
}

/// SIGKILL `child` by its PID, as a farm's scheduler or the OOM killer would.
fn kill(mut child: Child) {
    let status = Command::new("kill")
        .args(["-KILL", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let _ = child.wait();
}

fn temps(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

#[test]
fn a_frame_from_an_older_scene_state_is_never_counted_done() {
    let dir = temp_dir("formats");
    let out = dir.join("out");
    let r = |args: &[&str]| run(nephele(&dir).args(["render", "c.ron"]).args(args));
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    r(&["--frames", "2", "--formats", "exr"]);
    // Another sun, PNG only: the EXR of the old sun stays on disk, outside the manifest.
    write_scene(&dir, "c", "(-1.0, -1.0, 0.5)", 24, "Exr, Png");
    r(&["--frames", "2", "--formats", "png"]);
    let t = r(&["--frames", "2"]);
    assert!(t.contains("1 frames rendered, 0 already done"), "{t}");
    assert!(t.contains("formats changed: +exr"), "{t}");
    let m = out.join("s_0002.manifest.json");
    assert_eq!(
        listed_hash(&m, "s_0002.exr").unwrap(),
        exr_hash(&out.join("s_0002.exr")),
        "the EXR carries the manifest's hash"
    );
    // An EXR put back from elsewhere (the old sun's) is caught by its own header.
    let png = std::fs::read(out.join("s_0002.png")).unwrap();
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    run(nephele(&dir).args(["render", "c.ron", "--frames", "2", "--output", "old"]));
    write_scene(&dir, "c", "(-1.0, -1.0, 0.5)", 24, "Exr, Png");
    std::fs::copy(dir.join("old/s_0002.exr"), out.join("s_0002.exr")).unwrap();
    let t = r(&["--frames", "2"]);
    assert!(t.contains("1 files replaced since their manifest"), "{t}");
    assert_eq!(std::fs::read(out.join("s_0002.png")).unwrap(), png);
    // A scene edit names the component that changed.
    write_scene(&dir, "c", "(-1.0, -1.0, 0.5)", 12, "Exr, Png");
    let t = r(&["--frames", "2"]);
    assert!(
        t.contains("EXR header (scene"),
        "fps is in the EXR's hash: {t}"
    );
    write_scene(&dir, "c", "(0.0, -1.0, 0.5)", 12, "Exr, Png");
    let t = r(&["--frames", "2"]);
    assert!(t.contains("1 changed: sun and sky"), "{t}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn formats_come_and_go_without_rerendering_the_rest() {
    let dir = temp_dir("vol");
    let out = dir.join("out");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png, Vol");
    run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    let exr = std::fs::read(out.join("s_0001.exr")).unwrap();
    let modified = |p: &str| std::fs::metadata(out.join(p)).unwrap().modified().unwrap();
    let (exr_time, png_time) = (modified("s_0001.exr"), modified("s_0001.png"));
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    assert!(t.contains("2 formats changed: -vol"), "{t}");
    assert!(
        !out.join("s_0001.vol").exists(),
        "the dropped format's file goes"
    );
    assert_eq!(modified("s_0001.exr"), exr_time, "the EXR is not rewritten");
    assert_eq!(modified("s_0001.png"), png_time, "the PNG is not rewritten");
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    assert!(t.contains("0 frames rendered, 2 already done"), "{t}");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png, Vol");
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    assert!(t.contains("2 formats changed: +vol"), "{t}");
    assert!(out.join("s_0001.vol").is_file());
    assert_eq!(modified("s_0001.exr"), exr_time, "a grid needs no render");
    assert_eq!(std::fs::read(out.join("s_0001.exr")).unwrap(), exr);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_kill_between_files_and_manifest_leaves_no_done_frame() {
    let dir = temp_dir("kill");
    let out = dir.join("out");
    write_scene(&dir, "a", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    write_scene(&dir, "b", "(-1.0, -1.0, 0.5)", 24, "Exr, Png");
    run(nephele(&dir).args(["render", "a.ron", "--frames", "1..2"]));
    // Scene b re-renders frame 2 and is killed with its files in place, its manifest not yet.
    let child = stopped_at(
        nephele(&dir).args(["render", "b.ron", "--frames", "2"]),
        "after-files:2",
    );
    // While it holds frame 2, another render of it is refused and names the process.
    let t = fails(nephele(&dir).args(["render", "a.ron", "--frames", "2"]));
    assert!(
        t.contains(&format!("nephele process {}", child.id())) && t.contains("b.ron"),
        "{t}"
    );
    kill(child);
    assert!(
        !out.join("s_0002.manifest.json").exists(),
        "removed before the files"
    );
    // The old scene does not take the mixed frame for its own.
    let t = run(nephele(&dir).args(["render", "a.ron", "--frames", "1..2"]));
    assert!(t.contains("1 frames rendered, 1 already done"), "{t}");
    assert!(t.contains("1 interrupted"), "{t}");
    // A manifest edited by hand, or emptied, is not trusted.
    let m = out.join("s_0002.manifest.json");
    let text = std::fs::read_to_string(&m).unwrap();
    let tampered = {
        let at = text.find("\"hash\": \"").unwrap() + 9;
        let mut t = text.clone();
        let c = if &t[at..at + 1] == "0" { "1" } else { "0" };
        t.replace_range(at..at + 1, c);
        t
    };
    std::fs::write(&m, tampered).unwrap();
    let t = run(nephele(&dir).args(["render", "a.ron", "--frames", "2"]));
    assert!(
        t.contains("manifest unreadable: its check hash does not match"),
        "{t}"
    );
    std::fs::write(&m, "").unwrap();
    let t = run(nephele(&dir).args(["render", "a.ron", "--frames", "2"]));
    assert!(t.contains("manifest unreadable: empty file"), "{t}");
    std::fs::write(&m, "{\"frame\": 2").unwrap();
    let t = run(nephele(&dir).args(["render", "a.ron", "--frames", "2"]));
    assert!(t.contains("manifest unreadable: EOF"), "{t}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn temporaries_of_a_killed_render_are_removed_on_the_next_run() {
    let dir = temp_dir("temps");
    let out = dir.join("out");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Vdb");
    for next in [
        &["render", "c.ron", "--frames", "1..3"][..],
        &["render", "c.ron", "--force", "--frames", "1"],
        &["prepare", "c.ron"],
    ] {
        let child = stopped_at(
            nephele(&dir).args(["render", "c.ron", "--force", "--frames", "1..3"]),
            "before-rename:s_0002.vdb",
        );
        kill(child);
        let left = temps(&out);
        assert!(
            left.iter().any(|n| n.starts_with(".s_0002.vdb.")),
            "{left:?}"
        );
        run(nephele(&dir).args(next));
        assert_eq!(temps(&out), Vec::<String>::new(), "after {next:?}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn farm_scripts_cannot_be_injected_and_name_their_jobs_once() {
    let dir = temp_dir("farm");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr");
    let t = fails(nephele(&dir).args([
        "farm",
        "c.ron",
        "--engine",
        "slurm",
        "--sbatch-arg",
        "--comment=x\necho INJECTED",
    ]));
    assert!(t.contains("control character"), "{t}");
    assert!(!dir.join("out/s.sbatch").exists(), "nothing is written");
    std::fs::write(
        dir.join("k.ron"),
        "Scene(target: Model(\"builtin:cumulus\"), shot: (width: 40, height: 24, fps: 4, \
         seconds: 1.0), output: (dir: \"out\", name: \"shot_\"))",
    )
    .unwrap();
    let t = run(nephele(&dir).args(["farm", "k.ron", "--engine", "k8s"]));
    assert!(t.contains("job/shot-prepare"), "{t}");
    let yaml = std::fs::read_to_string(dir.join("out/shot_.prepare.k8s.yaml")).unwrap();
    assert!(yaml.contains("name: shot-prepare\n"), "{yaml}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn memory_is_checked_where_the_frames_render() {
    // 50 000 × 50 000 needs about 175 GB a frame: the farm's head node writes the jobs, the
    // render refuses (before writing anything).
    let dir = temp_dir("memory");
    std::fs::write(
        dir.join("h.ron"),
        "Scene(target: Model(\"builtin:cumulus\"), shot: (width: 50000, height: 50000, fps: 4, \
         seconds: 1.0), output: (dir: \"out\"))",
    )
    .unwrap();
    run(nephele(&dir).args(["farm", "h.ron", "--engine", "slurm"]));
    let t = fails(nephele(&dir).args(["render", "h.ron", "--frames", "1"]));
    assert!(
        t.contains("h.ron: shot: ") && t.contains("is available on this machine"),
        "{t}"
    );
    assert!(!dir.join("out/h_0001.exr").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
