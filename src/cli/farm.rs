//! `nephele farm`: write (and optionally submit) the jobs that render a shot on a farm — a
//! prepare job, then an array of one task per frame chunk. See [`nephele::farm`].

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{Context, bail};
use nephele::farm::{self, FarmJob, K8sPod};
use nephele::scene::{self, RenderOptions, Shot, chunk};

use nephele::scene::frames::FrameSelection;

/// The job-array engine to write jobs for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Engine {
    /// Slurm: two batch scripts (prepare, then a job array depending on it).
    Slurm,
    /// Kubernetes: two Job manifests (prepare, then an Indexed Job).
    K8s,
}

/// Arguments of `nephele farm`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (RON); see scenes/README.md.
    pub scene: PathBuf,
    /// The job-array engine.
    #[arg(long, value_enum)]
    pub engine: Engine,
    /// At most this many frames per task: the frames are cut into ceil(frames / CHUNK)
    /// contiguous chunks of balanced sizes [default: 10, or all frames if fewer].
    #[arg(long)]
    pub chunk: Option<u32>,
    /// Frames to render, as for `render --frames` (default: the scene's `frames`, else the
    /// whole shot).
    #[arg(long)]
    pub frames: Option<FrameSelection>,
    /// Render previews (`render --preview`): the jobs then live in <output>/preview/.
    #[arg(long)]
    pub preview: bool,
    /// Output folder (default: the scene's `output.dir`); the job files are written in the
    /// frames folder, the logs in its logs/ subfolder.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Submit the jobs with `sbatch --parsable` (Slurm only) and print their ids.
    #[arg(long)]
    pub submit: bool,
    /// An extra sbatch option for both jobs, e.g. `--sbatch-arg=--partition=render`
    /// (repeatable).
    #[arg(long = "sbatch-arg", value_name = "ARG", allow_hyphen_values = true)]
    pub sbatch_args: Vec<String>,
    /// The nephele program the tasks run (default: this program's absolute path for Slurm,
    /// `nephele` on the image's PATH for k8s).
    #[arg(long, value_name = "PATH")]
    pub nephele: Option<PathBuf>,
    /// Container image holding nephele (k8s).
    #[arg(long, default_value = "nephele:latest")]
    pub image: String,
    /// PersistentVolumeClaim holding the scene and output folders (k8s); it is mounted at
    /// their common ancestor so every path is the same in the pods.
    #[arg(long, default_value = "nephele-shared")]
    pub volume_claim: String,
    /// `--set KEY=VALUE` and `--size WxH`: checked here, and given to every task.
    #[command(flatten)]
    pub scene_args: super::common::SceneArgs,
}

/// Frames per task when `--chunk` is not given.
const DEFAULT_CHUNK: u32 = 10;

/// Run `nephele farm`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.submit && args.engine == Engine::K8s {
        bail!(
            "--submit submits to Slurm only; apply the k8s manifests with kubectl (README, \"Rendering on a farm\")"
        );
    }
    farm::check_sbatch_args(&args.sbatch_args)?;
    let scene = args.scene_args.load(&args.scene)?;
    let opts = RenderOptions {
        frames: args.frames.clone(),
        output: args.output.clone(),
        preview: args.preview,
        ..RenderOptions::default()
    };
    let shot = Shot::open(scene, &opts)?;
    let scene = shot.scene();
    let chunk_frames = args
        .chunk
        .unwrap_or(DEFAULT_CHUNK.min(chunk::frame_count(shot.frames())));
    let tasks = chunk::task_count(shot.frames(), chunk_frames)?;
    let job = farm_job(&args, &shot, tasks)?;
    // Both job files are made in memory first: a refused value writes nothing.
    let files = job_files(&args, &job, &scene.name)?;
    let job_dir = std::path::absolute(shot.dir())
        .with_context(|| format!("resolving {}", shot.dir().display()))?;
    shot.check_writable()?;
    if args.engine == Engine::Slurm {
        std::fs::create_dir_all(&job.logs)
            .with_context(|| format!("creating {}", job.logs.display()))?;
    }
    let write = |(name, text): (String, String)| -> anyhow::Result<PathBuf> {
        let path = job_dir.join(name);
        nephele::atomic::write_bytes_atomically(&path, text.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(path)
    };
    let [prepare, array] = files;
    let (prepare, array) = (write(prepare)?, write(array)?);
    println!(
        "{} tasks of at most {} frames (frames {}):\n  {}\n  {}",
        tasks,
        chunk_frames,
        nephele::scene::frames::selection_text(shot.frames()),
        prepare.display(),
        array.display()
    );
    match (args.engine, args.submit) {
        (Engine::Slurm, true) => submit(&prepare, &array, tasks),
        (Engine::Slurm, false) => {
            println!(
                "submit with:\n  prep=$(sbatch --parsable {})\n  sbatch --dependency=afterok:$prep {}",
                farm::shell_quote(&prepare.to_string_lossy()),
                farm::shell_quote(&array.to_string_lossy())
            );
            Ok(())
        }
        (Engine::K8s, _) => {
            let prep_job = farm::k8s_job_names(&job.name).prepare;
            println!(
                "run with:\n  kubectl apply -f {}\n  kubectl wait --for=condition=complete --timeout=1h job/{prep_job}\n  kubectl apply -f {}",
                farm::shell_quote(&prepare.to_string_lossy()),
                farm::shell_quote(&array.to_string_lossy())
            );
            Ok(())
        }
    }
}

