//! The one entry of blob optimisation, [`optimise`]: from the decomposition's selected
//! ellipsoids to the final blobs, every step of a fit after selection in order (see
//! docs/ARCHITECTURE.md, "Optimisation").

use glam::DVec3;

use super::{Budget, FullConfig, FullProblem, Placement, drop_negligible, far_field_points};
use crate::blobby::fit::{FaithfulConfig, objective, optimise_faithful};
use crate::blobby::{Blob, BlobField};
use crate::geometry::Ellipsoid;
use crate::mesh::Mesh;
use crate::mesh::sample::SurfaceSamples;
use crate::mesh::winding::WindingNumber;

/// How the blobs' parameters are optimised after decomposition.
#[derive(Clone, Debug, serde::Serialize)]
pub enum Optimisation {
    /// Keep the starting `A`, `B = (1+A)/A`.
    None,
    /// The paper's per-blob Nelder–Mead on `(A, B)`.
    Faithful(FaithfulConfig),
    /// Beyond the paper: the faithful pass, then every parameter by block Levenberg–Marquardt,
    /// the adaptive budget and the dropping of dead and negligible blobs.
    Full(FaithfulConfig, FullConfig),
}

/// What a fit approximates: the mesh, its surface samples and its solid (winding number).
#[derive(Clone, Copy)]
pub struct Target<'a> {
    /// The mesh (for far-field distances).
    pub mesh: &'a Mesh,
    /// Its area-weighted surface samples with normals.
    pub samples: &'a SurfaceSamples,
    /// Its generalized winding number: inside is `w > ½`.
    pub solid: &'a WindingNumber,
}

/// Where optimisation starts: the decomposition's candidates and the selected ones, in order.
#[derive(Clone, Copy)]
pub struct Start<'a> {
    /// Every grown candidate ellipsoid (the adaptive budget's pool).
    pub candidates: &'a [Ellipsoid],
    /// Indices of the selected candidates, in selection order: the starting blobs.
    pub selected: &'a [usize],
    /// Starting `A` of every blob.
    pub initial_a: f64,
    /// Blobs the model may have (the adaptive budget fills up to this).
    pub max_blobs: usize,
}

/// The optimised blobs and the objective `(1/m) Σ F(p)²` over the samples before and after.
#[derive(Clone, Debug)]
pub struct Optimised {
    /// The final blobs (dead and negligible ones dropped in full mode).
    pub blobs: Vec<Blob>,
    /// Objective of the starting blobs.
    pub objective_before: f64,
    /// Objective of the final blobs.
    pub objective_after: f64,
}

/// Optimise the selected blobs against the target at iso-level `threshold`. Full mode runs, in
/// order: the faithful pass (the paper's `(A, B)` fit, which also switches off redundant
/// blobs); the full problem on every blob; the drop of the blobs the passes switched off; the
/// adaptive budget (their count and the selection's held-back share, see
/// [`FullConfig::budget_reserve`], spent at the worst shortfalls from the unused candidates);
/// final sweeps over every blob; in small models, swap rounds that move the least useful
/// blobs to the worst shortfalls (see [`FullConfig::swap_rounds`]); the drop of negligible
/// blobs. Deterministic at any thread count.
pub fn optimise(how: &Optimisation, target: &Target, start: &Start, threshold: f64) -> Optimised {
    let held_back = match how {
        Optimisation::Full(_, full) => full.held_back(start.selected.len()),
        _ => 0,
    };
    let mut blobs: Vec<Blob> = start.selected[..start.selected.len() - held_back]
        .iter()
        .map(|&i| Blob::from_ellipsoid(&start.candidates[i], start.initial_a))
        .collect();
    let points: &[DVec3] = &target.samples.positions;
    let (objective_before, objective_after) = match how {
        Optimisation::None => {
            let o = objective(&BlobField::new(&blobs, threshold), points);
            (o, o)
        }
        Optimisation::Faithful(f) => optimise_faithful(f, &mut blobs, points, threshold),
        Optimisation::Full(f, full) => {
            let (before, _) = optimise_faithful(f, &mut blobs, points, threshold);
            full_steps(full, target, start, &mut blobs, threshold);
            (
                before,
                objective(&BlobField::new(&blobs, threshold), points),
            )
        }
    };
    Optimised {
        blobs,
        objective_before,
        objective_after,
    }
}

/// The full mode's steps after the faithful pass (see [`optimise`]).
fn full_steps(
    cfg: &FullConfig,
    target: &Target,
    start: &Start,
    blobs: &mut Vec<Blob>,
    threshold: f64,
) {
    let diag = target.mesh.bounds().diagonal();
    let far = far_field_points(target.mesh, target.solid, 40);
    let problem = FullProblem::new(
        cfg,
        target.samples,
        Some(target.solid),
        &far,
        diag,
        threshold,
    );
    let anchors = blobs.clone();
    problem.optimise(blobs, &anchors, cfg.sweeps, None, cfg.shape_prior);
    // Dead blobs (switched off by the faithful pass) are wasted bytes: drop them, keeping the
    // selection order of the rest; their budget is spent where the model falls shortest.
    // Blobs left negligible at the end go too (bytes and render time).
    let mut used = vec![false; start.candidates.len()];
    for (b, &i) in blobs.iter().zip(start.selected) {
        used[i] = b.is_live();
    }
    let mut placed = Placement {
        blobs: std::mem::take(blobs),
        anchors,
        used,
    };
    placed.drop_dead();
    let budget = Budget {
        blobs: start.max_blobs,
        candidates: start.candidates,
        initial_a: start.initial_a,
        points: &target.samples.positions,
    };
    budget.spend(&problem, &mut placed);
    // The budget re-fits only around the blobs it adds; a last pass over all lets the rest
    // settle with them.
    problem.optimise(
        &mut placed.blobs,
        &placed.anchors,
        cfg.final_sweeps,
        None,
        cfg.final_shape_prior,
    );
    if cfg.is_small(start.selected.len()) {
        budget.swap(&problem, &mut placed);
    }
    *blobs = placed.blobs;
    drop_negligible(blobs, threshold);
}
