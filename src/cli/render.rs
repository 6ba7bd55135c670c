//! `nephele render`: render a scene's shot to frame files (resumable).

use std::path::PathBuf;

use anyhow::Context;
use nephele::scene::{self, RenderOptions};

/// Arguments of `nephele render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (RON); see scenes/README.md.
    pub scene: PathBuf,
    /// Frames to render, 1-based and inclusive: `A..B`, `A..`, `..B` or `A` (default: the
    /// scene's `frames`, else the whole shot).
    #[arg(long, value_parser = parse_frames)]
    pub frames: Option<FrameArg>,
    /// Output folder (default: the scene's `output.dir`, else renders/<scene name>).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Quarter resolution (at least 64 px wide), fast quality, into <output>/preview/.
    #[arg(long)]
    pub preview: bool,
    /// Re-render frames whose files already exist.
    #[arg(long)]
    pub force: bool,
    /// Also write each frame's blobs as <name>_0001.blobs.ron.
    #[arg(long)]
    pub dump_blobs: bool,
    /// Print the wall time of each stage at the end.
    #[arg(long)]
    pub timings: bool,
    /// Formats to write per frame, overriding the scene's `output.formats`: a comma-separated
    /// list of exr, png, vdb (OpenVDB density grid) and vol (Mitsuba density grid).
    #[arg(long, value_delimiter = ',', value_parser = parse_format)]
    pub formats: Vec<scene::Format>,
}

fn parse_format(s: &str) -> Result<scene::Format, String> {
    scene::Format::from_name(s)
        .ok_or_else(|| format!("'{s}' is not a format (use exr, png, vdb or vol)"))
}

/// A `--frames` value: bounds left open are filled from the shot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameArg {
    /// First frame (1-based), if given.
    pub first: Option<u32>,
    /// Last frame (inclusive), if given.
    pub last: Option<u32>,
}

fn parse_frames(s: &str) -> Result<FrameArg, String> {
    let num = |t: &str| -> Result<Option<u32>, String> {
        let t = t.trim();
        if t.is_empty() {
            return Ok(None);
        }
        t.parse::<u32>()
            .map(Some)
            .map_err(|_| format!("'{t}' is not a frame number (frames are 1-based)"))
    };
    let (first, last) = match s.split_once("..") {
        Some((a, b)) => (num(a)?, num(b.strip_prefix('=').unwrap_or(b))?),
        None => {
            let n = num(s)?.ok_or("empty frame range")?;
            (Some(n), Some(n))
        }
    };
    Ok(FrameArg { first, last })
}

/// Run `nephele render`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut scene = scene::load_scene(&args.scene)?;
    if !args.formats.is_empty() {
        scene.file.output.formats = args.formats.clone();
    }
    let total = scene.file.shot.frame_count();
    let frames = args
        .frames
        .map(|f| (f.first.unwrap_or(1), f.last.unwrap_or(total)));
    let opts = RenderOptions {
        frames,
        output: args.output,
        preview: args.preview,
        force: args.force,
        dump_blobs: args.dump_blobs,
    };
    let setup = scene::shot::shot_setup(&scene, &opts)?;
    let count = (setup.frames.end() - setup.frames.start() + 1) as u64;
    let bar = nephele::progress::bar(&scene.name, count);
    let report = scene::render_shot(&scene, &opts, &mut |f| {
        bar.inc(1);
        if !f.skipped {
            bar.println(format!("frame {:>4}/{}: {:.2} s", f.frame, f.of, f.seconds));
        }
    })
    .with_context(|| format!("rendering {}", args.scene.display()))?;
    bar.finish_and_clear();
    if let Some(origin) = &report.target {
        use nephele::scene::target::TargetOrigin;
        match origin {
            TargetOrigin::Fitted(p) => eprintln!("fitted the target, cached in {}", p.display()),
            TargetOrigin::Cached(p) => eprintln!("target from cache {}", p.display()),
            TargetOrigin::ModelFile(_) => {}
        }
    }
    eprintln!(
        "{}: {} frames rendered, {} already done (use --force to redo)",
        report.output_dir.display(),
        report.rendered,
        report.skipped
    );
    if args.timings {
        eprint!("{}", report.timings.report());
        if report.rendered > 0 {
            let per = report
                .timings
                .stages
                .iter()
                .filter(|s| s.0 == "render" || s.0 == "write")
                .map(|s| s.1)
                .sum::<f64>()
                / report.rendered as f64;
            eprintln!("  {:<14} {per:>8.3} s", "per frame");
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ranges_parse() {
        let f = |a, b| FrameArg { first: a, last: b };
        assert_eq!(parse_frames("1..1"), Ok(f(Some(1), Some(1))));
        assert_eq!(parse_frames("3..=9"), Ok(f(Some(3), Some(9))));
        assert_eq!(parse_frames("5.."), Ok(f(Some(5), None)));
        assert_eq!(parse_frames("..7"), Ok(f(None, Some(7))));
        assert_eq!(parse_frames("12"), Ok(f(Some(12), Some(12))));
        assert!(parse_frames("a..3").is_err());
        assert!(parse_frames("").is_err());
    }
}
