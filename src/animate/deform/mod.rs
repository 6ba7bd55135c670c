//! Targets that bend (issue 51): the cloud carried by a deforming target, a mesh sequence of
//! one topology ([`crate::mesh::sequence::MeshSequence`]) fitted once on its rest frame.
//!
//! Each blob is anchored, at plan time, to the rest vertices around its formed position (those
//! within 1.5 of its largest semi-axis, at least [`MIN_ANCHORS`], at most [`MAX_ANCHORS`], the
//! nearest kept; Gaussian weights of that semi-axis). At shot time `t` the anchors' positions
//! are the sequence's, linear between its frames (held before the first and after the last),
//! and the blob's neighbourhood follows their least-squares affine map from rest to `t` — the
//! deformation gradient at the blob:
//!
//! ```text
//! p̄ = Σ w p,  q̄ = Σ w q,  P = Σ w (p − p̄)(p − p̄)ᵀ,  Q = Σ w (q − q̄)(p − p̄)ᵀ
//! M = (Q + λR)(P + λI)⁻¹,   c' = q̄ + M (c − p̄)
//! ```
//!
//! with `R` the rotation nearest `Q` (Kabsch) and `λ = 1 %` of `tr P`: where the anchors span
//! a direction `M` is their affine map, where they do not (a flat patch of surface, a ring of a
//! tube) it is their rotation, so a blob neither collapses nor flips. The blob's centre moves
//! by `c' − c` (a blob still flying in moves by its destination's displacement); its frame
//! turns by `R` and each semi-axis is scaled by how much `M` stretches it, so a formed blob's
//! ellipsoid is carried as the surface around it is, and the billows — anchored to the blobs'
//! frames in world units — ride along with it instead of swimming through a still texture.
//!
//! Where the surface leaves what an affine map can follow (a bend across a blob, a bulge
//! passing through it), [`Deformation::with_refit`] re-solves the blob's `A` and `B` — the
//! paper's local field's parameters — against the deformed surface around it ([`refit`]), once
//! per frame of the sequence, read linear between frames like the vertices. Shots do not use
//! it ([`Deformation::new`]): measured on the builtin waving tube and on a bend that stretches,
//! it lost silhouette IoU (docs/MEASUREMENTS.md, "Bending"; `A`, `B` scale a blob's field alike
//! in every direction, while a bend presses one side of it and pulls the other).
//!
//! [`Deformation::with_shape_refit`] ([`shape`]) re-stretches instead a blob's axes where the
//! anchors spread more (or less) than the affine map says; measured, it gains up to 0.003 of
//! IoU and loses none on both shapes, and shots use it (`scene::shot`): the blobs are refitted
//! only where the surface leaves them.
//!
//! The per-frame cost is a few multiply-adds per anchor and a 3×3 eigen-solve per blob (and,
//! with the refit, a lerp of two factors per blob; no solve, no search): tens of microseconds
//! for a few hundred blobs.

pub mod refit;
pub mod shape;

pub use refit::{RefitConfig, RefitSummary};
pub use shape::ShapeCorrection;

use std::collections::HashMap;

use glam::{DMat3, DQuat, DVec3};

use crate::blobby::Blob;
use crate::decompose::eigen::symmetric_eigen;
use crate::geometry::Aabb;

/// Fewest anchor vertices of a blob (the search widens until it finds them).
pub const MIN_ANCHORS: usize = 12;
/// Most anchor vertices of a blob (the nearest are kept).
pub const MAX_ANCHORS: usize = 96;
/// Search radius of the anchors, in the blob's largest semi-axis.
const ANCHOR_REACH: f64 = 1.5;
/// The regularisation toward the anchors' rotation, as a fraction of `tr P`.
const LAMBDA: f64 = 0.01;

/// One anchor: a vertex (index into the tracked vertices) with its normalised weight and its
/// rest offset from the anchors' weighted mean.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Anchor {
    vertex: u32,
    weight: f64,
    offset: DVec3,
}

