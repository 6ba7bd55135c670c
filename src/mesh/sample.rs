//! Area-weighted surface samples with smooth normals and mean curvature (docs/ARCHITECTURE.md, Decomposition).
//!
//! In: a [`Mesh`], a sample count and a seed. Out: [`SurfaceSamples`] (positions, unit normals
//! interpolated from the area-weighted vertex normals, mean curvature interpolated from the
//! cotangent-Laplacian vertex estimate). Deterministic at any thread count: sample `i` draws
//! from its own generator `item_rng(seed, Stream::Samples, i)`.

// `!(x > 0.0)` is the intended NaN-rejecting test here.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::DVec3;
use rand::RngExt;
use rayon::prelude::*;

use super::Mesh;
use crate::rng::{Stream, item_rng};

/// Points on a mesh surface with their smooth normal and mean curvature estimate.
#[derive(Clone, Debug, Default)]
pub struct SurfaceSamples {
    /// Positions on the surface.
    pub positions: Vec<DVec3>,
    /// Unit outward normals interpolated from area-weighted vertex normals.
    pub normals: Vec<DVec3>,
    /// Mean curvature `H` (1/length), interpolated from per-vertex cotangent-Laplacian values.
    pub mean_curvature: Vec<f64>,
}

impl SurfaceSamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
}

/// `count` area-weighted samples, deterministic for a given `seed` at any thread count.
///
/// A triangle is picked with probability proportional to its area (binary search in the
/// cumulative area table), then a uniform point in it. The normal is the barycentric blend of
/// [`Mesh::vertex_normals`], normalised (the face normal where the blend vanishes); `H` is the
/// blend of [`vertex_mean_curvature`]. A mesh of zero area gives no samples.
pub fn sample_surface(mesh: &Mesh, count: usize, seed: u64) -> SurfaceSamples {
    let cumulative = cumulative_areas(mesh);
    let total = cumulative.last().copied().unwrap_or(0.0);
    if !(total > 0.0) || !total.is_finite() {
        return SurfaceSamples::default();
    }
    let normals = mesh.vertex_normals();
    let curvature = vertex_mean_curvature(mesh);
    let drawn: Vec<(DVec3, DVec3, f64)> = (0..count)
        .into_par_iter()
        .map(|i| {
            let mut rng = item_rng(seed, Stream::Samples, i as u64);
            let target = rng.random::<f64>() * total;
            // First triangle whose cumulative area exceeds the target (skips zero-area ones).
            let t = cumulative
                .partition_point(|&c| c <= target)
                .min(cumulative.len() - 1);
            let (r1, r2): (f64, f64) = (rng.random(), rng.random());
            let s = r1.sqrt();
            let w = [1.0 - s, s * (1.0 - r2), s * r2];
            let tri = mesh.triangles[t];
            let [a, b, c] = mesh.corners(t);
            let p = w[0] * a + w[1] * b + w[2] * c;
            let blended: DVec3 = (0..3).map(|k| w[k] * normals[tri[k] as usize]).sum();
            let n = blended
                .try_normalize()
                .or_else(|| (b - a).cross(c - a).try_normalize())
                .unwrap_or(DVec3::Z);
            let h: f64 = (0..3).map(|k| w[k] * curvature[tri[k] as usize]).sum();
            (p, n, h)
        })
        .collect();
    let mut out = SurfaceSamples {
        positions: Vec::with_capacity(count),
        normals: Vec::with_capacity(count),
        mean_curvature: Vec::with_capacity(count),
    };
    for (p, n, h) in drawn {
        out.positions.push(p);
        out.normals.push(n);
        out.mean_curvature.push(h);
    }
    out
}

/// Running sum of triangle areas (non-finite areas count as zero).
fn cumulative_areas(mesh: &Mesh) -> Vec<f64> {
    let mut acc = 0.0;
    (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            let area = 0.5 * (b - a).cross(c - a).length();
            if area.is_finite() {
                acc += area;
            }
            acc
        })
        .collect()
}

/// Largest cotangent magnitude used by the Laplacian (angles below ~0.6°).
const MAX_COT: f64 = 100.0;

/// Cotangent of the angle between `u` and `v`, clamped to `±MAX_COT` (0 for degenerate input).
#[inline]
fn cot(u: DVec3, v: DVec3) -> f64 {
    let sin = u.cross(v).length();
    let cos = u.dot(v);
    if !(sin > 0.0) {
        return 0.0;
    }
    (cos / sin).clamp(-MAX_COT, MAX_COT)
}

