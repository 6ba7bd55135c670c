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
//!
//! # What may be written into a job file
//!
//! A job file is a program: a path that ends a line in it runs the rest as a command. So every
//! value written into one — paths, names, the array spec, the program, the extra `sbatch`
//! options, the opening comment — goes through one writer, [`write_value`], which either writes
//! it quoted for its [`Place`] or refuses it with a [`Refused`] error that names the value, where
//! it came from and how to fix it; a job file with a refused value is not written at all.
//!
//! - **Everywhere**: no control character (newline, carriage return, tab, NUL, …) nor Unicode
//!   line or paragraph separator, and no path that is not UTF-8 (it could not be written
//!   exactly).
//! - **Shell words** are single-quoted (`'` written `'\''`): nothing in them expands.
//! - **`#SBATCH` lines**, which sbatch splits at whitespace and where `'`, `"`, `\` and `#` mean
//!   something: a value is double-quoted unless it holds only plain characters, `\` is written
//!   `\\`, and a `"` cannot be written (refused). In a filename pattern (`--output`) `%` is
//!   written `%%`, since Slurm expands `%j`, `%A`, `%a`, …, and `\` is refused, since it turns
//!   those expansions off.
//! - **YAML** values are double-quoted strings (JSON escapes; a Kubernetes name is left plain
//!   when YAML reads it back unchanged); a `#` comment line carries the checked text as it is.

use std::ffi::OsString;
use std::path::PathBuf;

use crate::scene::frames::selection_text;

/// Where the outside values of a [`FarmJob`] came from, as its refusals name them (e.g.
/// `--output`, "the scene's output.dir").
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Origins {
    /// Where the scene file's path came from.
    pub scene: String,
    /// Where the output folder came from (the logs folder is inside it).
    pub output: String,
    /// Where the nephele program's path came from.
    pub nephele: String,
}

impl Default for Origins {
    /// Generic names, for a job made in code rather than by `nephele farm`.
    fn default() -> Self {
        Origins {
            scene: "the scene file path".into(),
            output: "the output folder setting".into(),
            nephele: "the nephele program setting".into(),
        }
    }
}

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
    /// Where the paths above came from.
    pub origins: Origins,
}

/// How to fix a refused folder.
const RENAME_FOLDER: &str =
    "rename the folder (or choose another with --output), then run nephele farm again";

impl FarmJob {
    // The job's outside values, each with what it is, where it came from and how to fix it.

    fn scene_value(&self) -> Value {
        Value::new(
            &self.scene,
            "the scene file",
            &self.origins.scene,
            "rename the scene file (or its folder), then run nephele farm again",
        )
    }

    fn output_value(&self) -> Value {
        Value::new(
            &self.output,
            "the output folder",
            &self.origins.output,
            RENAME_FOLDER,
        )
    }

    fn logs_value(&self) -> Value {
        Value::new(
            &self.logs,
            "the logs folder",
            &self.origins.output,
            RENAME_FOLDER,
        )
    }

    fn nephele_value(&self) -> Value {
        Value::new(
            &self.nephele,
            "the nephele program",
            &self.origins.nephele,
            "install nephele at a path without such characters and give it with --nephele",
        )
    }

    /// Check the job's outside values where they could break any job file (a line break, a path
    /// that is not UTF-8) before writing one: the output folder first, so that a refusal names
    /// the folder the user gave rather than the logs folder made from it.
    pub fn check(&self) -> Result<(), Refused> {
        let values = [
            self.output_value(),
            self.scene_value(),
            self.nephele_value(),
            self.logs_value(),
        ];
        for v in &values {
            checked(v, "into a job file")?;
        }
        Ok(())
    }

    /// The prepare job's command: the program, then its arguments.
    pub fn prepare_words(&self) -> Vec<Value> {
        let mut v = vec![
            self.nephele_value(),
            Value::own("prepare"),
            self.scene_value(),
            Value::own("--output"),
            self.output_value(),
        ];
        if self.preview {
            v.push(Value::own("--preview"));
        }
        v
    }

