//! `nephele usd`: write a scene's shot as a USD ASCII stage (camera, sun, sky, frame VDBs).

use std::path::PathBuf;

use anyhow::Context;
use nephele::scene::{self, RenderOptions};

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
    let scene = scene::load_scene(&args.scene)?;
    let opts = RenderOptions {
        output: args.frames_dir.clone(),
        ..RenderOptions::default()
    };
    // The stage covers the whole shot (`setup.total`), whatever the scene's `frames` range.
    let setup = scene::shot::shot_setup(&scene, &opts)?;
    let (model, _) = scene::load_target(&scene, &setup.cache_dir)
        .with_context(|| format!("loading the target of {}", args.scene.display()))?;
    let prep = scene::shot::prepare(&scene, model)?;
    let path = args
        .output
        .unwrap_or_else(|| setup.dir.join(format!("{}.usda", scene.name)));
    let stage_dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(std::path::Path::new("."));
    let stage = nephele::export::usd::shot_stage(&scene, &prep, &setup, stage_dir);
    let text = nephele::export::usd::stage_text(&stage);
    nephele::atomic::write_bytes_atomically(&path, text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))?;
    let missing = (1..=setup.total)
        .filter(|&f| !nephele::export::usd::frame_vdb(&scene, &setup.dir, f).is_file())
        .count();
    eprintln!(
        "{}: {} frames at {} fps",
        path.display(),
        setup.total,
        scene.file.shot.fps
    );
    if missing > 0 {
        eprintln!(
            "note: {missing} frame VDBs are not in {} yet; render them with `nephele render {} --formats vdb`",
            setup.dir.display(),
            args.scene.display()
        );
    }
    Ok(())
}
