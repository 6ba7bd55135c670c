//! Ellipsoid decomposition (paper §3, after Bischoff & Kobbelt 2002; docs/ARCHITECTURE.md,
//! Decomposition):
//! grow one candidate ellipsoid per seed vertex against shifted surface samples (obstacles),
//! then pick a covering subset by greedy weighted voxel coverage.
//!
//! In: a mesh and its [`SurfaceSamples`]. Out: [`Candidate`]s and a selection order.
//!
//! Files: `obstacles` (spatially sorted SoA obstacle chunks and the pruned first-touch search),
//! `grow` (the three growth stages of one seed), `quadric` and `eigen` (symmetric quadrics →
//! ellipsoids), `select` (voxel rasterisation and lazy greedy coverage).
//!
//! Seed placement: obstacles are the samples shifted by `σ·ε·D` along
//! their smooth normal (`σ` = +1 outward, −1 inward, 0 none); the seed is the simplified-mesh
//! vertex moved by `(σ − 1)·ε·D` along its vertex normal, i.e. always `ε·D` *inside* the
//! obstacle layer. With the outward default the seed stays on the mesh. That gap keeps the
//! faces around a seed vertex (which dip below its tangent plane linearly with distance) from
//! collapsing the inscribed sphere to a needle.

// `!(x > 0.0)` is the intended NaN-rejecting test throughout the decomposition.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::DVec3;
use serde::{Deserialize, Serialize};

use rayon::prelude::*;

use crate::geometry::{Aabb, Ellipsoid};
use crate::mesh::Mesh;
use crate::mesh::sample::{SurfaceSamples, vertex_mean_curvature};
use crate::mesh::simplify::simplified_vertex_indices;
use crate::mesh::winding::WindingNumber;

pub mod eigen;
pub mod grow;
pub mod obstacles;
pub mod quadric;
pub mod select;

use grow::{GrowLimits, grow_seed};
use obstacles::ObstacleSet;

/// Semi-axis cap as a fraction of `D` (open meshes would otherwise grow without bound).
pub const MAX_SEMI_AXIS: f64 = 0.5;

/// Clearance kept from each stage's contact before the next stage grows, fraction of `D`
/// (see [`grow`]).
pub const CONTACT_MARGIN: f64 = 5e-4;

/// Smallest semi-axis of an accepted perpendicular-stage ellipsoid, in mean sample spacings
/// `√(area / samples)` (see [`grow`]).
pub const STAGE3_MIN_AXIS: f64 = 1.5;

/// Seeds whose inscribed sphere is below this fraction of `D` are dropped.
pub const MIN_SPHERE_RADIUS: f64 = 1e-4;

/// Which way obstacles are shifted off the surface (paper §3.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ObstacleShift {
    /// Along the outward normal: the paper's change, keeps small features (default).
    #[default]
    Outward,
    /// Along the inward normal: Bischoff & Kobbelt's original scheme.
    Inward,
    /// Obstacles are the surface samples themselves.
    None,
}

/// The blob primitive.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Primitive {
    /// Full three-stage growth: general ellipsoids (default).
    #[default]
    Ellipsoid,
    /// Inscribed spheres only (stage 1): the spherical baseline.
    Sphere,
}

impl Primitive {
    /// Every primitive, in the order of their names.
    pub const ALL: [Primitive; 2] = [Primitive::Ellipsoid, Primitive::Sphere];

    /// The primitive's name: `ellipsoid` or `sphere` (the CLI's `--primitive` values).
    pub fn name(self) -> &'static str {
        match self {
            Primitive::Ellipsoid => "ellipsoid",
            Primitive::Sphere => "sphere",
        }
    }

    /// The primitive named `name` ([`Primitive::name`]), or the message naming them.
    pub fn from_name(name: &str) -> Result<Primitive, String> {
        Primitive::ALL
            .into_iter()
            .find(|p| p.name() == name)
            .ok_or_else(|| format!("primitive must be 'ellipsoid' or 'sphere', got {name:?}"))
    }
}