    /// An array task's command (the program, then its arguments); `task` is the `--task` value.
    pub fn render_words(&self, task: Value) -> Vec<Value> {
        let mut v = vec![
            self.nephele_value(),
            Value::own("render"),
            self.scene_value(),
            Value::own("--output"),
            self.output_value(),
            Value::own("--frames"),
            Value::own(selection_text(&self.frames)),
            Value::own("--task"),
            task,
        ];
        if self.preview {
            v.push(Value::own("--preview"));
        }
        v
    }
}

/// A value bound for a job file: its text, what it is, where it came from and how to fix it,
/// so that the error refusing it can say all of that.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Value {
    /// The text (a path need not be UTF-8; one that is not is refused).
    pub text: OsString,
    /// What it is, e.g. "the output folder".
    pub what: &'static str,
    /// Where it came from, e.g. "--output".
    pub from: String,
    /// How to fix it when it is refused, e.g. "rename the folder".
    pub fix: &'static str,
}

impl Value {
    /// A value from outside.
    pub fn new(
        text: impl Into<OsString>,
        what: &'static str,
        from: impl Into<String>,
        fix: &'static str,
    ) -> Value {
        Value {
            text: text.into(),
            what,
            from: from.into(),
            fix,
        }
    }

    /// Text nephele makes itself (a fixed word, a frame range, a sanitized name): it goes
    /// through the writer like any value, so that nothing reaches a job file around it.
    pub fn own(text: impl Into<String>) -> Value {
        Value::new(
            text.into(),
            "nephele's own text",
            "nephele farm",
            "this is a bug in nephele; please report it",
        )
    }

    /// The error refusing this value at `place` (a [`Place`]'s name), for `why`.
    fn refused(&self, place: &'static str, why: impl Into<String>) -> Refused {
        Refused {
            what: self.what,
            text: self.text.to_string_lossy().into_owned(),
            from: self.from.clone(),
            place,
            why: why.into(),
            fix: self.fix,
        }
    }
}

/// Where in a job file a value is written; each place has its own quoting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    /// A word of a POSIX shell command: single-quoted.
    ShellWord,
    /// An `#SBATCH` option or option value: double-quoted unless plain.
    Sbatch,
    /// A value in an `#SBATCH` filename pattern (`--output`): as [`Place::Sbatch`], `%` written
    /// `%%`.
    SbatchPattern,
    /// A YAML string: double-quoted, JSON escapes.
    Yaml,
    /// A Kubernetes object name in YAML: plain when YAML reads it back as that very string,
    /// else as [`Place::Yaml`].
    YamlName,
    /// Text in a `#` comment line: as it is.
    Comment,
}

impl Place {
    fn name(self) -> &'static str {
        match self {
            Place::ShellWord => "into a job script's command",
            Place::Sbatch => "on an #SBATCH line",
            Place::SbatchPattern => "into an #SBATCH file name",
            Place::Yaml | Place::YamlName => "into a YAML manifest",
            Place::Comment => "into a job file's comment line",
        }
    }
}

/// A value [`write_value`] refused: what it is, its text, where it came from, the place, why,
/// and how to fix it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{what} {text:?} (from {from}) cannot be written {place}: {why}; {fix}")]
pub struct Refused {
    /// What the value is.
    pub what: &'static str,
    /// Its text (lossy if it is not UTF-8).
    pub text: String,
    /// Where it came from.
    pub from: String,
    /// Where it was to be written ([`Place`]).
    pub place: &'static str,
    /// Why it cannot be written there.
    pub why: String,
    /// How to fix it.
    pub fix: &'static str,
}

/// The one writer of job files: `v` checked and quoted for `place`, or refused (the rule is in
/// the module documentation).
pub fn write_value(v: &Value, place: Place) -> Result<String, Refused> {
    let text = checked(v, place.name())?;
    match place {
        Place::ShellWord => Ok(shell_quote(text)),
        Place::Sbatch => sbatch_quote(text, false).map_err(|why| v.refused(place.name(), why)),
        Place::SbatchPattern => {
            sbatch_quote(text, true).map_err(|why| v.refused(place.name(), why))
        }
        Place::Yaml => Ok(yaml_string(text)),
        Place::YamlName if yaml_plain(text) => Ok(text.to_string()),
        Place::YamlName => Ok(yaml_string(text)),
        Place::Comment => Ok(text.to_string()),
    }
}

