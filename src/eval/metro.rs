//! Metro distances between two triangle meshes (Cignoni, Rocchini & Scopigno, "Metro: measuring
//! error on simplified surfaces", 1998).
//!
//! Each surface is sampled (area-weighted random points plus every vertex); each sample's
//! distance to the *other* surface is the distance to its nearest point, found through parry's
//! BVH over the other mesh's triangles. Queries run in parallel with rayon; every sample has its
//! own generator (`rng::item_rng(seed, Stream::Eval, i)`) and sums run sequentially in sample
//! order, so a report is bit-identical at any thread count.

use glam::DVec3;
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::{CompositeShapeRef, TriMesh, TriMeshFlags};
use rand::RngExt;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::mesh::Mesh;
use crate::rng::{Stream, item_rng};

/// Settings of a Metro comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct MetroConfig {
    /// Area-weighted samples per face of the larger mesh (default 10, Metro's habit).
    pub samples_per_face: usize,
    /// Lower bound on the area-weighted samples a direction (default 200,000).
    pub min_samples: usize,
    /// Upper bound on the area-weighted samples a direction (default 1,000,000; raised to
    /// `min_samples` if below it). A fine polygonization can have a million faces; ten samples
    /// on each would cost minutes and measure nothing the cap misses: the distance between two
    /// close surfaces varies on the scale of the coarser one's faces.
    pub max_samples: usize,
    /// Also measure every vertex of each surface (default true). Vertices count towards the
    /// maximum only: they are not area-weighted, so they would bias the mean.
    pub include_vertices: bool,
    /// Seed of the sample positions.
    pub seed: u64,
    /// Unit of the percentages; `None` = the bounding-box diagonal of the first mesh.
    pub diagonal: Option<f64>,
}

impl Default for MetroConfig {
    fn default() -> Self {
        MetroConfig {
            samples_per_face: 10,
            min_samples: 200_000,
            max_samples: 1_000_000,
            include_vertices: true,
            seed: 1,
            diagonal: None,
        }
    }
}

impl MetroConfig {
    /// Area-weighted samples a direction for meshes with `faces_a` and `faces_b` triangles:
    /// `samples_per_face · max(faces_a, faces_b)` clamped to `[min_samples, max_samples]`.
    pub fn sample_count(&self, faces_a: usize, faces_b: usize) -> usize {
        let wanted = self.samples_per_face.saturating_mul(faces_a.max(faces_b));
        wanted.min(self.max_samples).max(self.min_samples)
    }
}

/// One-sided distances from the samples of one surface to the other surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Distances {
    /// Area-weighted samples (they give the mean and RMS).
    pub samples: usize,
    /// Vertices measured in addition (they count towards the maximum only).
    pub vertices: usize,
    /// Mean distance, absolute (mesh units).
    pub mean: f64,
    /// Root mean square distance, absolute.
    pub rms: f64,
    /// Largest distance (samples and vertices), absolute.
    pub max: f64,
    /// `mean` as a percentage of the report's diagonal.
    pub mean_pct: f64,
    /// `rms` as a percentage of the report's diagonal.
    pub rms_pct: f64,
    /// `max` as a percentage of the report's diagonal.
    pub max_pct: f64,
}

/// Both directions of a Metro comparison of mesh A (the original) with mesh B.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MetroReport {
    /// Unit of every percentage: A's bounding-box diagonal unless the config named another.
    pub diagonal: f64,
    /// Samples of A measured against B.
    pub a_to_b: Distances,
    /// Samples of B measured against A.
    pub b_to_a: Distances,
    /// Symmetric Hausdorff distance, the larger one-sided maximum, absolute.
    pub hausdorff: f64,
    /// `hausdorff` as a percentage of the diagonal.
    pub hausdorff_pct: f64,
}

impl MetroReport {
    /// Symmetric mean: the larger of the two one-sided means (Metro's convention for a single
    /// "mean error" figure), absolute.
    pub fn mean(&self) -> f64 {
        self.a_to_b.mean.max(self.b_to_a.mean)
    }

    /// [`MetroReport::mean`] as a percentage of the diagonal.
    pub fn mean_pct(&self) -> f64 {
        self.a_to_b.mean_pct.max(self.b_to_a.mean_pct)
    }
}

/// Compare mesh `a` (the original) with mesh `b`: sample both surfaces, measure each sample's
/// distance to the other surface, in both directions.
///
/// Percentages are of `cfg.diagonal`, or of `a`'s bounding-box diagonal. A mesh without
/// triangles has no surface: distances to it are `+∞`, and its own direction has no samples
/// (zero mean and max). Never panics.
pub fn compare(a: &Mesh, b: &Mesh, cfg: &MetroConfig) -> MetroReport {
    let diagonal = cfg.diagonal.unwrap_or_else(|| a.bounds().diagonal());
    let n = cfg.sample_count(a.triangles.len(), b.triangles.len());
    let tree_a = bvh(a);
    let tree_b = bvh(b);
    let a_to_b = one_side(a, tree_b.as_ref(), n, 0, cfg, diagonal);
    let b_to_a = one_side(b, tree_a.as_ref(), n, 1, cfg, diagonal);
    let hausdorff = a_to_b.max.max(b_to_a.max);
    MetroReport {
        diagonal,
        a_to_b,
        b_to_a,
        hausdorff,
        hausdorff_pct: percent(hausdorff, diagonal),
    }
}

/// `x` as a percentage of `diagonal` (0 when the diagonal is 0 and `x` is 0).
fn percent(x: f64, diagonal: f64) -> f64 {
    if x == 0.0 { 0.0 } else { 100.0 * x / diagonal }
}