/// Settings of the decomposition; every length is relative to the mesh's diagonal `D`.
#[derive(Clone, Debug)]
pub struct DecomposeConfig {
    /// Target number of seed vertices (quadric simplification); default
    /// [`DecomposeConfig::DEFAULT_CANDIDATES`].
    pub candidates: usize,
    /// Obstacle shift direction; default outward.
    pub shift: ObstacleShift,
    /// Obstacle shift `ε` as a fraction of `D`; default 0.002.
    pub epsilon: f64,
    /// Ellipsoids or spheres.
    pub primitive: Primitive,
    /// Voxel cells along the bounding box's longest side; default 110.
    pub voxels: usize,
    /// Curvature weighting `λ` in `w = 1 + λ·|H|·D` (clamped); default 0.05 (`|H|·D` is ≥ 3.5
    /// for any closed surface and ~12 on a typical model, so `λ = 1` would saturate every
    /// weight at the clamp).
    pub curvature_weight: f64,
    /// Upper clamp of the weight `w`; default 4.0.
    pub max_weight: f64,
    /// Stop selecting when this many are selected; default
    /// [`DecomposeConfig::DEFAULT_MAX_SELECTED`].
    pub max_selected: usize,
    /// Stop when the best gain falls below this fraction of the covered (weighted) volume;
    /// default 1e-5 (a few voxels of a 110-voxel model).
    pub min_gain_fraction: f64,
}

impl DecomposeConfig {
    /// Default number of candidate seeds (the fit's default too).
    pub const DEFAULT_CANDIDATES: usize = 2500;
    /// Default number of ellipsoids selected (the fit's default blob budget).
    pub const DEFAULT_MAX_SELECTED: usize = 300;
}

impl Default for DecomposeConfig {
    fn default() -> Self {
        DecomposeConfig {
            candidates: Self::DEFAULT_CANDIDATES,
            shift: ObstacleShift::Outward,
            epsilon: 0.002,
            primitive: Primitive::Ellipsoid,
            voxels: 110,
            curvature_weight: 0.05,
            max_weight: 4.0,
            max_selected: Self::DEFAULT_MAX_SELECTED,
            min_gain_fraction: 1e-5,
        }
    }
}

/// One grown candidate.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// The grown ellipsoid (a sphere for [`Primitive::Sphere`]).
    pub ellipsoid: Ellipsoid,
    /// Mesh vertex it grew from.
    pub seed_vertex: u32,
    /// Seed position and outward normal.
    pub seed: (DVec3, DVec3),
    /// Radius of the stage-1 inscribed sphere.
    pub sphere_radius: f64,
    /// Selection weight `w = 1 + λ·|H|·D`, clamped.
    pub weight: f64,
    /// Last growth stage that succeeded (1 sphere, 2 wedge, 3 perpendicular).
    pub stage: u8,
}

impl ObstacleShift {
    /// Signed multiple `σ` of `ε·D` that obstacles are moved along their outward normal.
    pub fn sign(self) -> f64 {
        match self {
            ObstacleShift::Outward => 1.0,
            ObstacleShift::Inward => -1.0,
            ObstacleShift::None => 0.0,
        }
    }
}

/// The obstacle points: every sample moved by `σ·ε·D` along its normal (`diagonal` = `D`).
pub fn obstacles(cfg: &DecomposeConfig, samples: &SurfaceSamples, diagonal: f64) -> Vec<DVec3> {
    let shift = cfg.shift.sign() * cfg.epsilon * diagonal;
    samples
        .positions
        .iter()
        .zip(&samples.normals)
        .map(|(p, n)| *p + shift * *n)
        .collect()
}

/// Where the growth of a seed at mesh vertex `v` (unit normal `n`) starts: `ε·D` inside the
/// obstacle layer (see the module notes).
pub fn seed_point(cfg: &DecomposeConfig, v: DVec3, n: DVec3, diagonal: f64) -> DVec3 {
    v + (cfg.shift.sign() - 1.0) * cfg.epsilon * diagonal * n
}

