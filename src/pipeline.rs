//! The fitting pipeline, mesh → blob model (see docs/ARCHITECTURE.md): the mesh's solid
//! (winding number) → surface samples → seeds and candidate growth → greedy selection →
//! optimisation ([`crate::blobby::optimise::optimise`]). Each stage is timed.

use serde::Serialize;

use crate::blobby::model_file::MODEL_VERSION;
use crate::blobby::optimise::{self, Start, Target};
use crate::blobby::{BlobModel, SourceInfo, THRESHOLD};
use crate::decompose::{self, DecomposeConfig, ObstacleShift, Primitive};
use crate::mesh::LoadedMesh;
use crate::mesh::sample::{SurfaceSamples, sample_surface};
use crate::mesh::winding::WindingNumber;
use crate::progress::Timings;

pub use crate::blobby::optimise::Optimisation;

/// Version of the fitting algorithm: part of a fitted model's cache key with the serialized
/// [`FitConfig`]. Bump it whenever a change makes `fit` give a different model for the same
/// config (a cached fit from an older build is then redone, not reused).
/// History: 1 = inside/outside by parry's pseudo-normal test and a flood fill; 2 = by the
/// generalized winding number; 3 = part of a small selection held back for the adaptive budget,
/// six final sweeps under a weaker shape prior; 4 = swap rounds in small models (the least
/// useful blobs moved to the worst shortfalls).
pub const FIT_ALGORITHM_VERSION: u32 = 4;

/// Settings of a fit. Lengths are relative to the mesh's bounding-box diagonal. The defaults
/// of the counts every front end offers (CLI, scene files) are the `DEFAULT_*` constants, and
/// [`FitConfig::validate`] is their one check.
#[derive(Clone, Debug, Serialize)]
pub struct FitConfig {
    /// Blobs to select (upper bound; selection may stop earlier when coverage saturates).
    pub blobs: usize,
    /// Candidate seeds (vertices of the simplified mesh).
    pub candidates: usize,
    /// Surface samples (obstacles and optimisation targets).
    pub samples: usize,
    /// Ellipsoids or spheres.
    pub primitive: Primitive,
    /// Obstacle shift direction.
    pub shift: ObstacleShift,
    /// Obstacle shift, fraction of the diagonal.
    pub epsilon: f64,
    /// Voxels along the longest side for selection.
    pub voxels: usize,
    /// Curvature weighting `λ` of the selection gain.
    pub curvature_weight: f64,
    /// Starting `A` of every blob.
    pub initial_a: f64,
    /// Optimisation after decomposition.
    pub optimisation: Optimisation,
    /// The one seed every random choice derives from.
    pub seed: u64,
}

impl FitConfig {
    /// Default blob budget (the decomposition's default selection).
    pub const DEFAULT_BLOBS: usize = DecomposeConfig::DEFAULT_MAX_SELECTED;
    /// Default number of candidate seeds (the decomposition's).
    pub const DEFAULT_CANDIDATES: usize = DecomposeConfig::DEFAULT_CANDIDATES;
    /// Default number of surface samples.
    pub const DEFAULT_SAMPLES: usize = 60_000;
    /// Fewest blobs a fit accepts.
    pub const MIN_BLOBS: usize = 1;
    /// Fewest candidate seeds a fit accepts.
    pub const MIN_CANDIDATES: usize = 1;
    /// Fewest surface samples a fit accepts.
    pub const MIN_SAMPLES: usize = 100;

    /// Check the counts: at least one blob and one candidate, at least
    /// [`FitConfig::MIN_SAMPLES`] samples.
    pub fn validate(&self) -> Result<(), FitError> {
        let bad = |what: &str, min: usize, got: usize| {
            Err(FitError::Config(format!(
                "{what} must be at least {min}, got {got}"
            )))
        };
        if self.blobs < Self::MIN_BLOBS {
            return bad("blobs", Self::MIN_BLOBS, self.blobs);
        }
        if self.candidates < Self::MIN_CANDIDATES {
            return bad("candidates", Self::MIN_CANDIDATES, self.candidates);
        }
        if self.samples < Self::MIN_SAMPLES {
            return bad("samples", Self::MIN_SAMPLES, self.samples);
        }
        Ok(())
    }
}

impl Default for FitConfig {
    fn default() -> Self {
        let d = DecomposeConfig::default();
        FitConfig {
            blobs: Self::DEFAULT_BLOBS,
            candidates: Self::DEFAULT_CANDIDATES,
            samples: Self::DEFAULT_SAMPLES,
            primitive: d.primitive,
            shift: d.shift,
            epsilon: d.epsilon,
            voxels: d.voxels,
            curvature_weight: d.curvature_weight,
            initial_a: 1.0,
            optimisation: Optimisation::Full(Default::default(), Default::default()),
            seed: 1,
        }
    }
}