/// `v`'s text if it may be written anywhere in a job file (UTF-8, no line breaks), else its
/// refusal for being written at `place` (a [`Place`]'s name).
fn checked<'a>(v: &'a Value, place: &'static str) -> Result<&'a str, Refused> {
    let Some(text) = v.text.to_str() else {
        return Err(v.refused(
            place,
            "it is not valid UTF-8, so it cannot be written exactly",
        ));
    };
    if let Some(c) = text.chars().find(|&c| breaks_lines(c)) {
        return Err(v.refused(
            place,
            format!(
                "it holds the control character {c:?}, and job files take none (a line break \
                 would end the line and run the rest as a shell command)"
            ),
        ));
    }
    Ok(text)
}

/// Whether `c` may not appear in a job file: control characters, and the Unicode line and
/// paragraph separators (YAML 1.1 readers, Kubernetes' among them, break lines at them).
fn breaks_lines(c: char) -> bool {
    c.is_control() || matches!(c, '\u{2028}' | '\u{2029}')
}

/// `text` (free of control characters) for an `#SBATCH` line, which sbatch splits at
/// whitespace and where `'` and `"` quote, `\` escapes and `#` starts a comment: double-quoted
/// unless it holds only plain characters, `\` written `\\`. In a filename `pattern`, `%` is
/// written `%%`. A `"` cannot be written there; nor can a `\` in a pattern, where it turns
/// Slurm's `%` expansions off. The error is the reason.
fn sbatch_quote(text: &str, pattern: bool) -> Result<String, String> {
    if text.contains('"') {
        return Err("a double quote cannot be written on an #SBATCH line".into());
    }
    if pattern && text.contains('\\') {
        return Err("a backslash in an #SBATCH file name turns off Slurm's %j, %A and %a".into());
    }
    let mut t = text.replace('\\', r"\\");
    if pattern {
        t = t.replace('%', "%%");
    }
    let plain = |c: char| c.is_ascii_alphanumeric() || "/._,:=+@%-".contains(c);
    Ok(if t.chars().all(plain) {
        t
    } else {
        format!("\"{t}\"")
    })
}

/// The Slurm batch script of the prepare job. `sbatch_args` are extra `sbatch` options (one per
/// `#SBATCH` line, e.g. `--partition=render`; see [`check_sbatch_args`]).
pub fn slurm_prepare_script(job: &FarmJob, sbatch_args: &[String]) -> Result<String, Refused> {
    let name = slurm_job_name(&job.name);
    let mut s = slurm_header(job)?;
    s.push_str(&format!(
        "#SBATCH --job-name={}\n",
        write_value(&Value::own(format!("{name}-prepare")), Place::Sbatch)?
    ));
    s.push_str(&sbatch_output(job, &name, "-prepare_%j.log")?);
    s.push_str(&extra_lines(sbatch_args)?);
    s.push_str("\nset -eu\n");
    let words = job
        .prepare_words()
        .iter()
        .map(|w| write_value(w, Place::ShellWord))
        .collect::<Result<Vec<_>, _>>()?;
    s.push_str(&format!("exec {}\n", words.join(" ")));
    Ok(s)
}

/// The Slurm batch script of the render array: `--array=0-(N-1)`, `--requeue` (frames resume)
/// and `--open-mode=append` (a requeued task's log keeps the earlier run). Submit it with
/// `--dependency=afterok:<prepare job id>`.
pub fn slurm_array_script(job: &FarmJob, sbatch_args: &[String]) -> Result<String, Refused> {
    let name = slurm_job_name(&job.name);
    let mut s = slurm_header(job)?;
    s.push_str(&format!(
        "#SBATCH --job-name={}\n",
        write_value(&Value::own(name.as_str()), Place::Sbatch)?
    ));
    let array = Value::own(format!("0-{}", job.tasks.saturating_sub(1)));
    s.push_str(&format!(
        "#SBATCH --array={}\n",
        write_value(&array, Place::Sbatch)?
    ));
    s.push_str("#SBATCH --requeue\n#SBATCH --open-mode=append\n");
    s.push_str(&sbatch_output(job, &name, "_%A_%a.log")?);
    s.push_str(&extra_lines(sbatch_args)?);
    s.push_str("\nset -eu\n");
    // The task word must expand in the shell: the variable is double-quoted script text and
    // only the `/N` after it is a written value. It is the one word equal to `task`.
    let task = Value::own(format!("/{}", job.tasks));
    let mut words = Vec::new();
    for w in job.render_words(task.clone()) {
        let quoted = write_value(&w, Place::ShellWord)?;
        words.push(if w == task {
            format!("\"${{SLURM_ARRAY_TASK_ID}}\"{quoted}")
        } else {
            quoted
        });
    }
    s.push_str(&format!("exec {}\n", words.join(" ")));
    Ok(s)
}