/// Grow one candidate per simplified-mesh vertex; `inside` is the mesh's winding number (the
/// guard against ellipsoids grown out of the solid). Deterministic; parallel over seeds.
pub fn grow_candidates(
    cfg: &DecomposeConfig,
    mesh: &Mesh,
    inside: &WindingNumber,
    samples: &SurfaceSamples,
) -> Vec<Candidate> {
    let diagonal = mesh.bounds().diagonal();
    let obstacles = ObstacleSet::new(&obstacles(cfg, samples, diagonal), &samples.normals);
    if obstacles.is_empty() || !(diagonal > 0.0) {
        return Vec::new();
    }
    let seeds = simplified_vertex_indices(mesh, cfg.candidates);
    let normals = mesh.vertex_normals();
    let curvature = vertex_mean_curvature(mesh);
    let limits = GrowLimits {
        max_semi_axis: MAX_SEMI_AXIS * diagonal,
        min_radius: MIN_SPHERE_RADIUS * diagonal,
        sphere_only: cfg.primitive == Primitive::Sphere,
        surface_normal_at_q: false,
        margin: CONTACT_MARGIN * diagonal,
        min_stage3_axis: STAGE3_MIN_AXIS * (mesh.area() / obstacles.len() as f64).sqrt(),
    };
    let distance = parry3d_f64::shape::TriMesh::with_flags(
        mesh.positions.clone(),
        mesh.triangles.clone(),
        parry3d_f64::shape::TriMeshFlags::empty(),
    )
    .ok();
    let guard = distance.as_ref().map(|d| SolidGuard {
        inside,
        distance: d,
    });
    seeds
        .par_iter()
        .map_init(Vec::new, |order, &v| {
            let (pos, n) = (mesh.positions[v as usize], normals[v as usize]);
            if n == DVec3::ZERO {
                return None;
            }
            let p = seed_point(cfg, pos, n, diagonal);
            obstacles.chunks_by_distance(p, order);
            let mut g = grow_seed(&obstacles, order, p, n, &limits)?;
            if g.stage > 1 && leaves_mesh(guard.as_ref(), &g.ellipsoid, 0.005 * diagonal) {
                // Grown through a gap between samples: keep the stage-1 sphere, always safe.
                g.ellipsoid = Ellipsoid {
                    center: p - n * g.sphere_radius,
                    rotation: glam::DQuat::IDENTITY,
                    semi_axes: DVec3::splat(g.sphere_radius),
                };
                g.stage = 1;
            }
            let h = curvature[v as usize];
            let w = 1.0 + cfg.curvature_weight * h.abs() * diagonal;
            Some(Candidate {
                ellipsoid: g.ellipsoid,
                seed_vertex: v,
                seed: (pos, n),
                sphere_radius: g.sphere_radius,
                weight: if w.is_finite() {
                    w.clamp(1.0, cfg.max_weight.max(1.0))
                } else {
                    1.0
                },
                stage: g.stage,
            })
        })
        .collect::<Vec<_>>()
        .into_iter()
        .flatten()
        .collect()
}

/// The solid a mesh describes, for [`leaves_mesh`]: its winding number says which side a point
/// is on (right for open scans and soups too), the triangle BVH how far from the surface.
struct SolidGuard<'a> {
    inside: &'a WindingNumber,
    distance: &'a parry3d_f64::shape::TriMesh,
}

/// True when a point of `e` (its axis ends and the corners of its inscribed box, at 95 %) lies
/// outside the solid (winding number ≤ ½) by more than `tolerance`. Point samples can leave
/// gaps that an elongated quadric slips through (between a cow's legs, along thin parts, out
/// of a scan's holes); this catches such needles. Without a triangle BVH (`None`: parry
/// rejected the mesh), nothing is rejected.
fn leaves_mesh(guard: Option<&SolidGuard>, e: &Ellipsoid, tolerance: f64) -> bool {
    use parry3d_f64::query::PointQuery;
    let Some(guard) = guard else {
        return false;
    };
    let c = 0.95 / 3f64.sqrt();
    let axes = [
        DVec3::X,
        -DVec3::X,
        DVec3::Y,
        -DVec3::Y,
        DVec3::Z,
        -DVec3::Z,
    ]
    .map(|a| a * 0.95);
    let corners = (0..8).map(|k| {
        DVec3::new(
            if k & 1 == 0 { c } else { -c },
            if k & 2 == 0 { c } else { -c },
            if k & 4 == 0 { c } else { -c },
        )
    });
    axes.into_iter().chain(corners).any(|local| {
        let x = e.center + e.rotation * (local * e.semi_axes);
        !guard.inside.inside(x)
            && guard
                .distance
                .project_local_point(x, false)
                .point
                .distance(x)
                > tolerance
    })
}

/// Greedy weighted maximum coverage over a voxel grid of `bounds`; returns candidate indices
/// in selection order (first = largest weighted gain).
pub fn select_greedy(cfg: &DecomposeConfig, bounds: &Aabb, candidates: &[Candidate]) -> Vec<usize> {
    select::select_greedy(cfg, bounds, candidates)
}