/// A blob's anchoring: its anchors' range, their rest mean, the blob's rest centre and the
/// solved `(P + λI)⁻¹` with `λ`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Anchoring {
    start: u32,
    len: u32,
    rest_mean: DVec3,
    rest_center: DVec3,
    inverse: DMat3,
    lambda: f64,
}

/// The map of one blob's neighbourhood at an instant (rest → then).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalMap {
    /// How far the blob's rest centre has moved.
    pub displacement: DVec3,
    /// The anchors' rotation (the frame's turn).
    pub rotation: DMat3,
    /// The deformation gradient `M` (the affine map's linear part).
    pub linear: DMat3,
}

impl LocalMap {
    /// No motion.
    pub const IDENTITY: LocalMap = LocalMap {
        displacement: DVec3::ZERO,
        rotation: DMat3::IDENTITY,
        linear: DMat3::IDENTITY,
    };

    /// `blob` carried by this map: moved by the displacement, its frame turned by the
    /// rotation, each semi-axis scaled by the stretch of `M` along it.
    pub fn carry(&self, blob: &mut Blob) {
        blob.center += self.displacement;
        let r = DMat3::from_quat(blob.rotation);
        let stretch = DVec3::new(
            (self.linear * r.x_axis).length(),
            (self.linear * r.y_axis).length(),
            (self.linear * r.z_axis).length(),
        );
        blob.semi_axes *= stretch;
        blob.rotation = (DQuat::from_mat3(&self.rotation) * blob.rotation).normalize();
    }
}

/// A deforming target's motion of the blobs (see the module doc): the anchors of each blob of
/// the formed target and the tracked vertices' positions per frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Deformation {
    /// Shot time (seconds) of each frame, increasing.
    times: Vec<f64>,
    /// Per frame, the positions of the vertices some blob is anchored to.
    tracks: Vec<Vec<DVec3>>,
    anchors: Vec<Anchor>,
    blobs: Vec<Anchoring>,
    /// Per frame of the sequence, per blob, the factors of its `A` and `B` from the local refit
    /// (empty when no blob is refitted on any frame).
    refit: Vec<Vec<[f64; 2]>>,
    /// What the refit did.
    summary: RefitSummary,
    /// Per frame of the sequence, per blob, the shape refit's correction of the carry (empty
    /// unless made by [`Deformation::with_shape_refit`] and some blob is corrected).
    shape: Vec<Vec<ShapeCorrection>>,
    /// (blob, frame) pairs the shape refit corrects.
    shaped: usize,
}

impl Deformation {
    /// Anchor `formed` (the formed target's blobs in the rest pose, index = blob identity) to
    /// the rest vertices `frames[0]`; `frames[i]` is the mesh at shot time `times[i]` seconds
    /// (increasing; at least one frame, all of one length, the same place as the blobs).
    pub fn new(formed: &[Blob], frames: &[Vec<DVec3>], times: &[f64]) -> Deformation {
        let rest = &frames[0];
        let grid = VertexGrid::new(rest);
        let mut used: HashMap<u32, u32> = HashMap::new();
        let mut tracked: Vec<u32> = Vec::new();
        let mut anchors = Vec::new();
        let mut blobs = Vec::with_capacity(formed.len());
        let mut near = Vec::new();
        for b in formed {
            let sigma = b.semi_axes.max_element().max(grid.cell * 0.5);
            grid.nearest(rest, b.center, ANCHOR_REACH * sigma, MAX_ANCHORS, &mut near);
            let total: f64 = near
                .iter()
                .map(|&(d2, _)| (-d2 / (2.0 * sigma * sigma)).exp())
                .sum();
            let weights: Vec<(u32, f64)> = near
                .iter()
                .map(|&(d2, v)| (v, (-d2 / (2.0 * sigma * sigma)).exp() / total))
                .collect();
            let mean = weights
                .iter()
                .fold(DVec3::ZERO, |m, &(v, w)| m + rest[v as usize] * w);
            let start = anchors.len() as u32;
            let mut cov = DMat3::ZERO;
            for &(v, w) in &weights {
                let offset = rest[v as usize] - mean;
                cov += outer(offset * w, offset);
                let slot = *used.entry(v).or_insert_with(|| {
                    tracked.push(v);
                    tracked.len() as u32 - 1
                });
                anchors.push(Anchor {
                    vertex: slot,
                    weight: w,
                    offset,
                });
            }
            let trace = cov.x_axis.x + cov.y_axis.y + cov.z_axis.z;
            let lambda = (LAMBDA * trace).max(f64::MIN_POSITIVE);
            let inverse = (cov + DMat3::from_diagonal(DVec3::splat(lambda))).inverse();
            blobs.push(Anchoring {
                start,
                len: weights.len() as u32,
                rest_mean: mean,
                rest_center: b.center,
                inverse,
                lambda,
            });
        }
        let tracks = frames
            .iter()
            .map(|f| tracked.iter().map(|&v| f[v as usize]).collect())
            .collect();
        Deformation {
            times: times.to_vec(),
            tracks,
            anchors,
            blobs,
            refit: Vec::new(),
            summary: RefitSummary::default(),
            shape: Vec::new(),
            shaped: 0,
        }
    }