/// parry's BVH over the mesh's triangles; `None` for a mesh without triangles.
fn bvh(mesh: &Mesh) -> Option<TriMesh> {
    if mesh.triangles.is_empty() {
        return None;
    }
    let n = mesh.positions.len() as u32;
    // Out-of-range triangles (never in a validated mesh) are dropped rather than panicking.
    let tris: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .copied()
        .filter(|t| t.iter().all(|&v| v < n))
        .collect();
    TriMesh::with_flags(mesh.positions.clone(), tris, TriMeshFlags::empty()).ok()
}

/// Distances from `count` area-weighted samples (and the vertices) of `from` to `to`.
/// `direction` separates the two directions' sample streams.
fn one_side(
    from: &Mesh,
    to: Option<&TriMesh>,
    count: usize,
    direction: u64,
    cfg: &MetroConfig,
    diagonal: f64,
) -> Distances {
    let points = area_samples(from, count, cfg.seed, direction);
    let d = match to {
        Some(t) => distances(&points, t),
        None => vec![f64::INFINITY; points.len()],
    };
    let dv: Vec<f64> = match to {
        Some(t) if cfg.include_vertices && !from.triangles.is_empty() => {
            distances(&from.positions, t)
        }
        None if cfg.include_vertices && !from.triangles.is_empty() => {
            vec![f64::INFINITY; from.positions.len()]
        }
        _ => Vec::new(),
    };
    // Sequential sums in sample order: bit-identical at any thread count.
    let m = d.len().max(1) as f64;
    let mean = d.iter().sum::<f64>() / m;
    let rms = (d.iter().map(|x| x * x).sum::<f64>() / m).sqrt();
    let max = d.iter().chain(&dv).fold(0.0f64, |a, &x| a.max(x));
    Distances {
        samples: d.len(),
        vertices: dv.len(),
        mean,
        rms,
        max,
        mean_pct: percent(mean, diagonal),
        rms_pct: percent(rms, diagonal),
        max_pct: percent(max, diagonal),
    }
}

/// Samples a query batch: consecutive samples in Morton order, queried in sequence.
const BATCH: usize = 256;

/// Distance from every point to the surface `to`, in the points' order.
///
/// Points are visited in Morton (Z-curve) order in fixed batches; within a batch each query is
/// bounded by the previous answer through the triangle inequality, `d(p) ≤ |p − q_prev|`, so
/// the BVH prunes from the first node (about 2× fewer node visits). The answer is the exact
/// nearest distance whatever the bound, and batches do not depend on the thread count.
fn distances(points: &[DVec3], to: &TriMesh) -> Vec<f64> {
    let order = morton_order(points);
    let shape = CompositeShapeRef(to);
    let chunks: Vec<Vec<f64>> = order
        .par_chunks(BATCH)
        .map(|chunk| {
            let mut prev: Option<DVec3> = None;
            chunk
                .iter()
                .map(|&i| {
                    let p = points[i as usize];
                    let bounded = prev.and_then(|q| {
                        // A hair above the bound, so the previous answer itself is never pruned.
                        let bound = (p - q).length() * (1.0 + 1e-9) + f64::MIN_POSITIVE;
                        shape.project_local_point(p, bound, false)
                    });
                    let proj = match bounded {
                        Some((_, proj)) => proj,
                        None => to.project_local_point(p, false),
                    };
                    prev = Some(proj.point);
                    (proj.point - p).length()
                })
                .collect()
        })
        .collect();
    let mut out = vec![0.0; points.len()];
    for (&i, d) in order.iter().zip(chunks.into_iter().flatten()) {
        out[i as usize] = d;
    }
    out
}

/// Indices of `points` sorted along a Z-order curve over their bounding box (ties by index).
fn morton_order(points: &[DVec3]) -> Vec<u32> {
    let b = crate::geometry::Aabb::from_points(points);
    let scale = DVec3::splat(1023.0) / b.size().max(DVec3::splat(1e-300));
    let spread = |mut x: u64| {
        // 10 bits → every third bit of 30.
        x &= 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    let mut keyed: Vec<(u64, u32)> = points
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let c = ((*p - b.min) * scale).clamp(DVec3::ZERO, DVec3::splat(1023.0));
            let code = spread(c.x as u64) | (spread(c.y as u64) << 1) | (spread(c.z as u64) << 2);
            (code, i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|k| k.1).collect()
}

/// `count` points uniformly distributed by area over `mesh` (none for a mesh without area).
/// Sample `i` draws from `item_rng(seed, Eval, direction·2⁴⁰ + i)`.
pub fn area_samples(mesh: &Mesh, count: usize, seed: u64, direction: u64) -> Vec<DVec3> {
    let n = mesh.positions.len() as u32;
    // Cumulative areas; a triangle with an out-of-range index gets zero area.
    let mut cdf = Vec::with_capacity(mesh.triangles.len());
    let mut total = 0.0;
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if tri.iter().all(|&v| v < n) {
            let [a, b, c] = mesh.corners(t);
            let area = 0.5 * (b - a).cross(c - a).length();
            if area.is_finite() {
                total += area;
            }
        }
        cdf.push(total);
    }
    if total.is_nan() || total <= 0.0 {
        return Vec::new();
    }
    (0..count)
        .into_par_iter()
        .map(|i| {
            let mut rng = item_rng(seed, Stream::Eval, (direction << 40) + i as u64);
            let u: f64 = rng.random::<f64>() * total;
            let t = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
            let [a, b, c] = mesh.corners(t);
            // Uniform point in a triangle: square-root warp of two uniforms.
            let s = rng.random::<f64>().sqrt();
            let r = rng.random::<f64>();
            a * (1.0 - s) + b * (s * (1.0 - r)) + c * (s * r)
        })
        .collect()
}
