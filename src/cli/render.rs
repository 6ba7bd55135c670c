//! `nephele render`: render a scene's shot to frame files (resumable).

use std::path::PathBuf;

use anyhow::Context;
use nephele::scene::frames::{FrameSelection, selection_text};
use nephele::scene::{self, RenderOptions, Shot};

use super::common::{Level, RunArgs, SceneArgs};

/// Arguments of `nephele render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (RON); see scenes/README.md.
    pub scene: PathBuf,
    /// Frames to render, in the shot's frame numbers: comma-separated `A..B` (inclusive),
    /// `A..`, `..B` or `A`, e.g. `1001..1010,1050` (default: the scene's `frames`, else the
    /// whole shot).
    #[arg(long)]
    pub frames: Option<FrameSelection>,
    /// Output folder (default: the scene's `output.dir`, else renders/<scene name>).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Quarter resolution (at least 64 px wide), fast quality, into <output>/preview/.
    #[arg(long)]
    pub preview: bool,
    /// Re-render frames whose files already exist.
    #[arg(long)]
    pub force: bool,
    /// Remove the frames' files of formats this run does not write (left out of --formats or
    /// taken out of the scene's output.formats); without it they are kept, and reported.
    #[arg(long)]
    pub clean: bool,
    /// Also write each frame's blobs as <name>_0001.blobs.ron.
    #[arg(long)]
    pub dump_blobs: bool,
    /// Also write per-frame statistics (visible volume, 3D pieces, screen coverage) to
    /// <output>/<name>_stats.csv; frames already done are re-rendered in memory for them.
    #[arg(long)]
    pub stats: bool,
    /// Also write the render passes into the EXR: layers sun, sky and multiple (their sum is
    /// the beauty), as `output.passes: true` does.
    #[arg(long)]
    pub passes: bool,
    /// Also write the motion vectors into the EXR: layer forward (forward.u, forward.v), each
    /// pixel's forward motion over one frame in pixels, u right and v up (Nuke's VectorBlur),
    /// as `output.motion_vectors: true` does.
    #[arg(long)]
    pub motion_vectors: bool,
    /// Render only the window X0,Y0,X1,Y1 of each frame (pixels of the frame as rendered, the
    /// preview's with --preview; X1 and Y1 exclusive): an EXR with the full frame as display
    /// window and the region as data window, a full-size PNG transparent outside it. Written
    /// as NAME_0001.region.exr (and .png) beside the frames, never over them.
    #[arg(long, value_name = "X0,Y0,X1,Y1")]
    pub region: Option<String>,
    /// Print the wall time of each stage at the end.
    #[arg(long)]
    pub timings: bool,
    /// Render only chunk I (0-based) of N contiguous chunks of the frames: `I/N`, or `auto/N`
    /// to read I from the job array (SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX or
    /// AWS_BATCH_JOB_ARRAY_INDEX). See README "Rendering on a farm".
    #[arg(long, value_parser = parse_task)]
    pub task: Option<TaskArg>,
    /// Formats to write per frame, overriding the scene's `output.formats`: a comma-separated
    /// list of exr, png, vdb (OpenVDB density grid) and vol (Mitsuba density grid).
    #[arg(long, value_delimiter = ',', value_parser = nephele::render::output::parse_format)]
    pub formats: Vec<scene::Format>,
    /// `--set`, `--size`.
    #[command(flatten)]
    pub scene_args: SceneArgs,
    /// `--threads`, `--progress`, `-q`, `-v`.
    #[command(flatten)]
    pub run_args: RunArgs,
}

/// A `--task` value: chunk `index` of `count`; `index` is `None` for `auto`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TaskArg {
    /// 0-based chunk index, or `None` to read it from the job array's environment.
    pub index: Option<u32>,
    /// Number of chunks.
    pub count: u32,
}

fn parse_task(s: &str) -> Result<TaskArg, String> {
    let usage = || format!("'{s}' is not I/N (chunk I of N, 0-based) nor auto/N");
    let (i, n) = s.split_once('/').ok_or_else(usage)?;
    let count = n.trim().parse::<u32>().map_err(|_| usage())?;
    let index = match i.trim() {
        "auto" => None,
        i => Some(i.parse::<u32>().map_err(|_| usage())?),
    };
    Ok(TaskArg { index, count })
}

/// Run `nephele render` on the threads `--threads` asks for.
pub fn run(args: Args) -> anyhow::Result<()> {
    let run_args = args.run_args.clone();
    run_args.install(|| render(args))?
}