    /// [`Deformation::new`] with the shape refit where the surface leaves the blobs
    /// ([`shape`]: the anchors' spread mapped instead of their least-squares affine map; `cfg`'s
    /// `from`, `full` say where), made now on every frame of `frames`: what a deforming shot uses
    /// (docs/MEASUREMENTS.md, "Bending").
    pub fn with_shape_refit(
        formed: &[Blob],
        frames: &[Vec<DVec3>],
        times: &[f64],
        cfg: &RefitConfig,
    ) -> Deformation {
        let mut d = Deformation::new(formed, frames, times);
        (d.shape, d.shaped) = shape::corrections(&d, formed, frames.len(), cfg);
        d
    }

    /// (blob, frame) pairs the shape refit corrects (0 without it).
    pub fn shape_refitted(&self) -> usize {
        self.shaped
    }

    /// [`Deformation::new`] with the local refit of `A`, `B` where the surface leaves the
    /// blobs ([`refit`]; `cfg` says where and how), solved now on every frame of `frames`.
    pub fn with_refit(
        formed: &[Blob],
        frames: &[Vec<DVec3>],
        times: &[f64],
        cfg: &RefitConfig,
    ) -> Deformation {
        let mut d = Deformation::new(formed, frames, times);
        (d.refit, d.summary) = refit::factors(&d, formed, frames, cfg);
        d
    }

    /// What the local refit did over the sequence.
    pub fn refit_summary(&self) -> RefitSummary {
        self.summary
    }

    /// This deformation with the blobs carried only, not refitted (to measure what the refit
    /// changes).
    pub fn carried_only(&self) -> Deformation {
        Deformation {
            refit: Vec::new(),
            summary: RefitSummary::default(),
            shape: Vec::new(),
            shaped: 0,
            ..self.clone()
        }
    }

    /// True when some blob's `A`, `B` are refitted on some frame.
    pub fn is_refitted(&self) -> bool {
        !self.refit.is_empty()
    }

    /// The factors of blob `i`'s `A` and `B` at shot time `t` from the local refit (`[1, 1]`
    /// where it is not refitted).
    pub fn refit_factors(&self, i: usize, t: f64) -> [f64; 2] {
        let (a, b, u) = self.bracket(t);
        self.factors_between(i, a, b, u)
    }

    fn factors_between(&self, i: usize, a: usize, b: usize, u: f64) -> [f64; 2] {
        match (self.refit.get(a), self.refit.get(b)) {
            (Some(fa), Some(fb)) if i < fa.len() => {
                let (p, q) = (fa[i], fb[i]);
                if p == q {
                    p
                } else {
                    [p[0] + (q[0] - p[0]) * u, p[1] + (q[1] - p[1]) * u]
                }
            }
            _ => [1.0, 1.0],
        }
    }

    /// Number of blobs anchored (the formed target's).
    pub fn blob_count(&self) -> usize {
        self.blobs.len()
    }