/// Per-vertex mean curvature `H` from the cotangent Laplacian (1/length; sign: positive convex).
///
/// `K_i = 1/(2 A_i) Σ_j (cot α_ij + cot β_ij)(p_i − p_j)` with the mixed Voronoi area `A_i`
/// (Meyer et al. 2003), and `H_i = ½ K_i · n_i` with the area-weighted vertex normal. Cotangents
/// are clamped and degenerate triangles skipped, so the result is always finite (0 for vertices
/// without area).
pub fn vertex_mean_curvature(mesh: &Mesh) -> Vec<f64> {
    let nv = mesh.positions.len();
    let mut lap = vec![DVec3::ZERO; nv];
    let mut area = vec![0.0f64; nv];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let p = mesh.corners(t);
        let double_area = (p[1] - p[0]).cross(p[2] - p[0]).length();
        if !(double_area > 0.0) || !double_area.is_finite() {
            continue;
        }
        let tri_area = 0.5 * double_area;
        for k in 0..3 {
            // Corner k, opposite edge (i, j).
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let c = cot(p[i] - p[k], p[j] - p[k]);
            let e = p[i] - p[j];
            lap[tri[i] as usize] += c * e;
            lap[tri[j] as usize] -= c * e;
        }
        // Mixed area: Voronoi for non-obtuse triangles, else the obtuse rule.
        let obtuse = (0..3).find(|&k| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            (p[i] - p[k]).dot(p[j] - p[k]) < 0.0
        });
        match obtuse {
            None => {
                for k in 0..3 {
                    let (i, j) = ((k + 1) % 3, (k + 2) % 3);
                    // Voronoi share of corner i from edge (i, j) uses the angle at k, etc.
                    let c_k = cot(p[i] - p[k], p[j] - p[k]);
                    let l2 = (p[i] - p[j]).length_squared();
                    area[tri[i] as usize] += c_k * l2 / 8.0;
                    area[tri[j] as usize] += c_k * l2 / 8.0;
                }
            }
            Some(k) => {
                for m in 0..3 {
                    area[tri[m] as usize] += if m == k {
                        tri_area / 2.0
                    } else {
                        tri_area / 4.0
                    };
                }
            }
        }
    }
    let normals = mesh.vertex_normals();
    (0..nv)
        .map(|v| {
            if area[v] > 0.0 {
                let h = 0.5 * lap[v].dot(normals[v]) / (2.0 * area[v]);
                if h.is_finite() { h } else { 0.0 }
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Icosphere subdivided `level` times, radius `r`.
    pub(crate) fn sphere(r: f64, level: usize) -> Mesh {
        let mut m = crate::mesh::builtin::icosphere(level as u32);
        for p in &mut m.positions {
            *p *= r;
        }
        m
    }

    #[test]
    fn sphere_curvature_is_one_over_radius() {
        let m = sphere(2.0, 4);
        assert!(m.signed_volume() > 0.0);
        let h = vertex_mean_curvature(&m);
        for (v, &hv) in h.iter().enumerate() {
            assert!((hv - 0.5).abs() < 0.03, "vertex {v}: H = {hv}");
        }
    }

    #[test]
    fn degenerate_triangles_give_finite_curvature() {
        let mut m = sphere(1.0, 2);
        // Collapse one vertex onto another: zero-area and needle triangles.
        m.positions[7] = m.positions[0];
        m.positions.push(m.positions[0]); // an isolated duplicate of vertex 0
        m.triangles.push([0, 6, 0]);
        assert!(vertex_mean_curvature(&m).iter().all(|h| h.is_finite()));
    }

    #[test]
    fn samples_lie_on_the_sphere_with_radial_normals() {
        let m = sphere(1.5, 3);
        let s = sample_surface(&m, 2000, 7);
        assert_eq!(s.len(), 2000);
        for (p, n) in s.positions.iter().zip(&s.normals) {
            assert!(p.length() <= 1.5 + 1e-12 && p.length() > 1.45, "{p}");
            assert!((n.length() - 1.0).abs() < 1e-12);
            assert!(n.dot(p.normalize()) > 0.995);
        }
        // Area weighting: the octants are balanced.
        let upper = s.positions.iter().filter(|p| p.y > 0.0).count();
        assert!((900..1100).contains(&upper), "{upper}");
    }
}
