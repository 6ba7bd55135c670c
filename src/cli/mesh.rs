//! `nephele mesh`: polygonize a model's blob surface and write it as OBJ or PLY.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use nephele::blobby::{load_model, polygonize::polygonize};

/// Arguments of `nephele mesh`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Blob model file (.ron).
    pub model: PathBuf,
    /// Output mesh (.obj or .ply, chosen by extension).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Grid cells along the longest side of the blob supports' bounds (4..=2000).
    #[arg(long, default_value_t = 160)]
    pub resolution: usize,
}

/// Run `nephele mesh`.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        (4..=2000).contains(&args.resolution),
        "--resolution must be between 4 and 2000 (got {})",
        args.resolution
    );
    let ext = args
        .output
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    anyhow::ensure!(
        matches!(ext.as_deref(), Some("obj" | "ply")),
        "{}: output must end in .obj or .ply",
        args.output.display()
    );
    let model = load_model(&args.model)?;
    let start = Instant::now();
    let mesh = polygonize(&model.field(), args.resolution);
    let secs = start.elapsed().as_secs_f64();
    anyhow::ensure!(
        !mesh.triangles.is_empty(),
        "{}: the blob surface is empty ({} live blobs): nothing to write",
        args.model.display(),
        model.live_count()
    );
    nephele::mesh::io::write_mesh(&args.output, &mesh)
        .with_context(|| format!("writing {}", args.output.display()))?;
    println!(
        "{}: {} vertices, {} triangles (resolution {}, {:.2} s) -> {}",
        args.model.display(),
        mesh.positions.len(),
        mesh.triangles.len(),
        args.resolution,
        secs,
        args.output.display()
    );
    Ok(())
}