/// The job of `shot` in `tasks` tasks, every path absolute.
fn farm_job(args: &Args, shot: &Shot, tasks: u32) -> anyhow::Result<FarmJob> {
    let absolute =
        |p: &Path| std::path::absolute(p).with_context(|| format!("resolving {}", p.display()));
    let scene = shot.scene();
    let nephele = match (&args.nephele, args.engine) {
        (Some(p), _) => p.clone(),
        (None, Engine::Slurm) => {
            std::env::current_exe().context("finding this program's path (give --nephele)")?
        }
        (None, Engine::K8s) => PathBuf::from("nephele"),
    };
    Ok(FarmJob {
        name: if args.preview {
            format!("{}-preview", scene.name)
        } else {
            scene.name.clone()
        },
        nephele,
        scene: absolute(&args.scene)?,
        output: absolute(shot.cache_dir())?,
        frames: shot.frames().to_vec(),
        tasks,
        preview: args.preview,
        overrides: args
            .scene_args
            .overrides()
            .iter()
            .map(|o| format!("{}={}", o.key, o.value))
            .collect(),
        logs: absolute(shot.dir())?.join("logs"),
        origins: origins(args, scene),
    })
}

/// Where the job's paths came from, as a refusal names them (see [`farm::Origins`]); a relative
/// path is said to be resolved against the current folder, whose name is then part of it.
fn origins(args: &Args, scene: &scene::Scene) -> farm::Origins {
    let named = |p: &Path, from: &str| {
        if p.is_absolute() {
            from.to_string()
        } else {
            format!("{from}, resolved against the current folder")
        }
    };
    let output = match (&args.output, &scene.file.output.dir) {
        (Some(p), _) => named(p, "--output"),
        (None, Some(d)) => named(Path::new(d), "the scene's output.dir"),
        (None, None) => named(
            &scene.output_dir,
            "the default output folder renders/<scene file name>",
        ),
    };
    farm::Origins {
        scene: named(&args.scene, "the scene file path"),
        output,
        nephele: match &args.nephele {
            Some(p) => named(p, "--nephele"),
            None => "this program's own path".into(),
        },
    }
}

/// The two job files of `job` (prepare, then the array) as (file name, text), `name` being the
/// scene's frame prefix; a value the files cannot hold is the error.
fn job_files(args: &Args, job: &FarmJob, name: &str) -> anyhow::Result<[(String, String); 2]> {
    Ok(match args.engine {
        Engine::Slurm => [
            (
                format!("{name}.prepare.sbatch"),
                farm::slurm_prepare_script(job, &args.sbatch_args)?,
            ),
            (
                format!("{name}.sbatch"),
                farm::slurm_array_script(job, &args.sbatch_args)?,
            ),
        ],
        Engine::K8s => {
            let pod = K8sPod {
                image: args.image.clone(),
                volume_claim: args.volume_claim.clone(),
                mount: farm::k8s_mount(job).with_context(|| {
                    format!(
                        "k8s: the scene {} and the output folder {} share no folder below / to mount \
                         the volume at; put both under one shared folder",
                        job.scene.display(),
                        job.output.display()
                    )
                })?,
            };
            [
                (
                    format!("{name}.prepare.k8s.yaml"),
                    farm::k8s_prepare_job(job, &pod)?,
                ),
                (
                    format!("{name}.k8s.yaml"),
                    farm::k8s_indexed_job(job, &pod)?,
                ),
            ]
        }
    })
}

/// Submit the prepare script, then the array depending on it; print the job ids.
fn submit(prepare: &Path, array: &Path, tasks: u32) -> anyhow::Result<()> {
    let prep = sbatch(&[prepare.as_os_str()])?;
    let dependency = format!("--dependency=afterok:{prep}");
    let arr = sbatch(&[dependency.as_ref(), array.as_os_str()])?;
    println!(
        "prepare job: {prep}\nrender array: {arr} ({tasks} tasks)\nwatch it: squeue -j {prep},{arr}"
    );
    Ok(())
}

/// Run `sbatch --parsable ARGS` and return the job id it prints.
fn sbatch(args: &[&std::ffi::OsStr]) -> anyhow::Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .output()
        .context("running sbatch (is this a Slurm submit host? the job scripts are written; submit them by hand)")?;
    if !out.status.success() {
        bail!(
            "sbatch failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    // --parsable prints `id` or `id;cluster`.
    let id = text.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        bail!("sbatch printed {:?}, not a job id", text.trim());
    }
    Ok(id)
}