    /// The frames around shot time `t` and the fraction between them.
    fn bracket(&self, t: f64) -> (usize, usize, f64) {
        let n = self.times.len();
        if n == 1 || t <= self.times[0] || t.is_nan() {
            return (0, 0, 0.0);
        }
        if t >= self.times[n - 1] {
            return (n - 1, n - 1, 0.0);
        }
        let b = self.times.partition_point(|&x| x <= t).min(n - 1);
        let a = b - 1;
        let u = (t - self.times[a]) / (self.times[b] - self.times[a]);
        (a, b, u.clamp(0.0, 1.0))
    }

    /// The map of blob `i`'s neighbourhood at shot time `t`.
    pub fn local_map(&self, i: usize, t: f64) -> LocalMap {
        let (a, b, u) = self.bracket(t);
        self.map_between(i, a, b, u)
    }

    fn map_between(&self, i: usize, a: usize, b: usize, u: f64) -> LocalMap {
        let Some(k) = self.blobs.get(i) else {
            return LocalMap::IDENTITY;
        };
        let anchors = &self.anchors[k.start as usize..(k.start + k.len) as usize];
        let (fa, fb) = (&self.tracks[a], &self.tracks[b]);
        let at = |v: u32| {
            let (p, q) = (fa[v as usize], fb[v as usize]);
            p + (q - p) * u
        };
        let mean = anchors
            .iter()
            .fold(DVec3::ZERO, |m, x| m + at(x.vertex) * x.weight);
        let mut cross = DMat3::ZERO;
        for x in anchors {
            cross += outer((at(x.vertex) - mean) * x.weight, x.offset);
        }
        let rotation = nearest_rotation(&cross);
        let linear = (cross + rotation * k.lambda) * k.inverse;
        let moved = mean + linear * (k.rest_center - k.rest_mean);
        LocalMap {
            displacement: moved - k.rest_center,
            rotation,
            linear,
        }
    }

    /// How far blob `i`'s anchors at shot time `t` are from its affine map of them (the
    /// weighted RMS distance, world units): how much the surface there leaves what the blob
    /// can follow (0 for a locally affine motion).
    pub fn residual(&self, i: usize, t: f64) -> f64 {
        let (a, b, u) = self.bracket(t);
        self.residual_between(i, a, b, u)
    }

    fn residual_between(&self, i: usize, a: usize, b: usize, u: f64) -> f64 {
        let Some(k) = self.blobs.get(i) else {
            return 0.0;
        };
        let map = self.map_between(i, a, b, u);
        let mean = k.rest_center + map.displacement - map.linear * (k.rest_center - k.rest_mean);
        let anchors = &self.anchors[k.start as usize..(k.start + k.len) as usize];
        let (fa, fb) = (&self.tracks[a], &self.tracks[b]);
        anchors
            .iter()
            .map(|x| {
                let (p, q) = (fa[x.vertex as usize], fb[x.vertex as usize]);
                let at = p + (q - p) * u;
                x.weight * (at - (mean + map.linear * x.offset)).length_squared()
            })
            .sum::<f64>()
            .sqrt()
    }

    /// Carry `blobs` (a frame of the plan, index = identity) to shot time `t`: blob `i` by
    /// its anchors' map ([`LocalMap::carry`]), its `A` and `B` scaled by the refit's factors
    /// where it is refitted; blobs beyond the anchored ones stay.
    pub fn apply(&self, blobs: &mut [Blob], t: f64) {
        let (a, b, u) = self.bracket(t);
        for (i, blob) in blobs.iter_mut().enumerate().take(self.blobs.len()) {
            let mut map = self.map_between(i, a, b, u);
            if let (Some(sa), Some(sb)) = (self.shape.get(a), self.shape.get(b)) {
                let (p, q) = (sa[i], sb[i]);
                map.linear += p.linear + (q.linear - p.linear) * u;
            }
            map.carry(blob);
            if !self.refit.is_empty() {
                let [ka, kb] = self.factors_between(i, a, b, u);
                blob.a *= ka;
                blob.b *= kb;
            }
        }
    }