/// The shebang and comment line of a batch script, after checking the job's values.
fn slurm_header(job: &FarmJob) -> Result<String, Refused> {
    job.check()?;
    Ok(format!("#!/bin/bash\n{}", written_by("nephele farm", job)?))
}

/// The `#SBATCH --output` line: the logs folder and the job name as an escaped filename
/// pattern, then `pattern` (Slurm's own `%` expansions, e.g. `_%A_%a.log`).
fn sbatch_output(job: &FarmJob, name: &str, pattern: &str) -> Result<String, Refused> {
    Ok(format!(
        "#SBATCH --output={}/{}{pattern}\n",
        write_value(&job.logs_value(), Place::SbatchPattern)?,
        write_value(&Value::own(name), Place::SbatchPattern)?
    ))
}

/// The comment line that opens every job file: the command, version, scene, frames and tasks.
fn written_by(command: &str, job: &FarmJob) -> Result<String, Refused> {
    let comment = |v: &Value| write_value(v, Place::Comment);
    Ok(format!(
        "# Written by `{command}` (nephele {}): {} frames {} in {} tasks.\n",
        env!("CARGO_PKG_VERSION"),
        comment(&job.scene_value())?,
        comment(&Value::own(selection_text(&job.frames)))?,
        comment(&Value::own(job.tasks.to_string()))?
    ))
}

/// A Slurm job name: the shot's name with every character but ASCII letters, digits, `.`, `_`
/// and `-` replaced by `_` (a readable name that needs no quoting anywhere).
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
/// control character (a newline would end the `#SBATCH` line and start a shell command), a
/// double quote (it cannot be written on an `#SBATCH` line) or not starting with `-` is
/// refused, with the reason.
pub fn check_sbatch_args(sbatch_args: &[String]) -> Result<(), Refused> {
    extra_lines(sbatch_args).map(drop)
}