/// Why a fit cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// A setting is out of range.
    #[error("fit settings: {0}")]
    Config(String),
    /// The mesh bounds no solid.
    #[error(
        "{mesh}: the mesh encloses no volume: its generalized winding number is nowhere above \
         {ENCLOSED} next to its surface (largest {max_winding:.3}); it is a lone open sheet or \
         loose faces. Give the surface a thickness or close it (a scan with holes is fine)"
    )]
    NoVolume {
        /// The mesh's source.
        mesh: String,
        /// The largest winding number found just behind the surface.
        max_winding: f64,
    },
}

/// A mesh encloses a volume when its winding number exceeds this just behind its surface
/// somewhere. Exactly ½ is a flat sheet's value; the margin rejects nearly flat ones.
pub const ENCLOSED: f64 = 0.6;

/// The largest winding number at the samples moved `depth` behind the surface (along `−n`),
/// stopping at the first chunk that exceeds [`ENCLOSED`]. `w` is harmonic off the mesh, so
/// the region `w > ½` reaches its maximum on the mesh: if it exists, points just behind the
/// surface find it.
fn max_winding_behind(solid: &WindingNumber, samples: &SurfaceSamples, depth: f64) -> f64 {
    use rayon::prelude::*;
    let mut max = f64::NEG_INFINITY;
    for (p, n) in samples
        .positions
        .chunks(1024)
        .zip(samples.normals.chunks(1024))
    {
        let chunk = p
            .par_iter()
            .zip(n)
            .map(|(&p, &n)| solid.at(p - depth * n))
            .reduce(|| f64::NEG_INFINITY, f64::max);
        max = max.max(chunk);
        if max > ENCLOSED {
            break;
        }
    }
    max
}

/// Counts and objective values of a fit, for reports.
#[derive(Clone, Debug, Default)]
pub struct FitStats {
    /// Surface samples used.
    pub samples: usize,
    /// Candidates grown.
    pub candidates: usize,
    /// Candidates selected (blobs in the model).
    pub selected: usize,
    /// Blobs with `B > 0` after optimisation.
    pub live: usize,
    /// `(1/m) Σ F(p)²` before optimisation.
    pub objective_before: f64,
    /// `(1/m) Σ F(p)²` after optimisation.
    pub objective_after: f64,
    /// Median stage-1 sphere radius of the candidates, as a fraction of the diagonal.
    pub median_sphere_radius: f64,
}

/// A fitted model with its statistics and stage timings.
#[derive(Clone, Debug)]
pub struct FitOutput {
    /// The model.
    pub model: BlobModel,
    /// Counts and objective values.
    pub stats: FitStats,
    /// Wall time per stage.
    pub timings: Timings,
}

/// Fit a blob model to a loaded, validated mesh. Fails when the settings are out of range or
/// the mesh encloses no volume.
pub fn fit(cfg: &FitConfig, input: &LoadedMesh) -> Result<FitOutput, FitError> {
    fit_reporting(cfg, input, &mut |_| {})
}

/// The stages of a fit, in order, as [`fit_reporting`] names them (and [`FitOutput::timings`]).
pub const FIT_STAGES: [&str; 5] = ["winding", "samples", "grow", "select", "optimise"];

/// `timings.stage(name, f)`, telling `on_stage` as it starts.
fn reported<T>(
    timings: &mut Timings,
    on_stage: &mut dyn FnMut(&str),
    name: &str,
    f: impl FnOnce() -> T,
) -> T {
    on_stage(name);
    timings.stage(name, f)
}

