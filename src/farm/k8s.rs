//! Kubernetes Job manifests: the prepare Job and the Indexed Job of the render array.

use std::path::PathBuf;

use super::value::{Place, Refused, Value, write_value};
use super::{FarmJob, RENAME_FOLDER, written_by};

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
