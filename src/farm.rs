//! Rendering a shot on a farm: the job files of a job-array engine.
//!
//! A farm render is two jobs. The *prepare* job runs `nephele prepare`, which fits and caches
//! the target once. The *render* job is an array of `N` tasks; task `I` runs
//! `nephele render SCENE --task I/N`, which renders chunk `I` of the frames (see
//! [`crate::scene::chunk`]). Frames are written atomically and finished frames are skipped, so a
//! task that is killed and requeued resumes where it stopped, and a task that starts without the
//! cache refits the same target deterministically and renames its own copy into place.
//!
//! This module only writes text: Slurm batch scripts ([`slurm_prepare_script`],
//! [`slurm_array_script`]) and Kubernetes Job manifests ([`k8s_prepare_job`],
//! [`k8s_indexed_job`]). Every path in them is absolute, so they work from any folder.

use std::path::{Path, PathBuf};

use crate::scene::frames::selection_text;

/// One shot to render on a farm.
#[derive(Clone, Debug, PartialEq)]
pub struct FarmJob {
    /// Job name (the scene's frame prefix, `-preview` added for previews).
    pub name: String,
    /// The nephele program the tasks run (absolute path, or a name on the nodes' `PATH`).
    pub nephele: PathBuf,
    /// The scene file (absolute).
    pub scene: PathBuf,
    /// The output folder given to every task as `--output` (absolute).
    pub output: PathBuf,
    /// Frame numbers (sorted), split among the tasks.
    pub frames: Vec<u32>,
    /// Number of array tasks.
    pub tasks: u32,
    /// Render previews (`--preview`).
    pub preview: bool,
    /// Folder of the tasks' logs (absolute; must exist before the jobs start).
    pub logs: PathBuf,
}

impl FarmJob {
    /// Arguments of the prepare job's `nephele` command.
    pub fn prepare_args(&self) -> Vec<String> {
        let mut v = vec![
            "prepare".to_string(),
            path_text(&self.scene),
            "--output".into(),
            path_text(&self.output),
        ];
        if self.preview {
            v.push("--preview".into());
        }
        v
    }

    /// Arguments of an array task's `nephele` command; `task` is the `--task` value.
    pub fn render_args(&self, task: &str) -> Vec<String> {
        let mut v = vec![
            "render".to_string(),
            path_text(&self.scene),
            "--output".into(),
            path_text(&self.output),
            "--frames".into(),
            selection_text(&self.frames),
            "--task".into(),
            task.into(),
        ];
        if self.preview {
            v.push("--preview".into());
        }
        v
    }
}

/// The Slurm batch script of the prepare job. `sbatch_args` are extra `sbatch` options (one per
/// `#SBATCH` line, e.g. `--partition=render`).
pub fn slurm_prepare_script(job: &FarmJob, sbatch_args: &[String]) -> String {
    let mut s = slurm_header(job);
    s.push_str(&format!(
        "#SBATCH --job-name={}-prepare\n",
        slurm_job_name(&job.name)
    ));
    s.push_str(&format!(
        "#SBATCH --output={}\n",
        sbatch_path(
            &job.logs
                .join(format!("{}-prepare_%j.log", slurm_job_name(&job.name)))
        )
    ));
    s.push_str(&extra_lines(sbatch_args));
    s.push_str("\nset -eu\n");
    s.push_str(&format!(
        "exec {}\n",
        shell_command(&job.nephele, &job.prepare_args())
    ));
    s
}

/// The Slurm batch script of the render array: `--array=0-(N-1)`, `--requeue` (frames resume)
/// and `--open-mode=append` (a requeued task's log keeps the earlier run). Submit it with
/// `--dependency=afterok:<prepare job id>`.
pub fn slurm_array_script(job: &FarmJob, sbatch_args: &[String]) -> String {
    let mut s = slurm_header(job);
    s.push_str(&format!(
        "#SBATCH --job-name={}\n",
        slurm_job_name(&job.name)
    ));
    s.push_str(&format!("#SBATCH --array=0-{}\n", job.tasks - 1));
    s.push_str("#SBATCH --requeue\n#SBATCH --open-mode=append\n");
    s.push_str(&format!(
        "#SBATCH --output={}\n",
        sbatch_path(
            &job.logs
                .join(format!("{}_%A_%a.log", slurm_job_name(&job.name)))
        )
    ));
    s.push_str(&extra_lines(sbatch_args));
    s.push_str("\nset -eu\n");
    // The task word is the one that must expand in the shell, so it is double-quoted; it is
    // passed as "" (no other argument is empty) and swapped after quoting.
    let task = format!("\"${{SLURM_ARRAY_TASK_ID}}/{}\"", job.tasks);
    let words: Vec<String> = std::iter::once(path_text(&job.nephele))
        .chain(job.render_args(""))
        .map(|w| {
            if w.is_empty() {
                task.clone()
            } else {
                shell_quote(&w)
            }
        })
        .collect();
    s.push_str(&format!("exec {}\n", words.join(" ")));
    s
}

