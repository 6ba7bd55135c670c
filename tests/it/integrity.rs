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
    assert!(
        t.contains("1 files kept from an earlier state of the scene"),
        "{t}"
    );
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
fn formats_come_and_go_without_rerendering_or_deleting_the_rest() {
    let dir = temp_dir("vol");
    let out = dir.join("out");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png, Vol");
    run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    let vol = std::fs::read(out.join("s_0001.vol")).unwrap();
    let modified = |p: &str| std::fs::metadata(out.join(p)).unwrap().modified().unwrap();
    let (exr_time, png_time) = (modified("s_0001.exr"), modified("s_0001.png"));
    // A format taken out of the scene: its files stay, current, and are reported.
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    assert!(t.contains("0 frames rendered, 2 already done"), "{t}");
    assert!(
        t.contains("kept 2 files of formats this run does not write (vol); --clean"),
        "{t}"
    );
    assert_eq!(std::fs::read(out.join("s_0001.vol")).unwrap(), vol);
    assert_eq!(modified("s_0001.exr"), exr_time, "the EXR is not rewritten");
    assert_eq!(modified("s_0001.png"), png_time, "the PNG is not rewritten");
    // Put back, the kept grid is still the scene's: nothing to do.
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png, Vol");
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    assert!(t.contains("0 frames rendered, 2 already done"), "{t}");
    // A scene edit the grid depends on, while the grid is left out: it stays, no longer current.
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    std::fs::write(
        dir.join("c.ron"),
        std::fs::read_to_string(dir.join("c.ron"))
            .unwrap()
            .replace("seed: 3", "seed: 4"),
    )
    .unwrap();
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    assert!(t.contains("2 frames rendered"), "{t}");
    assert!(t.contains("2 of them no longer current"), "{t}");
    assert_eq!(std::fs::read(out.join("s_0001.vol")).unwrap(), vol);
    // Only --clean removes them.
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2", "--clean"]));
    assert!(
        t.contains("removed 2 files of formats this run does not write (vol)"),
        "{t}"
    );
    assert!(!out.join("s_0001.vol").exists());
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2"]));
    assert!(t.contains("0 frames rendered, 2 already done"), "{t}");
    assert!(!t.contains("kept"), "{t}");
    // A grid added needs no render of the images.
    let exr = std::fs::read(out.join("s_0001.exr")).unwrap();
    let exr_time = modified("s_0001.exr");
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..2", "--formats", "vol"]));
    assert!(t.contains("2 formats added: +vol"), "{t}");
    assert!(out.join("s_0001.vol").is_file());
    assert_eq!(modified("s_0001.exr"), exr_time, "a grid needs no render");
    assert_eq!(std::fs::read(out.join("s_0001.exr")).unwrap(), exr);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn following_the_usd_hint_keeps_every_finished_frame() {
    // `nephele usd` says to add the VDBs with `render --formats vdb`: that run writes the VDBs
    // and leaves the finished EXRs and PNGs as they are.
    let dir = temp_dir("usd-hint");
    let out = dir.join("out");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    run(nephele(&dir).args(["render", "c.ron", "--frames", "1..4"]));
    let before: Vec<(PathBuf, Vec<u8>)> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "exr" || x == "png"))
        .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
        .collect();
    assert_eq!(before.len(), 8);
    let t = run(nephele(&dir).args(["usd", "c.ron"]));
    assert!(t.contains("--formats vdb"), "{t}");
    run(nephele(&dir).args(["render", "c.ron", "--frames", "1..4", "--formats", "vdb"]));
    for (p, bytes) in &before {
        assert_eq!(&std::fs::read(p).unwrap(), bytes, "{}", p.display());
    }
    assert!(out.join("s_0004.vdb").is_file());
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..4"]));
    assert!(t.contains("0 frames rendered, 4 already done"), "{t}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Rewrite the manifest at `path` through `edit`, its check hash recomputed (as anyone can).
fn forge_manifest(path: &Path, edit: impl FnOnce(&mut nephele::scene::provenance::Manifest)) {
    use nephele::scene::provenance::{Manifest, hash_text};
    let mut m: Manifest = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    edit(&mut m);
    m.check = hash_text(m.check_hash());
    std::fs::write(path, m.to_text()).unwrap();
}

#[test]
fn nothing_outside_the_frames_folder_is_touched() {
    use nephele::scene::provenance::ListedFile;
    let dir = temp_dir("outside");
    let out = dir.join("out");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png");
    run(nephele(&dir).args(["render", "c.ron", "--frames", "1..4"]));
    let victim = dir.join("victim");
    std::fs::write(&victim, b"an artist's file").unwrap();
    let survives = || assert_eq!(std::fs::read(&victim).unwrap(), b"an artist's file");
    // A manifest naming files elsewhere (check hash recomputed) is not trusted, even with
    // --clean and --force: the frame is rendered again and nothing it lists is removed.
    for name in [
        "../victim".to_string(),
        victim.to_string_lossy().into_owned(),
        "sub/s_0002.png".into(),
        "s_0003.png".into(),
    ] {
        let m = out.join("s_0002.manifest.json");
        forge_manifest(&m, |m| {
            m.files.push(ListedFile {
                name: name.clone(),
                kind: "png".into(),
                hash: "0000000000000000".into(),
                bytes: 16,
                blake3: String::new(),
            })
        });
        let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "2", "--clean"]));
        assert!(
            t.contains("not a file nephele writes for this frame"),
            "{name}: {t}"
        );
        survives();
        assert!(out.join("s_0003.png").is_file());
        forge_manifest(&m, |m| {
            m.files.push(ListedFile {
                name: name.clone(),
                kind: "exr".into(),
                hash: "0000000000000000".into(),
                bytes: 16,
                blake3: String::new(),
            })
        });
        run(nephele(&dir).args(["render", "c.ron", "--frames", "2", "--force", "--clean"]));
        survives();
    }
    // Links planted at a frame's lock, manifest or file names are never written through.
    std::os::unix::fs::symlink("../victim", out.join(".s_0003.lock")).unwrap();
    let t = fails(nephele(&dir).args(["render", "c.ron", "--frames", "3", "--force"]));
    assert!(t.contains(".s_0003.lock: is a symbolic link"), "{t}");
    survives();
    std::fs::remove_file(out.join(".s_0003.lock")).unwrap();
    for file in ["s_0003.manifest.json", "s_0003.png", "s_0003.exr"] {
        std::fs::remove_file(out.join(file)).unwrap();
        std::os::unix::fs::symlink("../victim", out.join(file)).unwrap();
        let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "3"]));
        assert!(t.contains("1 frames rendered"), "{file}: {t}");
        survives();
        assert!(
            !out.join(file).is_symlink(),
            "{file} is nephele's own file again"
        );
    }
    // A link to a copy of the frame's own file is not counted done either.
    std::fs::copy(out.join("s_0004.png"), dir.join("copy.png")).unwrap();
    std::fs::remove_file(out.join("s_0004.png")).unwrap();
    std::os::unix::fs::symlink("../copy.png", out.join("s_0004.png")).unwrap();
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "4"]));
    assert!(t.contains("1 frames rendered"), "{t}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn corrupted_bytes_are_never_counted_done() {
    let dir = temp_dir("bytes");
    let out = dir.join("out");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Exr, Png, Vdb");
    run(nephele(&dir).args(["render", "c.ron", "--frames", "1..4"]));
    let originals: Vec<Vec<u8>> = ["s_0001.png", "s_0002.exr", "s_0003.vdb"]
        .iter()
        .map(|f| std::fs::read(out.join(f)).unwrap())
        .collect();
    // A PNG overwritten by as many pseudo-random bytes.
    let png = out.join("s_0001.png");
    let n = originals[0].len();
    let noise: Vec<u8> = (0..n as u64)
        .map(|i| (i.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 56) as u8)
        .collect();
    std::fs::write(&png, &noise).unwrap();
    // An EXR with its header intact and one byte of its pixel chunks changed.
    let exr = out.join("s_0002.exr");
    let mut bytes = originals[1].clone();
    let at = bytes.len() - 20;
    bytes[at] ^= 0x40;
    std::fs::write(&exr, &bytes).unwrap();
    // A VDB with one bit flipped in its middle.
    let vdb = out.join("s_0003.vdb");
    let mut bytes = originals[2].clone();
    let at = bytes.len() / 2;
    bytes[at] ^= 1;
    std::fs::write(&vdb, &bytes).unwrap();
    let t = run(nephele(&dir).args(["render", "c.ron", "--frames", "1..4"]));
    assert!(t.contains("3 frames rendered, 1 already done"), "{t}");
    assert!(t.contains("3 files replaced since their manifest"), "{t}");
    for (f, original) in ["s_0001.png", "s_0002.exr", "s_0003.vdb"]
        .iter()
        .zip(&originals)
    {
        assert_eq!(
            &std::fs::read(out.join(f)).unwrap(),
            original,
            "{f} rendered again"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn duplicate_formats_are_refused() {
    let dir = temp_dir("dup");
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Png, Exr, Png");
    let t = fails(nephele(&dir).args(["render", "c.ron"]));
    assert!(
        t.contains("c.ron:1:172: output.formats: png is listed twice"),
        "{t}"
    );
    write_scene(&dir, "c", "(1.0, -1.0, 0.0)", 24, "Png");
    let t = fails(nephele(&dir).args(["render", "c.ron", "--formats", "png,exr,png"]));
    assert!(t.contains("png is listed twice"), "{t}");
    assert!(!dir.join("out").exists(), "nothing is written");
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
    // The caches' and the statistics' temporaries too; one being written (its writer holds
    // its lock) stays, and another's files are left alone.
    let dead = [
        ".target-0123abcd.ron.11-22.tmp",
        ".blend-00ff00ff00ff00ff.ron.11-22.tmp",
        ".s_stats.csv.11-22.tmp",
        ".s_0001.manifest.json.11-22.tmp",
    ];
    for name in dead {
        std::fs::write(out.join(name), b"left by a killed run").unwrap();
    }
    let live = out.join(".s_0002.exr.33-44.tmp");
    let writer = std::fs::File::create(&live).unwrap();
    writer.lock().unwrap();
    let foreign = out.join(".notes.txt.11-22.tmp");
    std::fs::write(&foreign, b"not nephele's").unwrap();
    run(nephele(&dir).args(["render", "c.ron", "--frames", "1"]));
    let mut left = temps(&out);
    left.sort();
    assert_eq!(left, [".notes.txt.11-22.tmp", ".s_0002.exr.33-44.tmp"]);
    drop(writer);
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
