//! `nephele fit`: mesh → blob model.

use std::path::PathBuf;

use anyhow::Context;
use nephele::decompose::{ObstacleShift, Primitive};
use nephele::pipeline::{self, FitConfig, Optimisation};

/// Arguments of `nephele fit`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input mesh: .obj, .ply, .off, .stl, or builtin:NAME (sphere, ellipsoid, torus-knot, duck).
    pub mesh: String,
    /// Output model file (.ron).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Number of blobs to select: an upper bound (the full optimiser drops blobs that end
    /// switched off or negligible, so a model can have fewer).
    #[arg(long, default_value_t = FitConfig::DEFAULT_BLOBS)]
    pub blobs: usize,
    /// Number of candidate ellipsoids (seed vertices of the simplified mesh).
    #[arg(long, default_value_t = FitConfig::DEFAULT_CANDIDATES)]
    pub candidates: usize,
    /// Number of surface samples.
    #[arg(long, default_value_t = FitConfig::DEFAULT_SAMPLES)]
    pub samples: usize,
    /// Blob primitive.
    #[arg(long, value_enum, default_value_t = PrimitiveArg::Ellipsoid)]
    pub primitive: PrimitiveArg,
    /// Obstacle shift along the normal.
    #[arg(long, value_enum, default_value_t = ShiftArg::Outward)]
    pub shift: ShiftArg,
    /// Blob optimisation after decomposition: `faithful` (the paper: Nelder–Mead on A and B,
    /// centres and shapes fixed; fastest), `full` (beyond the paper: every blob parameter by block
    /// Levenberg–Marquardt on a geometric residual with sign constraints, the blobs it frees
    /// re-spent where the model falls short; 2–3× lower mean and max error; the default) or
    /// `none` (the "before optimisation" model).
    #[arg(long, value_enum, default_value_t = OptimiserArg::Full)]
    pub optimiser: OptimiserArg,
    /// Shorthand for `--optimiser full` (the default).
    #[arg(long, conflicts_with = "optimiser")]
    pub full: bool,
    /// Shorthand for `--optimiser faithful`.
    #[arg(long, conflicts_with_all = ["optimiser", "full"])]
    pub faithful: bool,
    /// Add blobs (×1.5 a round, starting from --blobs) until the Hausdorff error against the
    /// mesh is at most this percentage of its bounding-box diagonal (measured by Metro).
    #[arg(long, value_name = "PERCENT")]
    pub max_error: Option<f64>,
    /// Upper bound on the blob budget for --max-error.
    #[arg(long, default_value_t = 3000)]
    pub max_blobs: usize,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Print the wall time of each stage.
    #[arg(long)]
    pub timings: bool,
}

/// `--primitive`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum PrimitiveArg {
    /// General ellipsoids (three-stage growth).
    Ellipsoid,
    /// Inscribed spheres only (the spherical baseline).
    Sphere,
}

/// `--optimiser`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum OptimiserArg {
    /// The paper's per-blob Nelder–Mead on (A, B).
    Faithful,
    /// Every blob parameter, geometric residual, sign constraints.
    Full,
    /// No optimisation.
    None,
}

/// `--shift`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum ShiftArg {
    /// Outward (the paper's choice).
    Outward,
    /// Inward (Bischoff & Kobbelt).
    Inward,
    /// No shift.
    None,
}

/// Run `nephele fit`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cfg = FitConfig {
        blobs: args.blobs,
        candidates: args.candidates,
        samples: args.samples,
        primitive: match args.primitive {
            PrimitiveArg::Ellipsoid => Primitive::Ellipsoid,
            PrimitiveArg::Sphere => Primitive::Sphere,
        },
        shift: match args.shift {
            ShiftArg::Outward => ObstacleShift::Outward,
            ShiftArg::Inward => ObstacleShift::Inward,
            ShiftArg::None => ObstacleShift::None,
        },
        optimisation: match (args.faithful, args.optimiser) {
            (true, _) | (_, OptimiserArg::Faithful) => Optimisation::Faithful(Default::default()),
            (_, OptimiserArg::Full) => Optimisation::Full(Default::default(), Default::default()),
            (_, OptimiserArg::None) => Optimisation::None,
        },
        seed: args.seed,
        ..FitConfig::default()
    };
    cfg.validate()?;
    let loaded = super::load_mesh(&args.mesh)?;
    let out = match args.max_error {
        Some(pct) => {
            anyhow::ensure!(
                pct.is_finite() && pct > 0.0,
                "--max-error must be a positive percentage, got {pct}"
            );
            let (out, rounds) = pipeline::fit_to_error(&cfg, &loaded, pct, args.max_blobs)?;
            for r in &rounds {
                eprintln!(
                    "  budget {:>5} blobs ({} kept): Hausdorff {:.3}% of D",
                    r.blobs, r.kept, r.hausdorff_pct
                );
            }
            if rounds.last().is_some_and(|r| r.hausdorff_pct > pct) {
                eprintln!(
                    "warning: stopped above --max-error {pct}% (budget or selection exhausted)"
                );
            }
            out
        }
        None => pipeline::fit(&cfg, &loaded)?,
    };
    nephele::blobby::save_model(&args.output, &out.model)
        .with_context(|| format!("writing the model to {}", args.output.display()))?;
    let s = &out.stats;
    eprintln!(
        "{}: {} samples, {} candidates (median sphere radius {:.2}% of D), {} selected, {} live; objective {:.4e} -> {:.4e}",
        args.output.display(),
        s.samples,
        s.candidates,
        100.0 * s.median_sphere_radius,
        s.selected,
        s.live,
        s.objective_before,
        s.objective_after
    );
    if args.timings {
        eprint!("{}", out.timings.report());
    }
    Ok(())
}
