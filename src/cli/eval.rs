//! `nephele eval`: Metro error of a model against its mesh, sizes and data reduction.

use std::path::PathBuf;

use anyhow::Context;
use nephele::eval::{EvalConfig, MetroConfig, evaluate_model};

/// Arguments of `nephele eval`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The original mesh: .obj, .ply, .off, .stl or builtin:NAME.
    pub mesh: String,
    /// The model: a RON model file or an encoded .blob file.
    pub model: PathBuf,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Marching-cubes cells along the longest side of the blob bounds.
    #[arg(long, default_value_t = 200)]
    pub resolution: usize,
    /// Area-weighted Metro samples per face of the larger mesh.
    #[arg(long, default_value_t = 10)]
    pub samples_per_face: usize,
    /// Minimum area-weighted Metro samples a direction.
    #[arg(long, default_value_t = 200_000)]
    pub min_samples: usize,
    /// Maximum area-weighted Metro samples a direction.
    #[arg(long, default_value_t = 1_000_000)]
    pub max_samples: usize,
    /// Skip the quantized codec's extra error (saves a polygonization and a Metro run).
    #[arg(long)]
    pub no_codec_error: bool,
    /// Also measure the quantized model against the mesh (one more Metro run).
    #[arg(long)]
    pub quantized_vs_mesh: bool,
    /// Seed of the Metro sample positions.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the wall time of each stage (on stderr; in the JSON's `timings` either way).
    #[arg(long)]
    pub timings: bool,
}

/// Run `nephele eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        (2..=2048).contains(&args.resolution),
        "--resolution must be between 2 and 2048, got {}",
        args.resolution
    );
    anyhow::ensure!(args.min_samples >= 1, "--min-samples must be at least 1");
    let mut timings = nephele::progress::Timings::default();
    let loaded = timings.stage("load mesh", || super::load_mesh(&args.mesh))?;
    let model = timings
        .stage("load model", || nephele::blobby::load_model(&args.model))
        .with_context(|| format!("loading the model {}", args.model.display()))?;
    let cfg = EvalConfig {
        resolution: args.resolution,
        metro: MetroConfig {
            samples_per_face: args.samples_per_face,
            min_samples: args.min_samples,
            max_samples: args.max_samples,
            seed: args.seed,
            ..MetroConfig::default()
        },
        codec_error: !args.no_codec_error,
        quantized_vs_mesh: args.quantized_vs_mesh,
    };
    let mut eval = evaluate_model(&loaded.mesh, &model, &cfg);
    timings.stages.append(&mut eval.timings);
    eval.timings = timings.stages.clone();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&eval)?);
    } else {
        println!("{}", eval.report());
    }
    if args.timings {
        eprint!("{}", timings.report());
    }
    Ok(())
}