fn slurm_header(job: &FarmJob) -> String {
    format!("#!/bin/bash\n{}", written_by("nephele farm", job))
}

/// The comment line that opens every job file: the command, version, scene, frames and tasks.
fn written_by(command: &str, job: &FarmJob) -> String {
    format!(
        "# Written by `{command}` (nephele {}): {} frames {} in {} tasks.\n",
        env!("CARGO_PKG_VERSION"),
        path_text(&job.scene),
        selection_text(&job.frames),
        job.tasks
    )
}

/// A path as an `#SBATCH` option value: double-quoted when it holds whitespace (sbatch splits
/// `#SBATCH` lines on whitespace outside quotes).
fn sbatch_path(p: &Path) -> String {
    let t = path_text(p);
    if t.contains(char::is_whitespace) {
        format!("\"{t}\"")
    } else {
        t
    }
}

/// A Slurm job name: the shot's name with every character but ASCII letters, digits, `.`, `_`
/// and `-` replaced by `_` (nothing in it can end an `#SBATCH` line or start a shell word).
pub fn slurm_job_name(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() { "nephele".into() } else { s }
}

/// Check the extra `sbatch` options before they go into a batch script: an option holding a
/// control character (a newline would end the `#SBATCH` line and start a shell command) or a
/// double quote (it cannot be quoted on an `#SBATCH` line) is refused, with the reason.
pub fn check_sbatch_args(sbatch_args: &[String]) -> Result<(), String> {
    for a in sbatch_args {
        if let Some(c) = a.chars().find(|c| c.is_control()) {
            return Err(format!(
                "--sbatch-arg {a:?}: holds the control character {c:?}; give each sbatch option \
                 as one line without newlines or tabs"
            ));
        }
        if a.contains('"') {
            return Err(format!(
                "--sbatch-arg {a:?}: a double quote cannot be written on an #SBATCH line; \
                 leave it out (values with spaces are quoted for you)"
            ));
        }
        if !a.starts_with('-') {
            return Err(format!(
                "--sbatch-arg {a:?}: not an sbatch option (they start with -, e.g. \
                 --sbatch-arg=--partition=render)"
            ));
        }
    }
    Ok(())
}

/// The `#SBATCH` lines of the extra options (checked by [`check_sbatch_args`]), each
/// double-quoted when it holds whitespace (sbatch splits `#SBATCH` lines on whitespace outside
/// quotes); an option that would not be safe on such a line is left out.
fn extra_lines(sbatch_args: &[String]) -> String {
    sbatch_args
        .iter()
        .filter(|a| check_sbatch_args(std::slice::from_ref(a)).is_ok())
        .map(|a| {
            if a.contains(char::is_whitespace) {
                format!("#SBATCH \"{a}\"\n")
            } else {
                format!("#SBATCH {a}\n")
            }
        })
        .collect()
}

/// Where the pods of a Kubernetes job run.
#[derive(Clone, Debug, PartialEq)]
pub struct K8sPod {
    /// Container image holding nephele.
    pub image: String,
    /// PersistentVolumeClaim holding the scene and output folders.
    pub volume_claim: String,
    /// Where the claim is mounted: a folder holding the scene and the output folder, so that
    /// every path is the same inside the pods ([`k8s_mount`]).
    pub mount: PathBuf,
}

/// The Kubernetes Job that runs the prepare step.
pub fn k8s_prepare_job(job: &FarmJob, pod: &K8sPod) -> String {
    let mut s = k8s_head(job, &k8s_job_names(&job.name).prepare);
    s.push_str("  backoffLimit: 2\n");
    s.push_str(&k8s_pod(job, pod, &job.prepare_args()));
    s
}