fn render(args: Args) -> anyhow::Result<()> {
    let mut scene = args.scene_args.load(&args.scene)?;
    if !args.formats.is_empty() {
        scene.file.output.formats = args.formats.clone();
    }
    if args.motion_vectors {
        scene.file.output.motion_vectors = true;
    }
    let opts = RenderOptions {
        frames: args.frames.clone(),
        output: args.output,
        preview: args.preview,
        force: args.force,
        clean: args.clean,
        dump_blobs: args.dump_blobs,
        stats: args.stats,
        passes: args.passes,
        region: args.region.clone(),
    };
    let name = scene.name.clone();
    let mut shot = Shot::open(scene, &opts)?;
    let say = args.run_args.report(0);
    for o in args.scene_args.overrides() {
        say.detail(format!("{}: {} = {}", o.given, o.key, o.value));
    }
    say.detail(format!("worker threads: {}", rayon::current_num_threads()));
    if let Some(task) = args.task {
        let (index, frames) = task_frames(task, shot.frames())?;
        say.info(format!(
            "task {index}/{}: frames {} of {}",
            task.count,
            selection_text(&frames),
            selection_text(shot.frames())
        ));
        shot.set_frames(frames);
    }
    let mut report = args.run_args.report(shot.frames().len() as u64);
    report.stage("start");
    let bar = report.bar(&name);
    let done = shot
        .run(&mut |f| {
            bar.inc(1);
            report.step(f.frame, f.seconds, f.skipped);
            let line = if f.skipped {
                if report.level < Level::Verbose {
                    return;
                }
                format!("frame {:>4}/{}: up to date, skipped", f.frame, f.of)
            } else if report.level >= Level::Normal {
                format!("frame {:>4}/{}: {:.2} s", f.frame, f.of, f.seconds)
            } else {
                return;
            };
            // A hidden bar (not a terminal: a farm task's log) drops println; keep the line.
            if bar.is_hidden() {
                eprintln!("{line}");
            } else {
                bar.println(line);
            }
        })
        .with_context(|| format!("rendering {}", args.scene.display()))?;
    bar.finish_and_clear();
    report.stage("done");
    summary(&report, &done, args.timings);
    Ok(())
}

/// What the run did, on stderr (the timings with `--timings` or `-v`).
fn summary(say: &super::common::Report, report: &scene::ShotReport, timings: bool) {
    if let Some(origin) = &report.target {
        use nephele::scene::target::TargetOrigin;
        match origin {
            TargetOrigin::Fitted(p) => {
                say.info(format!("fitted the target, cached in {}", p.display()))
            }
            TargetOrigin::Cached(p) => say.info(format!("target from cache {}", p.display())),
            TargetOrigin::ModelFile(_) => {}
        }
    }
    say.info(format!(
        "{}: {} frames rendered, {} already done (use --force to redo)",
        report.output_dir.display(),
        report.rendered,
        report.skipped
    ));
    if !report.out_of_date.is_empty() {
        let why: Vec<String> = report
            .out_of_date
            .iter()
            .map(|(reason, n)| format!("{n} {reason}"))
            .collect();
        let n: u32 = report.out_of_date.iter().map(|(_, n)| n).sum();
        say.info(format!(
            "{n} of the rendered frames were out of date: {}",
            why.join("; ")
        ));
    }
    let others = &report.others;
    if others.current + others.not_current > 0 {
        say.info(format!(
            "kept {} files of formats this run does not write ({}){}; --clean removes them",
            others.current + others.not_current,
            others.kinds.join(", "),
            if others.not_current > 0 {
                format!(
                    ", {} of them no longer current (made before the scene changed)",
                    others.not_current
                )
            } else {
                String::new()
            }
        ));
    }
    if others.removed > 0 {
        say.info(format!(
            "removed {} files of formats this run does not write ({})",
            others.removed,
            others.kinds.join(", ")
        ));
    }
    if let Some(p) = &report.stats {
        say.info(format!("statistics in {}", p.display()));
    }
    if timings || say.level >= Level::Verbose {
        let mut t = report.timings.report();
        if report.rendered > 0 {
            let per = report
                .timings
                .stages
                .iter()
                .filter(|s| s.0 == "render" || s.0 == "write")
                .map(|s| s.1)
                .sum::<f64>()
                / report.rendered as f64;
            t.push_str(&format!("  {:<14} {per:>8.3} s\n", "per frame"));
        }
        // The work counters, in a `--features counters` build (speed work reads them).
        for (name, n) in nephele::render::work_counts() {
            t.push_str(&format!("  {name:<32} {:>10.3} M\n", n as f64 / 1e6));
        }
        // Asked for by name, the timings print even when quiet.
        if timings && say.level == Level::Quiet {
            eprint!("{t}");
        } else {
            say.info(t.trim_end());
        }
    }
}

/// The index of `task` (read from the environment for `auto`) and the frames of its chunk of
/// `frames`.
fn task_frames(task: TaskArg, frames: &[u32]) -> anyhow::Result<(u32, Vec<u32>)> {
    use nephele::scene::chunk;
    let index = match task.index {
        Some(i) => i,
        None => chunk::index_from_env(task.count, |var| std::env::var(var).ok())?,
    };
    Ok((index, chunk::chunk(frames, index, task.count)?.to_vec()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tasks_parse() {
        let t = |index, count| TaskArg { index, count };
        assert_eq!(parse_task("2/4"), Ok(t(Some(2), 4)));
        assert_eq!(parse_task("auto/8"), Ok(t(None, 8)));
        assert!(parse_task("2").is_err());
        assert!(parse_task("a/4").is_err());
        assert!(parse_task("-1/4").is_err());
    }
}
