//! The fitting pipeline, mesh → blob model: surface samples → seeds and candidate growth →
//! greedy selection → blobs → optimisation. Each stage is timed.

use glam::DVec3;

use crate::blobby::fit::{FaithfulConfig, objective, optimise_faithful};
use crate::blobby::model_file::MODEL_VERSION;
use crate::blobby::optimise::{
    Budget, FullConfig, FullProblem, drop_dead, drop_negligible, far_field_points,
};
use crate::blobby::{Blob, BlobField, BlobModel, SourceInfo, THRESHOLD};
use crate::decompose::{self, DecomposeConfig, ObstacleShift, Primitive};
use crate::mesh::LoadedMesh;
use crate::mesh::sample::sample_surface;
use crate::progress::Timings;

/// Version of what [`fit`] produces. Bump it with every change that alters the model a given
/// [`FitConfig`] and mesh fit to (optimiser, decomposition, sampling, defaults): the scenes'
/// fitted-target cache is keyed on it, so old cache files are then refitted instead of reused.
/// A test in `scene::target` pins a small fit's output to this number.
pub const FIT_ALGORITHM_VERSION: u32 = 1;

/// How the blobs' parameters are optimised after decomposition.
#[derive(Clone, Debug)]
pub enum Optimisation {
    /// Keep the starting `A`, `B = (1+A)/A`.
    None,
    /// The paper's per-blob Nelder–Mead on `(A, B)`.
    Faithful(FaithfulConfig),
    /// Beyond the paper: the faithful pass, then every parameter by block Levenberg–Marquardt.
    Full(FaithfulConfig, FullConfig),
}

/// Settings of a fit. Lengths are relative to the mesh's bounding-box diagonal.
#[derive(Clone, Debug)]
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

impl Default for FitConfig {
    fn default() -> Self {
        let d = DecomposeConfig::default();
        FitConfig {
            blobs: 300,
            candidates: d.candidates,
            samples: 60_000,
            primitive: d.primitive,
            shift: d.shift,
            epsilon: d.epsilon,
            voxels: d.voxels,
            curvature_weight: d.curvature_weight,
            initial_a: 1.0,
            optimisation: Optimisation::Full(FaithfulConfig::default(), FullConfig::default()),
            seed: 1,
        }
    }
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

/// Fit a blob model to a loaded, validated mesh.
pub fn fit(cfg: &FitConfig, input: &LoadedMesh) -> FitOutput {
    let mesh = &input.mesh;
    let bounds = mesh.bounds();
    let mut timings = Timings::default();
    let samples = timings.stage("samples", || sample_surface(mesh, cfg.samples, cfg.seed));
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
    let candidates = timings.stage("grow", || decompose::grow_candidates(&dcfg, mesh, &samples));
    let order = timings.stage("select", || {
        decompose::select_greedy(&dcfg, &bounds, &candidates)
    });
    let mut blobs: Vec<Blob> = order
        .iter()
        .map(|&i| Blob::from_ellipsoid(&candidates[i].ellipsoid, cfg.initial_a))
        .collect();
    let points: &[DVec3] = &samples.positions;
    let (before, after) = timings.stage("optimise", || match &cfg.optimisation {
        Optimisation::None => {
            let o = objective(&BlobField::new(&blobs, THRESHOLD), points);
            (o, o)
        }
        Optimisation::Faithful(f) => optimise_faithful(f, &mut blobs, points, THRESHOLD),
        Optimisation::Full(f, full) => {
            let (before, _) = optimise_faithful(f, &mut blobs, points, THRESHOLD);
            let far = far_field_points(mesh, 40);
            let problem = FullProblem::new(full, &samples, &far, bounds.diagonal(), THRESHOLD);
            let mut anchors = blobs.clone();
            problem.optimise(&mut blobs, &anchors, full.sweeps, None);
            // Dead blobs (switched off by the faithful pass) are wasted bytes: drop them,
            // keeping the selection order of the rest; their budget is spent where the model
            // falls shortest. Blobs left negligible at the end go too (bytes and render time).
            let mut used = vec![false; candidates.len()];
            for (b, &i) in blobs.iter().zip(&order) {
                used[i] = b.is_live();
            }
            drop_dead(&mut blobs, &mut anchors);
            let ellipsoids: Vec<_> = candidates.iter().map(|c| c.ellipsoid).collect();
            let budget = Budget {
                blobs: cfg.blobs,
                candidates: &ellipsoids,
                initial_a: cfg.initial_a,
            };
            budget.spend(&problem, &mut blobs, &mut anchors, &mut used, points);
            drop_negligible(&mut blobs, THRESHOLD);
            let after = objective(&BlobField::new(&blobs, THRESHOLD), points);
            (before, after)
        }
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
        blobs,
    };
    let stats = FitStats {
        samples: points.len(),
        candidates: candidates.len(),
        selected: order.len(),
        live: model.live_count(),
        objective_before: before,
        objective_after: after,
        median_sphere_radius: median,
    };
    FitOutput {
        model,
        stats,
        timings,
    }
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
/// blobs no longer adds any). Returns the last fit and every round.
pub fn fit_to_error(
    cfg: &FitConfig,
    input: &LoadedMesh,
    max_error_pct: f64,
    max_blobs: usize,
) -> (FitOutput, Vec<BudgetRound>) {
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
        );
        let surface = polygonize(&out.model.field(), 160);
        let error = compare(&input.mesh, &surface, &metro).hausdorff_pct;
        rounds.push(BudgetRound {
            blobs,
            kept: out.model.blobs.len(),
            hausdorff_pct: error,
        });
        let saturated = out.stats.selected < blobs;
        if error <= max_error_pct || blobs >= max_blobs || saturated {
            return (out, rounds);
        }
        blobs = (blobs + blobs / 2).min(max_blobs);
    }
}
