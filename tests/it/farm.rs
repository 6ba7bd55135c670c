//! Farm rendering without a scheduler (issue 15): `render --task I/N` and `auto/N` render
//! disjoint chunks whose union is byte-identical to one whole render; tasks racing on a missing
//! target cache both succeed with the same fit; `farm` writes job files for N tasks. The real
//! Slurm run is tests/slurm.sh.

use std::path::{Path, PathBuf};

use crate::cli_support;
use crate::temp_support::temp_dir;

use cli_support::{nephele_in as bin, run, succeeded as ok, text};
use nephele::scene::chunk::ARRAY_INDEX_VARS;

/// A folder with `shot.ron`: a tiny 10-frame shot of a coarse sphere fit.
fn shot_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("nephele-farm-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("shot.ron"),
        "Scene(target: Fit(mesh: \"builtin:sphere\", blobs: 12, candidates: 200, samples: 4000), \
         shot: (width: 64, height: 36, fps: 10, seconds: 1.0), output: (formats: [Exr, Png]))",
    )
    .unwrap();
    dir
}

/// Sorted names of the files in `dir` (not folders).
fn files(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap())
        .filter(|e| e.file_type().unwrap().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn frame_files(dir: &Path) -> Vec<String> {
    files(dir)
        .into_iter()
        .filter(|n| n.starts_with("shot_"))
        .collect()
}

fn same_bytes(a: &Path, b: &Path) {
    assert_eq!(frame_files(a), frame_files(b));
    for name in frame_files(a) {
        assert!(
            std::fs::read(a.join(&name)).unwrap() == std::fs::read(b.join(&name)).unwrap(),
            "{name} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

#[test]
fn task_chunks_cover_the_shot_once_and_equal_a_whole_render() {
    let dir = shot_dir("chunks");
    run(bin(&dir).args(["render", "shot.ron", "--output", "whole"]));
    run(bin(&dir).args(["prepare", "shot.ron", "--output", "tasks"]));
    // 10 frames in 4 tasks: 3, 3, 2, 2 frames.
    let expected = ["1..3", "4..6", "7..8", "9..10"];
    let mut seen = 0;
    for (i, frames) in expected.iter().enumerate() {
        let t = run(bin(&dir)
            .args(["render", "shot.ron", "--output", "tasks"])
            .args(["--task", &format!("{i}/4")]));
        assert!(
            t.contains(&format!("task {i}/4: frames {frames} of 1..10")),
            "{t}"
        );
        let now = frame_files(&dir.join("tasks")).len();
        assert!(now > seen, "task {i} wrote nothing");
        seen = now;
    }
    same_bytes(&dir.join("whole"), &dir.join("tasks"));
    // EXR, PNG and the manifest of each of the 10 frames.
    assert_eq!(frame_files(&dir.join("tasks")).len(), 30);
    // A chunk of a --frames range.
    let t = run(bin(&dir)
        .args(["render", "shot.ron", "--output", "tasks"])
        .args(["--frames", "3..9", "--task", "2/3"]));
    assert!(t.contains("task 2/3: frames 8..9 of 3..9"), "{t}");
    assert!(t.contains("0 frames rendered, 2 already done"), "{t}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn auto_reads_each_array_engines_index_variable() {
    let dir = shot_dir("auto");
    for (k, var) in ARRAY_INDEX_VARS.iter().enumerate() {
        let out = format!("out{k}");
        let t = run(bin(&dir)
            .args(["render", "shot.ron", "--output", &out, "--task", "auto/5"])
            .env(var, "3"));
        assert!(t.contains("task 3/5: frames 7..8 of 1..10"), "{var}: {t}");
        assert_eq!(
            frame_files(&dir.join(&out)),
            [
                "shot_0007.exr",
                "shot_0007.manifest.json",
                "shot_0007.png",
                "shot_0008.exr",
                "shot_0008.manifest.json",
                "shot_0008.png"
            ],
            "{var}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn tasks_racing_on_a_missing_cache_fit_the_same_target() {
    let dir = shot_dir("race");
    run(bin(&dir).args(["prepare", "shot.ron", "--output", "ref"]));
    // Two tasks start at once without `prepare`: both fit, both rename their copy into place.
    let children: Vec<_> = (0..2)
        .map(|i| {
            bin(&dir)
                .args(["render", "shot.ron", "--output", "race"])
                .args(["--frames", "1..2", "--task", &format!("{i}/2")])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for c in children {
        ok(c.wait_with_output().unwrap());
    }
    let names = files(&dir.join("race"));
    let caches: Vec<&String> = names.iter().filter(|n| n.starts_with("target-")).collect();
    assert_eq!(caches.len(), 1, "{names:?}");
    assert!(
        !names.iter().any(|n| n.ends_with(".tmp")),
        "temporary file left: {names:?}"
    );
    assert_eq!(
        std::fs::read(dir.join("race").join(caches[0])).unwrap(),
        std::fs::read(dir.join("ref").join(caches[0])).unwrap(),
        "the racing fits differ from the prepared one"
    );
    assert_eq!(frame_files(&dir.join("race")).len(), 6);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn farm_writes_a_prepare_job_and_an_array_of_chunks() {
    let dir = shot_dir("jobs");
    let t = run(bin(&dir)
        .args(["farm", "shot.ron", "--engine", "slurm", "--chunk", "3"])
        .args(["--output", "out", "--sbatch-arg=--partition=render"])
        .args(["--nephele", "/opt/bin/nephele"]));
    assert!(
        t.starts_with("4 tasks of at most 3 frames (frames 1..10)"),
        "{t}"
    );
    let out = dir.join("out");
    let array = std::fs::read_to_string(out.join("shot.sbatch")).unwrap();
    assert!(array.contains("#SBATCH --array=0-3\n"), "{array}");
    assert!(array.contains("#SBATCH --partition=render\n"), "{array}");
    assert!(
        array.contains("'--task' \"${SLURM_ARRAY_TASK_ID}\"'/4'"),
        "{array}"
    );
    assert!(
        array.contains("exec '/opt/bin/nephele' 'render' '/"),
        "{array}"
    );
    let prepare = std::fs::read_to_string(out.join("shot.prepare.sbatch")).unwrap();
    assert!(prepare.contains("'prepare'"), "{prepare}");
    assert!(out.join("logs").is_dir());
    // The default program is this very binary, by absolute path.
    run(bin(&dir).args(["farm", "shot.ron", "--engine", "slurm", "--output", "out2"]));
    let array = std::fs::read_to_string(dir.join("out2/shot.sbatch")).unwrap();
    let exe = std::fs::canonicalize(env!("CARGO_BIN_EXE_nephele")).unwrap();
    assert!(
        array.contains(&format!("exec '{}' ", exe.display())),
        "{array}"
    );
    assert!(array.contains("#SBATCH --array=0-0\n"), "{array}");
    // Kubernetes: an Indexed Job whose pods read JOB_COMPLETION_INDEX.
    run(bin(&dir)
        .args(["farm", "shot.ron", "--engine", "k8s", "--chunk", "5"])
        .args(["--output", "out3", "--preview"]));
    let job = std::fs::read_to_string(dir.join("out3/preview/shot.k8s.yaml")).unwrap();
    assert!(
        job.contains("completionMode: Indexed\n  completions: 2\n"),
        "{job}"
    );
    assert!(
        job.contains("\"--task\", \"auto/2\", \"--preview\""),
        "{job}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A folder name that a shell would run if a job file wrote it unquoted, and that Slurm would
/// expand if it wrote it unescaped; legal on Linux and kept word for word.
const HOSTILE: &str = "out 'q' $(touch PWNED) `touch PWNED2` %j %A_%a 100% ; #1 & x";

/// The 10-frame scene of [`shot_dir`] written at `path`.
fn write_scene(path: &Path) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(
        path,
        "Scene(target: Fit(mesh: \"builtin:sphere\", blobs: 12, candidates: 200, samples: 4000), \
         shot: (width: 64, height: 36, fps: 10, seconds: 1.0), output: (formats: [Exr, Png]))",
    )
    .unwrap();
}

/// Every path under `dir` (files and folders), recursively.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut all = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            all.extend(walk(&p));
        }
        all.push(p);
    }
    all
}

/// Paths under `dir` whose name starts with `prefix`.
fn named(dir: &Path, prefix: &str) -> Vec<PathBuf> {
    walk(dir)
        .into_iter()
        .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix))
        .collect()
}

/// Run `script` with bash in `dir` as a Slurm task with `SLURM_ARRAY_TASK_ID=1` would; return
/// the arguments the fake nephele recorded in `record`.
fn run_script(script: &Path, dir: &Path, record: &Path) -> Vec<String> {
    let _ = std::fs::remove_file(record);
    let out = std::process::Command::new("bash")
        .arg(script)
        .current_dir(dir)
        .env("SLURM_ARRAY_TASK_ID", "1")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", text(&out));
    let recorded = std::fs::read_to_string(record).unwrap();
    recorded.lines().map(str::to_string).collect()
}

#[test]
fn farm_scripts_pass_hostile_folders_word_for_word() {
    let dir = temp_dir("farm-hostile");
    // The scene, the output folder and the program all sit in hostile folders.
    let scene = dir.join(HOSTILE).join("scenes").join("shot.ron");
    write_scene(&scene);
    let output = dir.join(HOSTILE).join("renders");
    let record = dir.join("args.txt");
    let fake = dir.join(HOSTILE).join("bin").join("nephele");
    std::fs::create_dir_all(fake.parent().unwrap()).unwrap();
    std::fs::write(
        &fake,
        format!(
            "#!/bin/sh\nprintf '%s\\n' \"$@\" > {}\n",
            nephele::farm::shell_quote(record.to_str().unwrap())
        ),
    )
    .unwrap();
    let mut perms = std::fs::metadata(&fake).unwrap().permissions();
    std::os::unix::fs::PermissionsExt::set_mode(&mut perms, 0o755);
    std::fs::set_permissions(&fake, perms).unwrap();
    let t = run(bin(&dir)
        .arg("farm")
        .arg(&scene)
        .args(["--engine", "slurm", "--chunk", "5", "--output"])
        .arg(&output)
        .arg("--nephele")
        .arg(&fake));
    assert!(t.starts_with("2 tasks of at most 5 frames"), "{t}");
    let (scene, output) = (scene.to_str().unwrap(), output.to_str().unwrap());
    let prepare = Path::new(output).join("shot.prepare.sbatch");
    let array = Path::new(output).join("shot.sbatch");
    for script in [&prepare, &array] {
        let check = std::process::Command::new("bash")
            .arg("-n")
            .arg(script)
            .output()
            .unwrap();
        assert!(
            check.status.success(),
            "bash -n {}: {}",
            script.display(),
            text(&check)
        );
        // Slurm reads the logs' path from the --output line: `%` doubled, Slurm's own kept.
        let body = std::fs::read_to_string(script).unwrap();
        let logs = format!("{output}/logs").replace('%', "%%");
        assert!(
            body.contains(&format!("\n#SBATCH --output=\"{logs}\"/shot")),
            "{body}"
        );
    }
    assert_eq!(
        run_script(&prepare, &dir, &record),
        ["prepare", scene, "--output", output]
    );
    assert_eq!(
        run_script(&array, &dir, &record),
        [
            "render", scene, "--output", output, "--frames", "1..10", "--task", "1/2"
        ]
    );
    assert_eq!(named(&dir, "PWNED"), Vec::<PathBuf>::new());
}

#[test]
fn farm_refuses_a_line_break_in_any_path_and_writes_nothing() {
    let dir = temp_dir("farm-newline");
    write_scene(&dir.join("shot.ron"));
    // A file name may hold a newline on Linux.
    write_scene(&dir.join("two\nlines.ron"));
    std::fs::write(
        dir.join("dir.ron"),
        "Scene(target: Fit(mesh: \"builtin:sphere\", blobs: 12, candidates: 200, samples: 4000), \
         shot: (width: 64, height: 36, fps: 10, seconds: 1.0), \
         output: (dir: \"renders\\nx\", formats: [Exr, Png]))",
    )
    .unwrap();
    let mut before = walk(&dir);
    before.sort();
    let cases: [(&[&str], &[&str]); 6] = [
        (
            &["shot.ron", "--engine", "slurm", "--output", "out\nx"],
            &["the output folder", "(from --output", "rename the folder"],
        ),
        (
            &["shot.ron", "--engine", "k8s", "--output", "out\nx"],
            &["the output folder", "(from --output", "rename the folder"],
        ),
        (
            &["two\nlines.ron", "--engine", "slurm", "--output", "out"],
            &[
                "the scene file",
                "(from the scene file path",
                "rename the scene file",
            ],
        ),
        (
            &["two\nlines.ron", "--engine", "k8s", "--output", "out"],
            &[
                "the scene file",
                "(from the scene file path",
                "rename the scene file",
            ],
        ),
        (
            &["dir.ron", "--engine", "slurm"],
            &[
                "the output folder",
                "(from the scene's output.dir",
                "rename the folder",
            ],
        ),
        (
            &["shot.ron", "--engine", "slurm", "--output", "out"],
            &["the nephele program", "(from --nephele"],
        ),
    ];
    for (i, (args, names)) in cases.iter().enumerate() {
        let mut c = bin(&dir);
        c.arg("farm").args(*args);
        if i == 5 {
            c.args(["--nephele", "/opt/nephele\n/bin/nephele"]);
        }
        let out = c.output().unwrap();
        let t = text(&out);
        assert!(!out.status.success(), "{args:?}: {t}");
        for n in names.iter().chain(&["control character '\\n'"]) {
            assert!(t.contains(n), "{args:?}: no {n:?} in: {t}");
        }
        // No job file, no folder: nothing was written.
        let mut after = walk(&dir);
        after.sort();
        assert_eq!(after, before, "{args:?}: {t}");
    }
}
