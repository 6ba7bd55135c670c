//! `nephele usd`: write a scene's shot as a USD ASCII stage (camera, sun, sky, frame VDBs).

use std::path::PathBuf;

use anyhow::Context;
use nephele::scene::{self, RenderOptions, Shot};

/// Arguments of `nephele usd`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (RON); see scenes/README.md.
    pub scene: PathBuf,
    /// Stage file to write (default: <output folder>/<name>.usda).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Folder of the frame VDBs (default: the scene's `output.dir`, else renders/<scene name>),
    /// as given to `nephele render --output`.
    #[arg(long)]
    pub frames_dir: Option<PathBuf>,
}

/// Run `nephele usd`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let opts = RenderOptions {
        output: args.frames_dir.clone(),
        ..RenderOptions::default()
    };
    // The stage covers the whole shot, whatever the scene's `frames` range.
    let shot = Shot::open(scene::load_scene(&args.scene)?, &opts)?;
    let path = args
        .output
        .unwrap_or_else(|| shot.dir().join(format!("{}.usda", shot.scene().name)));
    let stage_dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    let stage = scene::usd::shot_stage(&shot, stage_dir)?;
    let text = scene::usd::stage_text(&stage)
        .with_context(|| format!("writing the stage of {}", args.scene.display()))?;
    nephele::atomic::write_bytes_atomically(&path, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    let missing = (0..shot.total())
        .filter(|&k| !scene::usd::frame_vdb(&shot, shot.number(k)).is_file())
        .count();
    eprintln!(
        "{}: {} frames at {} fps",
        path.display(),
        shot.total(),
        shot.scene().file.shot.fps
    );
    if missing > 0 {
        eprintln!(
            "note: {missing} frame VDBs are not in {} yet; add them with `nephele render {} --formats vdb` (it writes the VDBs and keeps the frames' other files)",
            shot.dir().display(),
            nephele::farm::shell_quote(&args.scene.to_string_lossy())
        );
    }
    Ok(())
}
