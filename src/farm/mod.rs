//! Rendering a shot on a farm: the job files of a job-array engine.
//!
//! A farm render is two jobs. The *prepare* job runs `nephele prepare`, which fits and caches
//! the target once. The *render* job is an array of `N` tasks; task `I` runs
//! `nephele render SCENE --task I/N`, which renders chunk `I` of the frames (see
//! [`crate::scene::shot::chunk`]). Frames are written atomically and finished frames are skipped, so a
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

mod k8s;
mod slurm;
mod value;

use std::path::PathBuf;

use crate::scene::shot::frames::selection_text;

pub use k8s::{
    K8sJobNames, K8sPod, k8s_indexed_job, k8s_job_names, k8s_mount, k8s_name, k8s_prepare_job,
};
pub use slurm::{check_sbatch_args, slurm_array_script, slurm_job_name, slurm_prepare_script};
use value::checked;
pub use value::{Place, Refused, Value, shell_quote, write_value};

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
    /// The command line's scene overrides, `KEY=VALUE` each (`--set`; `--size` as its two
    /// `shot.width`/`shot.height`), given to every task in order so that the tasks render the
    /// scene `nephele farm` checked.
    pub overrides: Vec<String>,
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

    fn override_values(&self) -> impl Iterator<Item = Value> + '_ {
        self.overrides.iter().flat_map(|o| {
            [
                Value::own("--set"),
                Value::new(
                    o.as_str(),
                    "a --set override",
                    "the command line's --set or --size",
                    "write the override without such characters (a line break cannot be passed)",
                ),
            ]
        })
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
        for v in values
            .iter()
            .chain(self.override_values().collect::<Vec<_>>().iter())
        {
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
        v.extend(self.override_values());
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
        v.extend(self.override_values());
        v
    }
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

#[cfg(test)]
mod tests;
