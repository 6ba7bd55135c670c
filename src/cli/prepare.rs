//! `nephele prepare`: fit and cache a scene's target once, before a farm's array tasks render.

use std::path::PathBuf;

use anyhow::Context;
use nephele::scene::provenance::FrameStatus;
use nephele::scene::target::TargetOrigin;
use nephele::scene::{RenderOptions, Shot};

use super::common::{RunArgs, SceneArgs};

/// Arguments of `nephele prepare`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (RON); see scenes/README.md.
    pub scene: PathBuf,
    /// Output folder, as given to `render` (default: the scene's `output.dir`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Prepare for `render --preview` (creates <output>/preview/; the fit cache is shared).
    #[arg(long)]
    pub preview: bool,
    /// `--set`, `--size` (give `render` the same).
    #[command(flatten)]
    pub scene_args: SceneArgs,
    /// `--threads`, `--progress`, `-q`, `-v`.
    #[command(flatten)]
    pub run_args: RunArgs,
}

/// Run `nephele prepare` on the threads `--threads` asks for.
pub fn run(args: Args) -> anyhow::Result<()> {
    let run_args = args.run_args.clone();
    run_args.install(|| prepare(args))?
}

/// Check the output folder, fit (or find) the target cache, plan the animation once to surface
/// its errors, and create the frames folder.
fn prepare(args: Args) -> anyhow::Result<()> {
    let opts = RenderOptions {
        output: args.output,
        preview: args.preview,
        ..RenderOptions::default()
    };
    let report = args.run_args.report(1);
    let shot = Shot::open(args.scene_args.load(&args.scene)?, &opts)?;
    shot.check_writable()?;
    report.stage("prepare");
    let origin = &shot
        .prepared()
        .with_context(|| format!("preparing {}", args.scene.display()))?
        .origin;
    std::fs::create_dir_all(shot.dir())
        .with_context(|| format!("creating {}", shot.dir().display()))?;
    report.info(match origin {
        TargetOrigin::Fitted(p) => format!("fitted the target, cached in {}", p.display()),
        TargetOrigin::Cached(p) => format!("target already cached in {}", p.display()),
        TargetOrigin::ModelFile(p) => format!("target is the model file {}", p.display()),
    });
    // A diffusion's blend path, made once here for every task of the farm (they read it).
    if let Some(d) = shot.prepared()?.plan.diffusion() {
        d.make_blend_path();
    }
    shot.cache_blend_path()?;
    let removed = shot.remove_stale_temps()?;
    if removed > 0 {
        report.info(format!(
            "removed {removed} temporary files left by killed renders"
        ));
    }
    // The render's own rule: how many of the frames a render would skip, and why not the rest.
    let statuses = shot.statuses()?;
    let done = statuses
        .iter()
        .filter(|(_, s)| *s == FrameStatus::UpToDate)
        .count();
    let mut stale: Vec<(String, u32)> = Vec::new();
    for (_, s) in statuses {
        if let FrameStatus::OutOfDate(reason) = s {
            match stale.iter_mut().find(|(r, _)| *r == reason) {
                Some((_, n)) => *n += 1,
                None => stale.push((reason, 1)),
            }
        }
    }
    let why: Vec<String> = stale.iter().map(|(r, n)| format!("{n} {r}")).collect();
    report.info(format!(
        "{}: ready to render; {done} of {} frames up to date{}",
        shot.dir().display(),
        shot.frames().len(),
        if why.is_empty() {
            String::new()
        } else {
            format!(", out of date: {}", why.join("; "))
        }
    ));
    report.stage("done");
    Ok(())
}
