//! Full optimisation (beyond the paper, DESIGN.md §4): every blob parameter — centre, rotation,
//! influence radii and `B` — on a geometric residual `F/|∇F|` at surface samples, plus one-sided
//! sign constraints just inside (`F > 0`) and outside (`F < 0`) the surface so that no spurious
//! surface appears away from the mesh.
//!
//! Solver: block-coordinate Levenberg–Marquardt. One blob's 10 parameters against the points
//! inside its support form a 10×10 normal system; blobs that share no point are updated in
//! parallel (greedy colouring of the overlap graph, so the result does not depend on the thread
//! count); `|∇F|` is held fixed within a sweep. Dead blobs (tiny `B`) are re-seeded where the
//! residual is largest.
//!
//! Parametrisation: the field of a blob depends only on its influence radii `r = s·√(1+A)`:
//! `f = B²(1 − |diag(1/r)·Rᵀ(x−c)|²)²`, so `A` is kept fixed and `s` is moved with `r`.

use glam::{DMat3, DQuat, DVec3};
use rayon::prelude::*;

use super::{Blob, BlobField};
use crate::mesh::sample::SurfaceSamples;

/// Settings of the full optimisation. Offsets are fractions of the diagonal `D`.
#[derive(Clone, Debug)]
pub struct FullConfig {
    /// Gauss–Seidel sweeps over all blobs.
    pub sweeps: usize,
    /// LM iterations per blob per sweep.
    pub iterations: usize,
    /// Offsets along `−n` of the inside constraint points.
    pub inside_offsets: Vec<f64>,
    /// Offsets along `+n` of the outside constraint points.
    pub outside_offsets: Vec<f64>,
    /// Weight of a sign-constraint residual relative to a surface residual.
    pub constraint_weight: f64,
    /// Field margin `τ`: inside points want `F ≥ τ`, outside points `F ≤ −τ`.
    pub margin: f64,
    /// Use at most this many surface samples (evenly strided) per point kind.
    pub max_points: usize,
    /// Blobs whose `B` falls below this are re-seeded (0 = never).
    pub b_floor: f64,
    /// Strength of the prior keeping radii and centres near the decomposition, as a length
    /// in units of `D` (see `Sweep::improve`).
    pub shape_prior: f64,
}

impl Default for FullConfig {
    fn default() -> Self {
        FullConfig {
            sweeps: 4,
            iterations: 2,
            inside_offsets: vec![0.005, 0.02],
            outside_offsets: vec![0.005, 0.03, 0.1],
            constraint_weight: 0.5,
            margin: 0.05,
            max_points: 20_000,
            // Re-seeding as small spheres measured worse on thin shapes (a sphere of 2 % of D
            // pokes through a horse's leg), so it is off by default; dead blobs are dropped.
            b_floor: 0.0,
            shape_prior: 0.002,
        }
    }
}

/// What happened during a full optimisation.
#[derive(Clone, Debug, Default)]
pub struct FullReport {
    /// RMS of `F/|∇F|` at the surface samples before, as a fraction of `D`.
    pub rms_before: f64,
    /// The same after.
    pub rms_after: f64,
    /// Blobs re-seeded because they had died.
    pub reseeded: usize,
}

/// What a constraint point wants of the field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Surface,
    Inside,
    Outside,
}

/// Constraint points as SoA.
struct Points {
    x: Vec<DVec3>,
    n: Vec<DVec3>,
    kind: Vec<Kind>,
}

/// Surface samples bucketed in a uniform grid, for "is any sample within r of q?" queries.
struct SampleGrid<'a> {
    points: &'a [DVec3],
    inv_cell: f64,
    /// `(cell key, sample index)` sorted by key.
    keyed: Vec<(u64, u32)>,
}

