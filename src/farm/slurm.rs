//! Slurm batch scripts: the prepare job and the render array.

use super::value::{Place, Refused, Value, write_value};
use super::{FarmJob, written_by};

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