    /// The box of `formed` carried to every frame of the sequence (the deforming target's
    /// reach over the shot, for framing).
    pub fn bounds(&self, formed: &[Blob]) -> Aabb {
        let mut out = Aabb::EMPTY;
        for &t in &self.times {
            let mut b = formed.to_vec();
            self.apply(&mut b, t);
            out = out.union(crate::blobby::ellipsoid_bounds(&b));
        }
        out
    }
}

/// `a bᵀ`.
fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The rotation `R` maximising `tr(Rᵀ Q)` (Kabsch, through the eigenvectors of `QᵀQ`), proper
/// also when `Q` has rank 2 (anchors on a plane); the identity when `Q` has rank < 2.
fn nearest_rotation(q: &DMat3) -> DMat3 {
    let (sigma2, v) = symmetric_eigen(&(q.transpose() * *q));
    let scale = sigma2.x.max(0.0);
    if !(scale > 0.0) || !(sigma2.y > 1e-12 * scale) {
        return DMat3::IDENTITY;
    }
    let u1 = (*q * v.x_axis).normalize();
    let w = *q * v.y_axis;
    let u2 = (w - u1 * u1.dot(w)).normalize();
    if !(u1.is_finite() && u2.is_finite()) {
        return DMat3::IDENTITY;
    }
    let u3 = u1.cross(u2);
    // V is a proper rotation, so its third column is v1 × v2 and R = U Vᵀ is proper.
    outer(u1, v.x_axis) + outer(u2, v.y_axis) + outer(u3, v.z_axis)
}

/// A uniform grid over points, for the anchors' neighbour search.
struct VertexGrid {
    cell: f64,
    origin: DVec3,
    cells: HashMap<(i64, i64, i64), Vec<u32>>,
}

impl VertexGrid {
    fn new(points: &[DVec3]) -> VertexGrid {
        let b = Aabb::from_points(points);
        let cell = (b.diagonal() / 32.0).max(1e-12);
        let mut cells: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        let origin = b.min;
        for (i, &p) in points.iter().enumerate() {
            cells
                .entry(Self::key(origin, cell, p))
                .or_default()
                .push(i as u32);
        }
        VertexGrid {
            cell,
            origin,
            cells,
        }
    }

    fn key(origin: DVec3, cell: f64, p: DVec3) -> (i64, i64, i64) {
        let k = ((p - origin) / cell).floor();
        (k.x as i64, k.y as i64, k.z as i64)
    }