impl<'a> SampleGrid<'a> {
    fn new(points: &'a [DVec3], cell: f64) -> SampleGrid<'a> {
        let inv_cell = 1.0 / cell;
        let mut keyed: Vec<(u64, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, &p)| (Self::key(Self::cell_of(p, inv_cell)), i as u32))
            .collect();
        keyed.sort_unstable();
        SampleGrid {
            points,
            inv_cell,
            keyed,
        }
    }

    fn cell_of(p: DVec3, inv_cell: f64) -> [i64; 3] {
        let c = (p * inv_cell).floor();
        [c.x as i64, c.y as i64, c.z as i64]
    }

    fn key(c: [i64; 3]) -> u64 {
        // 21 bits an axis, offset so negative cells pack too.
        let f = |v: i64| ((v + (1 << 20)) as u64) & 0x1F_FFFF;
        f(c[0]) | (f(c[1]) << 21) | (f(c[2]) << 42)
    }

    /// True when some sample lies within `r` (at most one cell) of `q`.
    fn any_within(&self, q: DVec3, r: f64) -> bool {
        let c = Self::cell_of(q, self.inv_cell);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let k = Self::key([c[0] + dx, c[1] + dy, c[2] + dz]);
                    let lo = self.keyed.partition_point(|e| e.0 < k);
                    let hit = self.keyed[lo..]
                        .iter()
                        .take_while(|e| e.0 == k)
                        .any(|e| self.points[e.1 as usize].distance_squared(q) < r * r);
                    if hit {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// Surface points and offset constraint points. An offset point is kept only when no surface
/// sample is nearer than 80 % of its offset: a point pushed through a thin part or into a
/// concavity would otherwise demand the wrong sign.
fn constraint_points(
    cfg: &FullConfig,
    samples: &SurfaceSamples,
    far: &[(DVec3, bool)],
    diag: f64,
) -> Points {
    let m = samples.positions.len();
    let stride = m.div_ceil(cfg.max_points.max(1)).max(1);
    let mut pts = Points {
        x: Vec::new(),
        n: Vec::new(),
        kind: Vec::new(),
    };
    let offsets = std::iter::once((Kind::Surface, 0.0))
        .chain(cfg.inside_offsets.iter().map(|&o| (Kind::Inside, -o)))
        .chain(cfg.outside_offsets.iter().map(|&o| (Kind::Outside, o)));
    for (kind, off) in offsets {
        // Cells as wide as the clearance radius: the query then scans 27 small cells, not
        // 27 cells sized for the largest offset (that was a third of the whole fit's time).
        let r = 0.8 * off.abs() * diag;
        let grid = (off != 0.0).then(|| SampleGrid::new(&samples.positions, r));
        let candidates: Vec<(DVec3, DVec3)> = (0..m)
            .step_by(stride)
            .collect::<Vec<_>>()
            .par_iter()
            .filter_map(|&i| {
                let n = samples.normals[i];
                let x = samples.positions[i] + n * (off * diag);
                let clear = grid.as_ref().is_none_or(|g| !g.any_within(x, r));
                clear.then_some((x, n))
            })
            .collect();
        for (x, n) in candidates {
            pts.x.push(x);
            pts.n.push(n);
            pts.kind.push(kind);
        }
    }
    for &(x, inside) in far {
        pts.x.push(x);
        pts.n.push(DVec3::ZERO);
        pts.kind
            .push(if inside { Kind::Inside } else { Kind::Outside });
    }
    pts
}

/// Far-field sign constraints: points of a coarse grid over the mesh's bounds (expanded by
/// 15 % of `D`, `resolution` cells on the longest side) that lie farther than `1.5 %` of `D` from
/// the surface, with whether they are inside. They stop blobs from growing a spurious surface
/// away from the mesh, where no offset sample reaches. Inside/outside comes from parry's
/// pseudo-normal test, so the mesh must be consistently oriented; an unusable mesh gives none.
pub fn far_field_points(mesh: &crate::mesh::Mesh, resolution: usize) -> Vec<(DVec3, bool)> {
    use parry3d_f64::query::PointQuery;
    use parry3d_f64::shape::{TriMesh, TriMeshFlags};
    let bounds = mesh.bounds();
    let diag = bounds.diagonal();
    let bounds = bounds.expanded(0.15 * diag);
    let Ok(tri) = TriMesh::with_flags(
        mesh.positions.clone(),
        mesh.triangles.clone(),
        TriMeshFlags::ORIENTED,
    ) else {
        return Vec::new();
    };
    let size = bounds.size();
    let cell = size.max_element() / resolution.max(2) as f64;
    let n = [
        (size.x / cell).ceil() as usize + 1,
        (size.y / cell).ceil() as usize + 1,
        (size.z / cell).ceil() as usize + 1,
    ];
    (0..n[0] * n[1] * n[2])
        .into_par_iter()
        .filter_map(|k| {
            let (i, j, l) = (k % n[0], (k / n[0]) % n[1], k / (n[0] * n[1]));
            let x = bounds.min + DVec3::new(i as f64, j as f64, l as f64) * cell;
            let proj = tri.project_local_point(x, false);
            let d = proj.point.distance(x);
            (d > 0.015 * diag).then_some((x, proj.is_inside))
        })
        .collect()
}

/// One blob in optimisation coordinates.
#[derive(Clone, Copy, Debug)]
struct Params {
    c: DVec3,
    q: DQuat,
    log_r: DVec3,
    log_b: f64,
}

impl Params {
    fn from_blob(b: &Blob) -> Params {
        let r = b.semi_axes * (1.0 + b.a).sqrt();
        Params {
            c: b.center,
            q: b.rotation,
            log_r: DVec3::new(r.x.ln(), r.y.ln(), r.z.ln()),
            log_b: b.b.abs().max(1e-12).ln(),
        }
    }

    fn to_blob(self, a: f64) -> Blob {
        let r = DVec3::new(self.log_r.x.exp(), self.log_r.y.exp(), self.log_r.z.exp());
        Blob {
            center: self.c,
            rotation: self.q.normalize(),
            semi_axes: r / (1.0 + a).sqrt(),
            a,
            b: self.log_b.exp(),
        }
    }

    /// Apply a step `[dc (3, in units of `scale`), ω (3), d log r (3), d log B]`, keeping the
    /// influence radii within `[1e-3, 0.5]·scale`, their ratio within 8 and `B` within
    /// `[1e-3, 50]` (beyond these a blob is a needle or a spike that no sample constrains).
    fn stepped(self, d: &[f64; 10], scale: f64) -> Params {
        let w = DVec3::new(d[3], d[4], d[5]);
        let lo = (1e-3 * scale).ln();
        let hi = (0.5 * scale).ln();
        let mut log_r =
            (self.log_r + DVec3::new(d[6], d[7], d[8])).clamp(DVec3::splat(lo), DVec3::splat(hi));
        let max_ratio = 8f64.ln();
        log_r = log_r.max(DVec3::splat(log_r.max_element() - max_ratio));
        Params {
            c: self.c + DVec3::new(d[0], d[1], d[2]) * scale,
            q: (self.q * DQuat::from_scaled_axis(w)).normalize(),
            log_r,
            log_b: (self.log_b + d[9]).clamp(1e-3f64.ln(), 50f64.ln()),
        }
    }
}

/// A blob's field prepared for evaluation: `y = Rᵀ(x−c)`, `u = Σ (y_k/r_k)²`.
struct Eval {
    c: DVec3,
    rt: DMat3,
    inv_r2: DVec3,
    b2: f64,
}

impl Eval {
    fn new(p: &Params) -> Eval {
        let r = DVec3::new(p.log_r.x.exp(), p.log_r.y.exp(), p.log_r.z.exp());
        Eval {
            c: p.c,
            rt: DMat3::from_quat(p.q).transpose(),
            inv_r2: DVec3::ONE / (r * r),
            b2: (2.0 * p.log_b).exp(),
        }
    }

    #[inline]
    fn value(&self, x: DVec3) -> f64 {
        let y = self.rt * (x - self.c);
        let u = (y * y * self.inv_r2).element_sum();
        if u < 1.0 {
            self.b2 * (1.0 - u) * (1.0 - u)
        } else {
            0.0
        }
    }

    /// `f` and `∂f/∂θ` for `θ = [c/scale, ω, log r, log B]`.
    #[inline]
    fn value_and_jacobian(&self, x: DVec3, scale: f64) -> (f64, [f64; 10]) {
        let y = self.rt * (x - self.c);
        let v = y * self.inv_r2;
        let u = (y * v).element_sum();
        if u >= 1.0 {
            return (0.0, [0.0; 10]);
        }
        let k = 1.0 - u;
        let f = self.b2 * k * k;
        let df_du = -2.0 * self.b2 * k;
        // ∂u/∂c = −2 R v; ∂u/∂ω = 2 (v × y); ∂u/∂log r_k = −2 y_k v_k.
        let du_dc = self.rt.transpose() * v * (-2.0 * scale);
        let du_dw = v.cross(y) * 2.0;
        let du_dlr = y * v * -2.0;
        let j = [
            df_du * du_dc.x,
            df_du * du_dc.y,
            df_du * du_dc.z,
            df_du * du_dw.x,
            df_du * du_dw.y,
            df_du * du_dw.z,
            df_du * du_dlr.x,
            df_du * du_dlr.y,
            df_du * du_dlr.z,
            2.0 * f,
        ];
        (f, j)
    }
}

/// Residual of one point given its field value `F`, and its derivative `dr/dF`.
#[inline]
fn residual(kind: Kind, big_f: f64, inv_g: f64, cfg: &FullConfig) -> (f64, f64) {
    let w = cfg.constraint_weight * inv_g;
    match kind {
        Kind::Surface => (big_f * inv_g, inv_g),
        Kind::Inside if big_f < cfg.margin => ((big_f - cfg.margin) * w, w),
        Kind::Outside if big_f > -cfg.margin => ((big_f + cfg.margin) * w, w),
        _ => (0.0, 0.0),
    }
}

/// Per blob, the indices of the points inside its (slightly enlarged) support, as CSR.
fn incidence(blobs: &[Blob], pts: &Points) -> (Vec<usize>, Vec<u32>) {
    let widened: Vec<Blob> = blobs
        .iter()
        .map(|b| Blob {
            semi_axes: b.semi_axes * 1.15,
            b: if b.is_live() { 1.0 } else { 0.0 },
            ..*b
        })
        .collect();
    let index = BlobField::new(&widened, 1.0);
    // Support tests as a matrix product: `x` is inside when |M(x − c)|² < 1.
    let frames: Vec<(DMat3, DVec3)> = widened
        .iter()
        .map(|b| {
            let r = b.semi_axes * (1.0 + b.a).sqrt();
            let m = DMat3::from_diagonal(1.0 / r) * DMat3::from_quat(b.rotation.inverse());
            (m, b.center)
        })
        .collect();
    let per_point: Vec<Vec<u32>> = pts
        .x
        .par_iter()
        .map(|&x| {
            index
                .blobs_near(x)
                .iter()
                .copied()
                .filter(|&i| {
                    let (m, c) = frames[i as usize];
                    widened[i as usize].b > 0.0 && (m * (x - c)).length_squared() < 1.0
                })
                .collect()
        })
        .collect();
    let mut start = vec![0usize; blobs.len() + 1];
    for list in &per_point {
        for &i in list {
            start[i as usize + 1] += 1;
        }
    }
    for i in 0..blobs.len() {
        start[i + 1] += start[i];
    }
    let mut fill = start.clone();
    let mut entries = vec![0u32; start[blobs.len()]];
    for (p, list) in per_point.iter().enumerate() {
        for &i in list {
            entries[fill[i as usize]] = p as u32;
            fill[i as usize] += 1;
        }
    }
    (start, entries)
}

/// Greedy colouring of the graph "blobs share a point": blobs of one colour can be updated
/// in parallel. Deterministic (blobs in index order, smallest free colour).
fn colour(n_blobs: usize, start: &[usize], entries: &[u32], n_points: usize) -> Vec<Vec<usize>> {
    // The transpose of the incidence (point → blobs), as CSR.
    let mut p_start = vec![0usize; n_points + 1];
    for &p in entries {
        p_start[p as usize + 1] += 1;
    }
    for p in 0..n_points {
        p_start[p + 1] += p_start[p];
    }
    let mut fill = p_start.clone();
    let mut p_blobs = vec![0u32; entries.len()];
    for i in 0..n_blobs {
        for &p in &entries[start[i]..start[i + 1]] {
            p_blobs[fill[p as usize]] = i as u32;
            fill[p as usize] += 1;
        }
    }
    let mut colour_of = vec![usize::MAX; n_blobs];
    // `taken[c] == i + 1` marks colour `c` as used by a neighbour of blob `i`.
    let mut taken: Vec<usize> = Vec::new();
    for i in 0..n_blobs {
        for &p in &entries[start[i]..start[i + 1]] {
            for &j in &p_blobs[p_start[p as usize]..p_start[p as usize + 1]] {
                let c = colour_of[j as usize];
                if c != usize::MAX {
                    if c >= taken.len() {
                        taken.resize(c + 1, 0);
                    }
                    taken[c] = i + 1;
                }
            }
        }
        colour_of[i] = (0..).find(|&c| taken.get(c) != Some(&(i + 1))).unwrap_or(0);
    }
    let n_colours = colour_of.iter().copied().max().map_or(0, |c| c + 1);
    let mut groups = vec![Vec::new(); n_colours];
    for (i, &c) in colour_of.iter().enumerate() {
        groups[c].push(i);
    }
    groups
}

/// Solve the 10×10 symmetric system `(H + λ·diag(H) + ε) d = −g` by Cholesky; `None` if singular.
fn solve_damped(h: &[[f64; 10]; 10], g: &[f64; 10], lambda: f64) -> Option<[f64; 10]> {
    let mut a = *h;
    for (k, row) in a.iter_mut().enumerate() {
        row[k] += lambda * h[k][k] + 1e-9;
    }
    // In-place Cholesky: a = L Lᵀ.
    for j in 0..10 {
        let mut d = a[j][j];
        for k in 0..j {
            d -= a[j][k] * a[j][k];
        }
        if d <= 0.0 || !d.is_finite() {
            return None;
        }
        let d = d.sqrt();
        a[j][j] = d;
        for i in j + 1..10 {
            let mut s = a[i][j];
            for k in 0..j {
                s -= a[i][k] * a[j][k];
            }
            a[i][j] = s / d;
        }
    }
    let mut y = [0.0; 10];
    for i in 0..10 {
        let mut s = -g[i];
        for k in 0..i {
            s -= a[i][k] * y[k];
        }
        y[i] = s / a[i][i];
    }
    let mut x = [0.0; 10];
    for i in (0..10).rev() {
        let mut s = y[i];
        for k in i + 1..10 {
            s -= a[k][i] * x[k];
        }
        x[i] = s / a[i][i];
    }
    Some(x)
}

/// Shared, read-only state of one sweep.
struct Sweep<'a> {
    cfg: &'a FullConfig,
    pts: &'a Points,
    sums: &'a [f64],
    inv_g: &'a [f64],
    threshold: f64,
    scale: f64,
}

impl Sweep<'_> {
    /// LM on one blob against the points `idx`; returns the improved parameters.
    fn improve(&self, p0: Params, anchor: &Params, idx: &[u32]) -> Params {
        let e0 = Eval::new(&p0);
        // Shape prior: a blob's radii and centre stay near where the decomposition put them
        // (in units of its mean radius), weighted like `idx.len()` points `shape_prior·D` off.
        // Without it, weak blobs stretch into long tails that add up to spurious surface.
        let w = self.cfg.shape_prior * self.scale * (idx.len() as f64).sqrt();
        let r0 = anchor.log_r.exp().element_sum() / 3.0;
        let prior = |p: &Params| -> [f64; 6] {
            let dc = (p.c - anchor.c) / r0;
            let dr = p.log_r - anchor.log_r;
            [dc.x, dc.y, dc.z, dr.x, dr.y, dr.z].map(|v| v * w)
        };
        // F without this blob, per incident point.
        let rest: Vec<f64> = idx
            .iter()
            .map(|&k| self.sums[k as usize] - e0.value(self.pts.x[k as usize]) - self.threshold)
            .collect();
        let cost = |p: &Params| -> f64 {
            let e = Eval::new(p);
            idx.iter()
                .zip(&rest)
                .map(|(&k, &r)| {
                    let k = k as usize;
                    let (res, _) = residual(
                        self.pts.kind[k],
                        r + e.value(self.pts.x[k]),
                        self.inv_g[k],
                        self.cfg,
                    );
                    res * res
                })
                .sum::<f64>()
                + prior(p).iter().map(|v| v * v).sum::<f64>()
        };
        let mut p = p0;
        let mut c = cost(&p);
        let mut lambda = 1e-3;
        for _ in 0..self.cfg.iterations {
            let e = Eval::new(&p);
            let (mut h, mut g) = ([[0.0; 10]; 10], [0.0; 10]);
            for (&k, &r) in idx.iter().zip(&rest) {
                let k = k as usize;
                let (f, jf) = e.value_and_jacobian(self.pts.x[k], self.scale);
                let (res, dres) = residual(self.pts.kind[k], r + f, self.inv_g[k], self.cfg);
                if dres == 0.0 {
                    continue;
                }
                let j: [f64; 10] = std::array::from_fn(|a| jf[a] * dres);
                for a in 0..10 {
                    g[a] += j[a] * res;
                    for b in 0..=a {
                        h[a][b] += j[a] * j[b];
                    }
                }
            }
            // Prior residuals: d(centre)/d(step) = scale, d(log r)/d(step) = 1.
            let pr = prior(&p);
            for k in 0..3 {
                let jc = w * self.scale / r0;
                g[k] += jc * pr[k];
                h[k][k] += jc * jc;
                g[6 + k] += w * pr[3 + k];
                h[6 + k][6 + k] += w * w;
            }
            for a in 0..10 {
                for b in 0..a {
                    h[b][a] = h[a][b];
                }
            }
            let mut accepted = false;
            for _ in 0..4 {
                let Some(mut d) = solve_damped(&h, &g, lambda) else {
                    lambda *= 10.0;
                    continue;
                };
                // Trust region: bounded moves per iteration.
                for (a, v) in d.iter_mut().enumerate() {
                    let cap = if a < 3 { 0.05 } else { 0.3 };
                    *v = v.clamp(-cap, cap);
                }
                let trial = p.stepped(&d, self.scale);
                let ct = cost(&trial);
                if ct < c {
                    (p, c) = (trial, ct);
                    lambda = (lambda * 0.3).max(1e-7);
                    accepted = true;
                    break;
                }
                lambda *= 8.0;
            }
            if !accepted {
                break;
            }
        }
        p
    }
}

/// `|∇F|` at every point, floored so a residual never explodes where the field is flat.
fn gradient_norms(field: &BlobField, pts: &Points, diag: f64) -> Vec<f64> {
    // Typical |∇F| on the surface of a blob of radius ~D/20 is ~ 2·B·… ; the floor keeps the
    // geometric residual bounded by about 10 % of D per unit of F.
    let floor = 10.0 / diag;
    pts.x
        .par_iter()
        .map(|&x| 1.0 / field.value_and_gradient(x).1.length().max(floor))
        .collect()
}

/// RMS of `F/|∇F|` over the surface points, as a fraction of `diag`.
fn surface_rms(field: &BlobField, pts: &Points, diag: f64) -> f64 {
    let (s, n) = pts
        .x
        .par_iter()
        .zip(&pts.kind)
        .filter(|(_, k)| **k == Kind::Surface)
        .map(|(&x, _)| {
            let (f, g) = field.value_and_gradient(x);
            let d = f / g.length().max(10.0 / diag);
            (d * d, 1usize)
        })
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    (s / n.max(1) as f64).sqrt() / diag
}

/// Re-seed dead blobs as small spheres just inside the surface where the residual is worst.
fn reseed_dead(
    cfg: &FullConfig,
    blobs: &mut [Blob],
    pts: &Points,
    field: &BlobField,
    diag: f64,
) -> Vec<usize> {
    let dead: Vec<usize> = (0..blobs.len())
        .filter(|&i| blobs[i].b.abs() < cfg.b_floor)
        .collect();
    let mut moved = Vec::new();
    if dead.is_empty() {
        return moved;
    }
    // Worst surface points by |F|/|∇F|, largest first, deterministic tie-break by index.
    let mut worst: Vec<(f64, usize)> = (0..pts.x.len())
        .into_par_iter()
        .filter(|&k| pts.kind[k] == Kind::Surface)
        .map(|k| {
            let (f, g) = field.value_and_gradient(pts.x[k]);
            ((f / g.length().max(10.0 / diag)).abs(), k)
        })
        .collect();
    worst.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let radius = 0.02 * diag;
    let mut placed: Vec<DVec3> = Vec::new();
    let mut cursor = worst.iter();
    for &i in &dead {
        let Some(&(_, k)) =
            cursor.find(|(_, k)| placed.iter().all(|p| p.distance(pts.x[*k]) > 2.0 * radius))
        else {
            break;
        };
        let centre = pts.x[k] - pts.n[k] * radius;
        placed.push(pts.x[k]);
        let a = blobs[i].a;
        // Iso-radius `radius`: with A, B = (1+A)/A reproduces the sphere.
        blobs[i] = Blob {
            center: centre,
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(radius),
            a,
            b: (1.0 + a) / a,
        };
        moved.push(i);
    }
    moved
}

/// Optimise every parameter of every blob in place. Deterministic at any thread count.
pub fn optimise_full(
    cfg: &FullConfig,
    blobs: &mut [Blob],
    samples: &SurfaceSamples,
    far: &[(DVec3, bool)],
    diag: f64,
    threshold: f64,
) -> FullReport {
    let pts = constraint_points(cfg, samples, far, diag);
    let mut report = FullReport {
        rms_before: surface_rms(&BlobField::new(blobs, threshold), &pts, diag),
        ..FullReport::default()
    };
    let scale = diag;
    let mut reseeded = vec![false; blobs.len()];
    let mut anchors: Vec<Params> = blobs.iter().map(Params::from_blob).collect();
    for sweep in 0..cfg.sweeps {
        let field = BlobField::new(blobs, threshold);
        if sweep > 0 && sweep + 1 < cfg.sweeps {
            for i in reseed_dead(cfg, blobs, &pts, &field, diag) {
                reseeded[i] = true;
                anchors[i] = Params::from_blob(&blobs[i]);
                report.reseeded += 1;
            }
        }
        let field = BlobField::new(blobs, threshold);
        let inv_g = gradient_norms(&field, &pts, diag);
        let (start, entries) = incidence(blobs, &pts);
        let mut sums: Vec<f64> = pts.x.par_iter().map(|&x| field.sum(x)).collect();
        let groups = colour(blobs.len(), &start, &entries, pts.x.len());
        for group in groups {
            let updated: Vec<(usize, Params)> = {
                let sweep_state = Sweep {
                    cfg,
                    pts: &pts,
                    sums: &sums,
                    inv_g: &inv_g,
                    threshold,
                    scale,
                };
                group
                    .par_iter()
                    .filter(|&&i| blobs[i].is_live() && start[i + 1] > start[i])
                    .map(|&i| {
                        (
                            i,
                            sweep_state.improve(
                                Params::from_blob(&blobs[i]),
                                &anchors[i],
                                &entries[start[i]..start[i + 1]],
                            ),
                        )
                    })
                    .collect()
            };
            for (i, p) in updated {
                let old = Eval::new(&Params::from_blob(&blobs[i]));
                let new = Eval::new(&p);
                for &k in &entries[start[i]..start[i + 1]] {
                    let x = pts.x[k as usize];
                    sums[k as usize] += new.value(x) - old.value(x);
                }
                blobs[i] = p.to_blob(blobs[i].a);
            }
        }
    }
    report.rms_after = surface_rms(&BlobField::new(blobs, threshold), &pts, diag);
    // Keep the selection order meaningful (the diffusion animation starts from the first blob):
    // blobs that kept their decomposition origin first, in order; re-seeded ones after them.
    let original = blobs.to_vec();
    let order = (0..blobs.len())
        .filter(|&i| !reseeded[i])
        .chain((0..blobs.len()).filter(|&i| reseeded[i]));
    for (k, i) in order.enumerate() {
        blobs[k] = original[i];
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jacobian_matches_finite_differences() {
        let p = Params {
            c: DVec3::new(0.1, -0.2, 0.3),
            q: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.5, 1.0),
            log_r: DVec3::new(0.2, -0.1, 0.05),
            log_b: 0.4,
        };
        let x = DVec3::new(0.5, 0.1, 0.2);
        let scale = 4.0;
        let (_, j) = Eval::new(&p).value_and_jacobian(x, scale);
        for a in 0..10 {
            let h = 1e-6;
            let mut d = [0.0; 10];
            d[a] = h;
            let fp = Eval::new(&p.stepped(&d, scale)).value(x);
            d[a] = -h;
            let fm = Eval::new(&p.stepped(&d, scale)).value(x);
            let fd = (fp - fm) / (2.0 * h);
            assert!(
                (fd - j[a]).abs() < 1e-5 * (1.0 + fd.abs()),
                "param {a}: analytic {} vs fd {fd}",
                j[a]
            );
        }
    }

    #[test]
    fn blob_params_round_trip() {
        let b = Blob {
            center: DVec3::new(1.0, 2.0, 3.0),
            rotation: DQuat::from_rotation_y(0.7),
            semi_axes: DVec3::new(0.5, 0.25, 1.5),
            a: 1.3,
            b: 2.2,
        };
        let back = Params::from_blob(&b).to_blob(b.a);
        assert!((back.semi_axes - b.semi_axes).length() < 1e-12 && (back.b - b.b).abs() < 1e-12);
    }

    #[test]
    fn fits_a_sphere_from_a_poor_start() {
        // Samples of the unit sphere; one blob started off-centre, squashed and too weak.
        let m = 2000;
        let mut s = SurfaceSamples::default();
        for i in 0..m {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / m as f64;
            let t = i as f64 * 2.399963;
            let r = (1.0 - z * z).sqrt();
            let n = DVec3::new(r * t.cos(), r * t.sin(), z);
            s.positions.push(n);
            s.normals.push(n);
            s.mean_curvature.push(1.0);
        }
        let mut blobs = vec![Blob {
            center: DVec3::new(0.1, -0.05, 0.0),
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::new(1.0, 0.8, 1.1),
            a: 1.0,
            b: 2.0,
        }];
        let cfg = FullConfig {
            sweeps: 8,
            iterations: 4,
            max_points: 10_000,
            ..FullConfig::default()
        };
        let report = optimise_full(&cfg, &mut blobs, &s, &[], 2.0 * 3f64.sqrt(), 1.0);
        assert!(report.rms_after < 0.2 * report.rms_before, "{report:?}");
        assert!(report.rms_after < 1e-3, "{report:?}");
    }
}