/// The Kubernetes Indexed Job of the render array: `completionMode: Indexed` with `N`
/// completions; each pod runs `nephele render … --task auto/N`, which reads
/// `JOB_COMPLETION_INDEX`. A failed pod is retried (frames resume).
pub fn k8s_indexed_job(job: &FarmJob, pod: &K8sPod) -> String {
    let mut s = k8s_head(job, &k8s_job_names(&job.name).render);
    s.push_str(&format!(
        "  completionMode: Indexed\n  completions: {n}\n  parallelism: {n}\n  backoffLimitPerIndex: 3\n  maxFailedIndexes: 0\n",
        n = job.tasks
    ));
    let task = format!("auto/{}", job.tasks);
    s.push_str(&k8s_pod(job, pod, &job.render_args(&task)));
    s
}

fn k8s_head(job: &FarmJob, name: &str) -> String {
    format!(
        "{}apiVersion: batch/v1\nkind: Job\nmetadata:\n  name: {name}\nspec:\n",
        written_by("nephele farm --engine k8s", job)
    )
}

fn k8s_pod(job: &FarmJob, pod: &K8sPod, args: &[String]) -> String {
    let command: Vec<String> = std::iter::once(path_text(&job.nephele))
        .chain(args.iter().cloned())
        .map(|a| yaml_string(&a))
        .collect();
    format!(
        "  template:\n    spec:\n      restartPolicy: Never\n      containers:\n      - name: nephele\n        image: {}\n        command: [{}]\n        volumeMounts:\n        - name: shared\n          mountPath: {}\n      volumes:\n      - name: shared\n        persistentVolumeClaim:\n          claimName: {}\n",
        yaml_string(&pod.image),
        command.join(", "),
        yaml_string(&path_text(&pod.mount)),
        yaml_string(&pod.volume_claim)
    )
}

/// A Kubernetes object name: lowercase letters, digits and `-`, at most 63 characters.
pub fn k8s_name(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() {
                c.to_ascii_lowercase()
            } else {
                '-'
            }
        })
        .collect();
    let s = s.trim_matches('-');
    let s: String = s.chars().take(55).collect();
    if s.is_empty() { "nephele".into() } else { s }
}

/// The names of a shot's two Kubernetes Jobs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct K8sJobNames {
    /// The prepare Job: the render Job's name and `-prepare` (at most 63 characters).
    pub prepare: String,
    /// The Indexed Job of the render array ([`k8s_name`] of the shot's job name).
    pub render: String,
}

/// The names of the Jobs of a shot whose job name is `name`: the one place they are made, for
/// the manifests and for the instructions printed beside them.
pub fn k8s_job_names(name: &str) -> K8sJobNames {
    let render = k8s_name(name);
    K8sJobNames {
        prepare: format!("{render}-prepare"),
        render,
    }
}

/// The deepest folder holding both the scene file and the output folder (absolute paths), or
/// `None` when that is the root, which cannot be a volume's mount point.
pub fn k8s_mount(job: &FarmJob) -> Option<PathBuf> {
    let folder = job.scene.parent()?;
    let mut common = PathBuf::new();
    for (a, b) in folder.components().zip(job.output.components()) {
        if a != b {
            break;
        }
        common.push(a);
    }
    (common.components().count() > 1).then_some(common)
}

/// A YAML double-quoted scalar (JSON string syntax, which YAML accepts).
fn yaml_string(s: &str) -> String {
    serde_json::to_string(s).expect("strings always serialize")
}

fn path_text(p: &Path) -> String {
    p.to_string_lossy().into_owned()
}

/// `program args…` with every word single-quoted for a POSIX shell.
pub fn shell_command(program: &Path, args: &[String]) -> String {
    std::iter::once(path_text(program))
        .chain(args.iter().cloned())
        .map(|w| shell_quote(&w))
        .collect::<Vec<_>>()
        .join(" ")
}