/// [`fit`], calling `on_stage` with each stage's name of [`FIT_STAGES`] as it starts (for
/// front ends that show a fit's progress, like the Python package's `fit(progress=…)`).
pub fn fit_reporting(
    cfg: &FitConfig,
    input: &LoadedMesh,
    on_stage: &mut dyn FnMut(&str),
) -> Result<FitOutput, FitError> {
    cfg.validate()?;
    let mesh = &input.mesh;
    let bounds = mesh.bounds();
    let mut timings = Timings::default();
    let solid = reported(&mut timings, on_stage, "winding", || {
        WindingNumber::new(mesh)
    });
    let samples = reported(&mut timings, on_stage, "samples", || {
        sample_surface(mesh, cfg.samples, cfg.seed)
    });
    let max_winding = max_winding_behind(&solid, &samples, cfg.epsilon * bounds.diagonal());
    if !(max_winding > ENCLOSED) {
        return Err(FitError::NoVolume {
            mesh: input.source.clone(),
            max_winding,
        });
    }
    let dcfg = DecomposeConfig {
        candidates: cfg.candidates,
        shift: cfg.shift,
        epsilon: cfg.epsilon,
        primitive: cfg.primitive,
        voxels: cfg.voxels,
        curvature_weight: cfg.curvature_weight,
        max_selected: cfg.blobs,
        ..DecomposeConfig::default()
    };
    let candidates = reported(&mut timings, on_stage, "grow", || {
        decompose::grow_candidates(&dcfg, mesh, &solid, &samples)
    });
    let order = reported(&mut timings, on_stage, "select", || {
        decompose::select_greedy(&dcfg, &bounds, &candidates)
    });
    let ellipsoids: Vec<_> = candidates.iter().map(|c| c.ellipsoid).collect();
    let target = Target {
        mesh,
        samples: &samples,
        solid: &solid,
    };
    let start = Start {
        candidates: &ellipsoids,
        selected: &order,
        initial_a: cfg.initial_a,
        max_blobs: cfg.blobs,
    };
    let optimised = reported(&mut timings, on_stage, "optimise", || {
        optimise::optimise(&cfg.optimisation, &target, &start, THRESHOLD)
    });
    let mut radii: Vec<f64> = candidates.iter().map(|c| c.sphere_radius).collect();
    radii.sort_by(f64::total_cmp);
    let median = radii.get(radii.len() / 2).copied().unwrap_or(0.0) / bounds.diagonal();
    let model = BlobModel {
        version: MODEL_VERSION,
        primitive: cfg.primitive,
        threshold: THRESHOLD,
        source: SourceInfo {
            mesh: input.source.clone(),
            bounds,
            vertices: mesh.positions.len(),
            faces: mesh.triangles.len(),
        },
        seed: cfg.seed,
        blobs: optimised.blobs,
    };
    let stats = FitStats {
        samples: samples.positions.len(),
        candidates: candidates.len(),
        selected: order.len(),
        live: model.live_count(),
        objective_before: optimised.objective_before,
        objective_after: optimised.objective_after,
        median_sphere_radius: median,
    };
    Ok(FitOutput {
        model,
        stats,
        timings,
    })
}

/// One round of [`fit_to_error`]: the blob budget tried and the Hausdorff error it gave.
#[derive(Clone, Copy, Debug)]
pub struct BudgetRound {
    /// Blobs asked for.
    pub blobs: usize,
    /// Blobs in the model.
    pub kept: usize,
    /// Hausdorff distance to the mesh, % of its bounding-box diagonal.
    pub hausdorff_pct: f64,
}

/// Fit with a growing blob budget (×1.5 a round, from `cfg.blobs`, at most `max_blobs`) until
/// the Hausdorff error of the polygonized model against the mesh, measured by Metro, is at most
/// `max_error_pct` % of the diagonal. Stops early when the selection saturates (asking for more
/// blobs no longer adds any). Returns the last fit and every round, or the first fit's error.
pub fn fit_to_error(
    cfg: &FitConfig,
    input: &LoadedMesh,
    max_error_pct: f64,
    max_blobs: usize,
) -> Result<(FitOutput, Vec<BudgetRound>), FitError> {
    use crate::blobby::polygonize::polygonize;
    use crate::eval::metro::{MetroConfig, compare};
    // A budget decision needs the worst gap, not a publication-grade mean: every vertex of
    // both surfaces plus 60k-200k area samples find it at a fraction of the default's cost.
    let metro = MetroConfig {
        samples_per_face: 1,
        min_samples: 60_000,
        max_samples: 200_000,
        ..MetroConfig::default()
    };
    let mut blobs = cfg.blobs.max(1);
    let mut rounds = Vec::new();
    loop {
        let out = fit(
            &FitConfig {
                blobs,
                ..cfg.clone()
            },
            input,
        )?;
        let surface = polygonize(&out.model.field(), 160);
        let error = compare(&input.mesh, &surface, &metro).hausdorff_pct;
        rounds.push(BudgetRound {
            blobs,
            kept: out.model.blobs.len(),
            hausdorff_pct: error,
        });
        let saturated = out.stats.selected < blobs;
        if error <= max_error_pct || blobs >= max_blobs || saturated {
            return Ok((out, rounds));
        }
        blobs = (blobs + blobs / 2).min(max_blobs);
    }
}