    /// The points within `radius` of `c` (widened until at least [`MIN_ANCHORS`] or all), the
    /// nearest `most` kept, as `(squared distance, index)` sorted by distance then index
    /// (deterministic).
    fn nearest(
        &self,
        points: &[DVec3],
        c: DVec3,
        radius: f64,
        most: usize,
        out: &mut Vec<(f64, u32)>,
    ) {
        let mut r = radius.max(self.cell * 0.5);
        let total = points.len();
        loop {
            out.clear();
            let lo = Self::key(self.origin, self.cell, c - DVec3::splat(r));
            let hi = Self::key(self.origin, self.cell, c + DVec3::splat(r));
            let cells = ((hi.0 - lo.0 + 1) * (hi.1 - lo.1 + 1) * (hi.2 - lo.2 + 1)) as usize;
            if cells > 4 * self.cells.len() {
                // Wider than the grid: every point.
                for (i, p) in points.iter().enumerate() {
                    let d2 = (*p - c).length_squared();
                    if d2 <= r * r {
                        out.push((d2, i as u32));
                    }
                }
            } else {
                for x in lo.0..=hi.0 {
                    for y in lo.1..=hi.1 {
                        for z in lo.2..=hi.2 {
                            for &i in self.cells.get(&(x, y, z)).into_iter().flatten() {
                                let d2 = (points[i as usize] - c).length_squared();
                                if d2 <= r * r {
                                    out.push((d2, i));
                                }
                            }
                        }
                    }
                }
            }
            if out.len() >= MIN_ANCHORS.min(total) {
                break;
            }
            r *= 2.0;
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out.truncate(most);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::sphere_blob;

    /// A row of overlapping spheres and points on the surface of the capsule around
    /// them (the refits' tests' shape).
    pub(super) fn capsule() -> (Vec<Blob>, Vec<DVec3>) {
        let blobs: Vec<Blob> = (0..5)
            .map(|k| sphere_blob(DVec3::new(0.0, k as f64 * 0.3 - 0.6, 0.0), 0.25))
            .collect();
        let mut points = Vec::new();
        for ring in 0..=40 {
            let y = -0.85 + 1.7 * ring as f64 / 40.0;
            for side in 0..24 {
                let a = std::f64::consts::TAU * side as f64 / 24.0;
                points.push(DVec3::new(0.25 * a.cos(), y, 0.25 * a.sin()));
            }
        }
        (blobs, points)
    }

    /// Points of a ball of radius 1 (a coarse lattice).
    fn ball() -> Vec<DVec3> {
        let mut p = Vec::new();
        for x in -4..=4 {
            for y in -4..=4 {
                for z in -4..=4 {
                    let v = DVec3::new(x as f64, y as f64, z as f64) / 4.0;
                    if v.length() <= 1.0 {
                        p.push(v);
                    }
                }
            }
        }
        p
    }

    #[test]
    fn a_rigid_motion_carries_blobs_rigidly() {
        let rest = ball();
        let turn = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.7);
        let shift = DVec3::new(0.3, -1.0, 2.0);
        let moved: Vec<DVec3> = rest.iter().map(|&p| turn * p + shift).collect();
        let blobs = vec![
            sphere_blob(DVec3::new(0.2, 0.1, 0.0), 0.3),
            sphere_blob(DVec3::new(-0.5, 0.3, 0.2), 0.2),
        ];
        let d = Deformation::new(&blobs, &[rest, moved], &[0.0, 1.0]);
        let mut at_end = blobs.clone();
        d.apply(&mut at_end, 1.0);
        for (b, e) in blobs.iter().zip(&at_end) {
            let want = turn * b.center + shift;
            assert!((e.center - want).length() < 1e-9, "{} vs {want}", e.center);
            assert!((e.semi_axes - b.semi_axes).abs().max_element() < 1e-9);
            let r = DMat3::from_quat(e.rotation);
            assert!((r - turn).abs_diff_eq(DMat3::ZERO, 1e-9), "{r:?}");
        }
        // Halfway the anchors are halfway (linear between frames), and at rest nothing moves.
        let mut rest_blobs = blobs.clone();
        d.apply(&mut rest_blobs, 0.0);
        for (b, e) in blobs.iter().zip(&rest_blobs) {
            assert!((e.center - b.center).length() < 1e-12);
        }
    }

    #[test]
    fn a_stretch_scales_the_axes_and_planar_anchors_do_not_collapse() {
        // A flat patch of anchors (z = 0) stretched 2× along x: the blob's x axis doubles, its
        // z axis (no anchor spans it) keeps its length.
        let mut rest = Vec::new();
        for x in -5..=5 {
            for y in -5..=5 {
                rest.push(DVec3::new(x as f64, y as f64, 0.0) / 5.0);
            }
        }
        let moved: Vec<DVec3> = rest
            .iter()
            .map(|p| DVec3::new(2.0 * p.x, p.y, 0.0))
            .collect();
        let blob = sphere_blob(DVec3::ZERO, 0.5);
        let d = Deformation::new(&[blob], &[rest, moved], &[0.0, 1.0]);
        let mut b = [blob];
        d.apply(&mut b, 1.0);
        let s = b[0].semi_axes;
        assert!((s.x / 0.5 - 2.0).abs() < 0.05, "{s}");
        assert!((s.y / 0.5 - 1.0).abs() < 0.05, "{s}");
        assert!((s.z / 0.5 - 1.0).abs() < 0.05, "{s}");
    }
}