/// `s` single-quoted for a POSIX shell (`'` becomes `'\''`).
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job() -> FarmJob {
        FarmJob {
            name: "duck-diffusion-preview".into(),
            nephele: "/opt/nephele/bin/nephele".into(),
            scene: "/farm/scenes/duck diffusion.ron".into(),
            output: "/farm/renders/duck".into(),
            frames: (1..=96).collect(),
            tasks: 4,
            preview: true,
            logs: "/farm/renders/duck/preview/logs".into(),
        }
    }

    #[test]
    fn array_script_runs_one_chunk_per_task() {
        let s = slurm_array_script(&job(), &["--partition=render".into()]);
        assert!(s.starts_with("#!/bin/bash\n"));
        for line in [
            "#SBATCH --array=0-3\n",
            "#SBATCH --requeue\n",
            "#SBATCH --partition=render\n",
            "#SBATCH --output=/farm/renders/duck/preview/logs/duck-diffusion-preview_%A_%a.log\n",
            "exec '/opt/nephele/bin/nephele' 'render' '/farm/scenes/duck diffusion.ron' '--output' \
             '/farm/renders/duck' '--frames' '1..96' '--task' \"${SLURM_ARRAY_TASK_ID}/4\" '--preview'\n",
        ] {
            assert!(s.contains(line), "missing {line:?} in\n{s}");
        }
        // sbatch reads #SBATCH lines only before the first command.
        let first_command = s.find("\nset -eu").unwrap();
        assert!(s.rfind("#SBATCH").unwrap() < first_command);
    }

    #[test]
    fn prepare_script_fits_once() {
        let s = slurm_prepare_script(&job(), &[]);
        assert!(s.contains("#SBATCH --job-name=duck-diffusion-preview-prepare\n"));
        assert!(s.contains(
            "exec '/opt/nephele/bin/nephele' 'prepare' '/farm/scenes/duck diffusion.ron' '--output' '/farm/renders/duck' '--preview'\n"
        ));
    }

    #[test]
    fn indexed_job_reads_the_completion_index() {
        let pod = K8sPod {
            image: "registry/nephele:0.1".into(),
            volume_claim: "renders".into(),
            mount: k8s_mount(&job()).unwrap(),
        };
        let s = k8s_indexed_job(&job(), &pod);
        assert!(s.contains("completionMode: Indexed\n  completions: 4\n"));
        assert!(s.contains("\"--task\", \"auto/4\""));
        assert!(s.contains("mountPath: \"/farm\"\n"));
        assert!(s.contains("claimName: \"renders\"\n"));
        assert!(k8s_prepare_job(&job(), &pod).contains("name: duck-diffusion-preview-prepare\n"));
        let apart = FarmJob {
            output: "/tmp/out".into(),
            ..job()
        };
        assert_eq!(k8s_mount(&apart), None);
    }

    #[test]
    fn sbatch_options_cannot_inject_lines() {
        let bad = ["--comment=x\necho INJECTED".to_string()];
        let e = check_sbatch_args(&bad).unwrap_err();
        assert!(e.contains("control character"), "{e}");
        for s in [
            slurm_array_script(&job(), &bad),
            slurm_prepare_script(&job(), &bad),
        ] {
            assert!(!s.contains("INJECTED"), "{s}");
        }
        assert!(check_sbatch_args(&["--comment=\"x\"".into()]).is_err());
        assert!(check_sbatch_args(&["echo".into()]).is_err());
        let spaced = ["--comment=two words".to_string()];
        assert!(check_sbatch_args(&spaced).is_ok());
        let s = slurm_array_script(&job(), &spaced);
        assert!(s.contains("#SBATCH \"--comment=two words\"\n"), "{s}");
        let named = FarmJob {
            name: "my shot; rm -rf".into(),
            ..job()
        };
        let s = slurm_array_script(&named, &[]);
        assert!(s.contains("#SBATCH --job-name=my_shot__rm_-rf\n"), "{s}");
    }

    #[test]
    fn quoting_survives_quotes() {
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
        assert_eq!(k8s_name("Duck_Diffusion.v2"), "duck-diffusion-v2");
        // One function names both jobs: `shot_` is `shot` and `shot-prepare`, and a long name
        // keeps its prepare job within Kubernetes' 63 characters.
        let names = k8s_job_names("shot_");
        assert_eq!(
            (names.render.as_str(), names.prepare.as_str()),
            ("shot", "shot-prepare")
        );
        let long = k8s_job_names(&"a".repeat(60));
        assert_eq!(long.render.len(), 55);
        assert_eq!(long.prepare, format!("{}-prepare", long.render));
        assert!(long.prepare.len() <= 63);
        assert_eq!(sbatch_path(Path::new("/a b/c")), "\"/a b/c\"");
        assert_eq!(sbatch_path(Path::new("/a/c")), "/a/c");
    }
}