/// The `#SBATCH` lines of the extra options, each written by [`write_value`]; the first that is
/// refused is the error.
fn extra_lines(sbatch_args: &[String]) -> Result<String, Refused> {
    let mut lines = String::new();
    for a in sbatch_args {
        let v = Value::new(
            a.as_str(),
            "the sbatch option",
            "--sbatch-arg",
            "give each sbatch option as one line starting with -, without newlines, tabs or \
             double quotes (values with spaces are quoted for you), e.g. \
             --sbatch-arg=--partition=render",
        );
        if !a.starts_with('-') {
            return Err(v.refused(
                Place::Sbatch.name(),
                "it is not an sbatch option (they start with -)",
            ));
        }
        lines.push_str(&format!("#SBATCH {}\n", write_value(&v, Place::Sbatch)?));
    }
    Ok(lines)
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
pub fn k8s_prepare_job(job: &FarmJob, pod: &K8sPod) -> Result<String, Refused> {
    let mut s = k8s_head(job, &k8s_job_names(&job.name).prepare)?;
    s.push_str("  backoffLimit: 2\n");
    s.push_str(&k8s_pod(pod, &job.prepare_words())?);
    Ok(s)
}

/// The Kubernetes Indexed Job of the render array: `completionMode: Indexed` with `N`
/// completions; each pod runs `nephele render … --task auto/N`, which reads
/// `JOB_COMPLETION_INDEX`. A failed pod is retried (frames resume).
pub fn k8s_indexed_job(job: &FarmJob, pod: &K8sPod) -> Result<String, Refused> {
    let mut s = k8s_head(job, &k8s_job_names(&job.name).render)?;
    s.push_str(&format!(
        "  completionMode: Indexed\n  completions: {n}\n  parallelism: {n}\n  backoffLimitPerIndex: 3\n  maxFailedIndexes: 0\n",
        n = job.tasks
    ));
    let task = Value::own(format!("auto/{}", job.tasks));
    s.push_str(&k8s_pod(pod, &job.render_words(task))?);
    Ok(s)
}

/// The comment line and head of the manifest of the Job `name`, after checking the job's values.
fn k8s_head(job: &FarmJob, name: &str) -> Result<String, Refused> {
    job.check()?;
    Ok(format!(
        "{}apiVersion: batch/v1\nkind: Job\nmetadata:\n  name: {}\nspec:\n",
        written_by("nephele farm --engine k8s", job)?,
        write_value(&Value::own(name), Place::YamlName)?
    ))
}

/// The pod template running `words` (the program, then its arguments).
fn k8s_pod(pod: &K8sPod, words: &[Value]) -> Result<String, Refused> {
    let command = words
        .iter()
        .map(|w| write_value(w, Place::Yaml))
        .collect::<Result<Vec<_>, _>>()?;
    let image = Value::new(
        pod.image.as_str(),
        "the container image",
        "--image",
        "give another with --image",
    );
    let claim = Value::new(
        pod.volume_claim.as_str(),
        "the volume claim",
        "--volume-claim",
        "give another with --volume-claim",
    );
    let mount = Value::new(
        &pod.mount,
        "the volume's mount folder",
        "the folder holding both the scene file and the output folder",
        RENAME_FOLDER,
    );
    Ok(format!(
        "  template:\n    spec:\n      restartPolicy: Never\n      containers:\n      - name: nephele\n        image: {}\n        command: [{}]\n        volumeMounts:\n        - name: shared\n          mountPath: {}\n      volumes:\n      - name: shared\n        persistentVolumeClaim:\n          claimName: {}\n",
        write_value(&image, Place::Yaml)?,
        command.join(", "),
        write_value(&mount, Place::Yaml)?,
        write_value(&claim, Place::Yaml)?
    ))
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

/// Whether YAML (1.1 or 1.2) reads `text` written plain back as that very string: lowercase
/// letters, digits and `-`, starting with a letter, and not a word read as a boolean or null.
fn yaml_plain(text: &str) -> bool {
    text.starts_with(|c: char| c.is_ascii_lowercase())
        && text
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
        && !matches!(
            text,
            "y" | "n" | "yes" | "no" | "on" | "off" | "true" | "false" | "null"
        )
}

/// A YAML double-quoted scalar (JSON string syntax, which YAML accepts).
fn yaml_string(s: &str) -> String {
    serde_json::to_string(s).expect("strings always serialize")
}

/// `s` single-quoted for a POSIX shell (`'` becomes `'\''`).
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;
    use std::process::Command;

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
            origins: Origins::default(),
        }
    }

    /// `job()` with every path under the folder `hostile`.
    fn hostile_job(hostile: &str) -> FarmJob {
        let out = PathBuf::from("/farm").join(hostile);
        FarmJob {
            nephele: out.join("bin/nephele"),
            scene: out.join("shot.ron"),
            logs: out.join("preview/logs"),
            output: out,
            ..job()
        }
    }

    /// Both Slurm scripts of `job`, which must be accepted.
    fn slurm_scripts(job: &FarmJob) -> [String; 2] {
        [
            slurm_prepare_script(job, &[]).unwrap(),
            slurm_array_script(job, &[]).unwrap(),
        ]
    }

    /// The words bash makes of `script`'s `exec` line, with `SLURM_ARRAY_TASK_ID=2` (run with
    /// `printf` in place of `exec`, in an empty environment, so nothing in it can run).
    fn exec_words(script: &str) -> Vec<String> {
        let line = script.lines().find(|l| l.starts_with("exec ")).unwrap();
        let line = format!("printf '%s\\0' {}", &line["exec ".len()..]);
        let out = Command::new("bash")
            .args(["-c", &line])
            .env_clear()
            .env("SLURM_ARRAY_TASK_ID", "2")
            .current_dir(std::env::temp_dir())
            .output()
            .unwrap();
        assert!(out.status.success(), "{line}");
        let text = String::from_utf8(out.stdout).unwrap();
        text.split_terminator('\0').map(str::to_string).collect()
    }

    /// Whether `bash -n` parses `script`.
    fn bash_parses(script: &str) -> bool {
        use std::io::Write;
        let mut child = Command::new("bash")
            .arg("-n")
            .stdin(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        child
            .stdin
            .take()
            .unwrap()
            .write_all(script.as_bytes())
            .unwrap();
        child.wait().unwrap().success()
    }

    /// The arguments sbatch makes of an `#SBATCH` line's rest, as Slurm 22.05's `sbatch/opt.c`
    /// (`_get_argument`) reads them: whitespace splits, `'` and `"` quote, `\` escapes, an
    /// unquoted `#` ends the line.
    fn sbatch_words(line: &str) -> Vec<String> {
        let (mut words, mut word, mut quote) = (Vec::new(), None::<String>, None);
        let mut chars = line.chars();
        while let Some(c) = chars.next() {
            match (quote, c) {
                (_, '\\') => {
                    let next = chars.next().expect("sbatch would fail on a final \\");
                    word.get_or_insert_default().push(next);
                }
                (Some(q), c) if c == q => quote = None,
                (Some(_), c) => word.get_or_insert_default().push(c),
                (None, '"' | '\'') => {
                    quote = Some(c);
                    word.get_or_insert_default();
                }
                (None, '#') => break,
                (None, c) if c.is_whitespace() => words.extend(word.take()),
                (None, c) => word.get_or_insert_default().push(c),
            }
        }
        assert!(quote.is_none(), "sbatch would fail on {line:?}");
        words.extend(word);
        words
    }

    /// The value of the `#SBATCH --output=` option of `script`, as sbatch reads it.
    fn sbatch_output_option(script: &str) -> String {
        let words: Vec<String> = script
            .lines()
            .filter_map(|l| l.strip_prefix("#SBATCH"))
            .flat_map(sbatch_words)
            .collect();
        let outputs: Vec<&String> = words
            .iter()
            .filter(|w| w.starts_with("--output="))
            .collect();
        assert_eq!(outputs.len(), 1, "{script}");
        outputs[0]["--output=".len()..].to_string()
    }

    #[test]
    fn array_script_runs_one_chunk_per_task() {
        let s = slurm_array_script(&job(), &["--partition=render".into()]).unwrap();
        assert!(s.starts_with("#!/bin/bash\n"));
        for line in [
            "#SBATCH --array=0-3\n",
            "#SBATCH --requeue\n",
            "#SBATCH --partition=render\n",
            "#SBATCH --output=/farm/renders/duck/preview/logs/duck-diffusion-preview_%A_%a.log\n",
            "exec '/opt/nephele/bin/nephele' 'render' '/farm/scenes/duck diffusion.ron' '--output' \
             '/farm/renders/duck' '--frames' '1..96' '--task' \"${SLURM_ARRAY_TASK_ID}\"'/4' \
             '--preview'\n",
        ] {
            assert!(s.contains(line), "missing {line:?} in\n{s}");
        }
        // sbatch reads #SBATCH lines only before the first command.
        let first_command = s.find("\nset -eu").unwrap();
        assert!(s.rfind("#SBATCH").unwrap() < first_command);
        assert_eq!(exec_words(&s)[8], "2/4");
    }

    #[test]
    fn prepare_script_fits_once() {
        let s = slurm_prepare_script(&job(), &[]).unwrap();
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
        let s = k8s_indexed_job(&job(), &pod).unwrap();
        assert!(s.contains("completionMode: Indexed\n  completions: 4\n"));
        assert!(s.contains("\"--task\", \"auto/4\""));
        assert!(s.contains("mountPath: \"/farm\"\n"));
        assert!(s.contains("claimName: \"renders\"\n"));
        let prepare = k8s_prepare_job(&job(), &pod).unwrap();
        assert!(prepare.contains("name: duck-diffusion-preview-prepare\n"));
        // A name YAML would read as a number or a boolean is quoted.
        let yes = FarmJob {
            name: "yes".into(),
            ..job()
        };
        assert!(
            k8s_indexed_job(&yes, &pod)
                .unwrap()
                .contains("name: \"yes\"\n")
        );
        assert_eq!(
            write_value(&Value::own("123"), Place::YamlName).unwrap(),
            "\"123\""
        );
        let apart = FarmJob {
            output: "/tmp/out".into(),
            ..job()
        };
        assert_eq!(k8s_mount(&apart), None);
    }

    #[test]
    fn sbatch_options_cannot_inject_lines() {
        let bad = ["--comment=x\necho INJECTED".to_string()];
        let e = check_sbatch_args(&bad).unwrap_err().to_string();
        assert!(e.contains("control character '\\n'"), "{e}");
        assert!(e.contains("(from --sbatch-arg)"), "{e}");
        assert!(slurm_array_script(&job(), &bad).is_err());
        assert!(slurm_prepare_script(&job(), &bad).is_err());
        assert!(check_sbatch_args(&["--comment=\"x\"".into()]).is_err());
        assert!(check_sbatch_args(&["echo".into()]).is_err());
        let spaced = ["--comment=two words".to_string()];
        assert!(check_sbatch_args(&spaced).is_ok());
        let s = slurm_array_script(&job(), &spaced).unwrap();
        assert!(s.contains("#SBATCH \"--comment=two words\"\n"), "{s}");
        // A lone `'` would open a quote sbatch never closes; `\` is an escape there.
        let odd = ["--comment=it's".to_string(), r"--comment=a\b".to_string()];
        let s = slurm_array_script(&job(), &odd).unwrap();
        assert!(s.contains("#SBATCH \"--comment=it's\"\n"), "{s}");
        assert!(s.contains("#SBATCH \"--comment=a\\\\b\"\n"), "{s}");
        let read: Vec<String> = s
            .lines()
            .filter_map(|l| l.strip_prefix("#SBATCH"))
            .flat_map(sbatch_words)
            .filter(|w| w.starts_with("--comment"))
            .collect();
        assert_eq!(read, odd);
        let named = FarmJob {
            name: "my shot; rm -rf".into(),
            ..job()
        };
        let s = slurm_array_script(&named, &[]).unwrap();
        assert!(s.contains("#SBATCH --job-name=my_shot__rm_-rf\n"), "{s}");
    }

    #[test]
    fn hostile_folders_are_quoted_word_for_word() {
        for hostile in [
            "renders %j %A_%a 100%",
            "it's",
            "$(touch X)",
            "`touch X`",
            "two  spaces",
            "a;b&c|d>e<f",
            "shot #2",
            "$HOME ${PATH} *?[x]",
            "~user",
            "é ☁",
        ] {
            let job = hostile_job(hostile);
            for s in slurm_scripts(&job) {
                assert!(bash_parses(&s), "bash -n fails on {hostile:?}:\n{s}");
                let words = exec_words(&s);
                assert_eq!(Path::new(&words[0]), job.nephele, "{s}");
                assert_eq!(Path::new(&words[2]), job.scene, "{s}");
                assert_eq!(Path::new(&words[4]), job.output, "{s}");
                // The #SBATCH block is whole: comments up to the first blank line.
                let block: Vec<&str> = s.lines().skip(1).take_while(|l| !l.is_empty()).collect();
                assert!(block.iter().all(|l| l.starts_with('#')), "{s}");
                let logs = job.logs.to_str().unwrap().replace('%', "%%");
                assert!(
                    sbatch_output_option(&s).starts_with(&format!("{logs}/duck-diffusion-preview")),
                    "{s}"
                );
            }
            let array = slurm_array_script(&job, &[]).unwrap();
            assert!(
                array.contains("#SBATCH --array=0-3\n#SBATCH --requeue\n"),
                "{array}"
            );
            assert!(sbatch_output_option(&array).ends_with("/duck-diffusion-preview_%A_%a.log"));
            let words = exec_words(&array);
            assert_eq!(words[8], "2/4");
        }
    }

    #[test]
    fn line_breaks_are_refused_wherever_they_come_from() {
        for bad in [
            "a\nb",
            "a\rb",
            "a\tb",
            "a\0b",
            "a\u{7f}b",
            "a\u{85}b",
            "a\u{2028}b",
        ] {
            let pod = K8sPod {
                image: "nephele".into(),
                volume_claim: "claim".into(),
                mount: "/farm".into(),
            };
            let cases: [(FarmJob, &str); 4] = [
                (
                    FarmJob {
                        output: format!("/farm/{bad}").into(),
                        ..job()
                    },
                    "the output folder",
                ),
                (
                    FarmJob {
                        logs: format!("/farm/{bad}/logs").into(),
                        ..job()
                    },
                    "the logs folder",
                ),
                (
                    FarmJob {
                        scene: format!("/farm/{bad}.ron").into(),
                        ..job()
                    },
                    "the scene file",
                ),
                (
                    FarmJob {
                        nephele: format!("/farm/{bad}").into(),
                        ..job()
                    },
                    "the nephele program",
                ),
            ];
            for (job, what) in cases {
                let mut errors = vec![
                    slurm_prepare_script(&job, &[]).unwrap_err(),
                    slurm_array_script(&job, &[]).unwrap_err(),
                ];
                // The logs folder is only in the Slurm scripts.
                if what != "the logs folder" {
                    errors.push(k8s_prepare_job(&job, &pod).unwrap_err());
                    errors.push(k8s_indexed_job(&job, &pod).unwrap_err());
                }
                for e in errors {
                    assert_eq!(e.what, what);
                    let text = e.to_string();
                    assert!(text.contains("control character"), "{text}");
                    assert!(text.contains(&format!("{bad:?}")[1..4]), "{text}");
                    assert!(text.contains("(from "), "{text}");
                    assert!(
                        text.contains("rename") || text.contains("install"),
                        "{text}"
                    );
                }
            }
        }
    }

    #[test]
    fn what_sbatch_cannot_read_is_refused_only_there() {
        let pod = K8sPod {
            image: "nephele".into(),
            volume_claim: "claim".into(),
            mount: "/farm".into(),
        };
        for bad in ["say \"hi\"", r"back\slash"] {
            let job = hostile_job(bad);
            let e = slurm_array_script(&job, &[]).unwrap_err();
            assert_eq!(e.what, "the logs folder", "{e}");
            assert!(e.to_string().contains("#SBATCH"), "{e}");
            assert!(slurm_prepare_script(&job, &[]).is_err());
            // A Kubernetes manifest holds any text in a JSON-escaped string.
            let s = k8s_indexed_job(&job, &pod).unwrap();
            let output = serde_json::to_string(job.output.to_str().unwrap()).unwrap();
            assert!(s.contains(&format!("\"--output\", {output}")), "{s}");
        }
        // The program and the scene are only shell words: any printable text is fine there.
        let job = FarmJob {
            nephele: "/opt/a\"b\\c/nephele".into(),
            scene: "/farm/\"quoted\" \\.ron".into(),
            ..job()
        };
        for s in slurm_scripts(&job) {
            let words = exec_words(&s);
            assert_eq!(Path::new(&words[0]), job.nephele);
            assert_eq!(Path::new(&words[2]), job.scene);
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_path_that_is_not_utf8_is_refused() {
        use std::os::unix::ffi::OsStrExt;
        let job = FarmJob {
            output: Path::new(std::ffi::OsStr::from_bytes(b"/farm/\xff")).to_path_buf(),
            ..job()
        };
        let e = slurm_prepare_script(&job, &[]).unwrap_err();
        assert!(e.to_string().contains("not valid UTF-8"), "{e}");
    }

    #[test]
    fn the_comment_line_is_checked_too() {
        // The comment line is the first place the scene path is written: a line break there
        // would end the comment in the scripts and in the YAML manifests alike.
        let job = FarmJob {
            scene: "/farm/a\n#SBATCH --wrap=x\n.ron".into(),
            ..job()
        };
        for e in [
            slurm_array_script(&job, &[]).unwrap_err(),
            write_value(&job.scene_value(), Place::Comment).unwrap_err(),
        ] {
            assert_eq!(e.what, "the scene file", "{e}");
        }
        let fine = slurm_array_script(&hostile_job("x # y"), &[]).unwrap();
        assert!(
            fine.lines()
                .nth(1)
                .unwrap()
                .starts_with("# Written by `nephele farm`"),
            "{fine}"
        );
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
        let pattern = |s: &str| sbatch_quote(s, true);
        assert_eq!(pattern("/a b/c").unwrap(), "\"/a b/c\"");
        assert_eq!(pattern("/a/c").unwrap(), "/a/c");
        assert_eq!(pattern("/a/%j").unwrap(), "/a/%%j");
        assert_eq!(pattern("/it's #1").unwrap(), "\"/it's #1\"");
        assert!(pattern("/a\\b").is_err());
        assert!(sbatch_quote("\"", false).is_err());
    }
}
