//! The summed blob field `F(x) = Σ f_i(x) − t`, evaluated through a uniform grid of blob supports
//! so that a query touches only the blobs whose support can contain it.

use glam::{DMat3, DVec3};

use super::Blob;
use crate::geometry::Aabb;

/// One blob prepared for evaluation: `u = |M (x − c)|²` is `ρ²/(1+A)`, so the support is `u < 1`.
#[derive(Clone, Copy, Debug)]
struct Kernel {
    center: DVec3,
    /// `diag(1/(s·√(1+A))) · Rᵀ`: world offset → unit support coordinates.
    unit_from_world: DMat3,
    b2: f64,
}

impl Kernel {
    fn new(blob: &Blob) -> Kernel {
        let scale = blob.semi_axes * (1.0 + blob.a).sqrt();
        let rt = DMat3::from_quat(blob.rotation).transpose();
        // Row i of diag(1/scale)·Rᵀ is row i of Rᵀ divided by scale_i.
        let inv = DVec3::ONE / scale;
        let unit_from_world = DMat3::from_diagonal(inv) * rt;
        Kernel {
            center: blob.center,
            unit_from_world,
            b2: blob.b * blob.b,
        }
    }

    #[inline]
    fn value(&self, x: DVec3) -> f64 {
        let u = (self.unit_from_world * (x - self.center)).length_squared();
        if u < 1.0 {
            let k = 1.0 - u;
            self.b2 * k * k
        } else {
            0.0
        }
    }

    #[inline]
    fn value_and_gradient(&self, x: DVec3) -> (f64, DVec3) {
        let local = self.unit_from_world * (x - self.center);
        let u = local.length_squared();
        if u < 1.0 {
            let k = 1.0 - u;
            // ∇u = 2 Mᵀ M (x − c), so ∇f = −4 B² (1 − u) Mᵀ local.
            let g = self.unit_from_world.transpose() * local * (-4.0 * self.b2 * k);
            (self.b2 * k * k, g)
        } else {
            (0.0, DVec3::ZERO)
        }
    }
}

/// The blob field with a spatial index. Immutable once built; cheap to query from many threads.
#[derive(Clone, Debug)]
pub struct BlobField {
    kernels: Vec<Kernel>,
    supports: Vec<Aabb>,
    threshold: f64,
    bounds: Aabb,
    origin: DVec3,
    inv_cell: f64,
    res: [usize; 3],
    /// CSR: blobs overlapping cell `k` are `entries[cell_start[k]..cell_start[k + 1]]`.
    cell_start: Vec<u32>,
    entries: Vec<u32>,
}

impl BlobField {
    /// Index `blobs` (dead blobs, `B = 0` or zero size, are skipped) for iso-level `threshold`.
    pub fn new(blobs: &[Blob], threshold: f64) -> BlobField {
        let live: Vec<usize> = (0..blobs.len()).filter(|&i| blobs[i].is_live()).collect();
        let kernels: Vec<Kernel> = blobs.iter().map(Kernel::new).collect();
        let supports: Vec<Aabb> = blobs.iter().map(Blob::support_bounds).collect();
        let bounds = live.iter().fold(Aabb::EMPTY, |b, &i| b.union(supports[i]));
        if live.is_empty() {
            return BlobField {
                kernels,
                supports,
                threshold,
                bounds,
                origin: DVec3::ZERO,
                inv_cell: 1.0,
                res: [1, 1, 1],
                cell_start: vec![0, 0],
                entries: Vec::new(),
            };
        }
        // About four cells per blob, at most 96 along an axis: a few blobs per cell.
        let size = bounds.size().max(DVec3::splat(bounds.diagonal() * 1e-6));
        let target_cells = (4 * live.len()).clamp(8, 96 * 96 * 96) as f64;
        let cell = (size.x * size.y * size.z / target_cells).cbrt();
        let res = [
            ((size.x / cell).ceil() as usize).clamp(1, 96),
            ((size.y / cell).ceil() as usize).clamp(1, 96),
            ((size.z / cell).ceil() as usize).clamp(1, 96),
        ];
        let cell = (size.x / res[0] as f64)
            .max(size.y / res[1] as f64)
            .max(size.z / res[2] as f64);
        let inv_cell = 1.0 / cell;
        let origin = bounds.min;
        let cell_range = |b: &Aabb| -> [std::ops::RangeInclusive<usize>; 3] {
            let lo = ((b.min - origin) * inv_cell).floor();
            let hi = ((b.max - origin) * inv_cell).floor();
            let r = |l: f64, h: f64, n: usize| {
                (l.max(0.0) as usize).min(n - 1)..=(h.max(0.0) as usize).min(n - 1)
            };
            [
                r(lo.x, hi.x, res[0]),
                r(lo.y, hi.y, res[1]),
                r(lo.z, hi.z, res[2]),
            ]
        };
        let ncell = res[0] * res[1] * res[2];
        let mut counts = vec![0u32; ncell + 1];
        let index = |x: usize, y: usize, z: usize| x + res[0] * (y + res[1] * z);
        for &i in &live {
            let [rx, ry, rz] = cell_range(&supports[i]);
            for z in rz.clone() {
                for y in ry.clone() {
                    for x in rx.clone() {
                        counts[index(x, y, z) + 1] += 1;
                    }
                }
            }
        }
        for k in 0..ncell {
            counts[k + 1] += counts[k];
        }
        let cell_start = counts;
        let mut fill = cell_start.clone();
        let mut entries = vec![0u32; cell_start[ncell] as usize];
        for &i in &live {
            let [rx, ry, rz] = cell_range(&supports[i]);
            for z in rz.clone() {
                for y in ry.clone() {
                    for x in rx.clone() {
                        let k = index(x, y, z);
                        entries[fill[k] as usize] = i as u32;
                        fill[k] += 1;
                    }
                }
            }
        }
        BlobField {
            kernels,
            supports,
            threshold,
            bounds,
            origin,
            inv_cell,
            res,
            cell_start,
            entries,
        }
    }

    /// Union of the live blobs' support bounds (empty when no blob is live). `F = −t` outside.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The iso-level `t`.
    pub fn threshold(&self) -> f64 {
        self.threshold
    }

    /// Support bounds of blob `i` (indices as in the slice given to [`BlobField::new`]).
    pub fn support_bounds(&self, i: usize) -> Aabb {
        self.supports[i]
    }

    /// Indices of the blobs whose support may contain `x` (a superset; empty outside the grid).
    #[inline]
    pub fn blobs_near(&self, x: DVec3) -> &[u32] {
        if !self.bounds.contains(x) {
            return &[];
        }
        // `x ≥ origin` inside the bounds, so `c ≥ 0` and `as` truncates as `floor` would
        // (without its library call: baseline x86-64 has no rounding instruction).
        let c = (x - self.origin) * self.inv_cell;
        let cx = (c.x as usize).min(self.res[0] - 1);
        let cy = (c.y as usize).min(self.res[1] - 1);
        let cz = (c.z as usize).min(self.res[2] - 1);
        let k = cx + self.res[0] * (cy + self.res[1] * cz);
        &self.entries[self.cell_start[k] as usize..self.cell_start[k + 1] as usize]
    }

    /// `Σ f_i(x)`, the field without the threshold.
    #[inline]
    pub fn sum(&self, x: DVec3) -> f64 {
        self.blobs_near(x)
            .iter()
            .map(|&i| self.kernels[i as usize].value(x))
            .sum()
    }

    /// `F(x) = Σ f_i(x) − t` (positive inside).
    #[inline]
    pub fn value(&self, x: DVec3) -> f64 {
        self.sum(x) - self.threshold
    }

    /// `F(x) ≥ 0`, exactly as `value(x) >= 0.0` answers it, but stopping as soon as the blobs
    /// summed so far reach the iso-level: every term is ≥ 0, so the rounded partial sums never
    /// fall (most of a cloud's inside is decided by its first few blobs).
    #[inline]
    pub fn is_inside(&self, x: DVec3) -> bool {
        // The same sum as [`BlobField::sum`]'s (`Sum` for f64 starts from −0.0), in the same
        // order.
        let mut sum = -0.0;
        for &i in self.blobs_near(x) {
            sum += self.kernels[i as usize].value(x);
            if sum >= self.threshold {
                return true;
            }
        }
        sum - self.threshold >= 0.0
    }

    /// `F(x)` and `∇F(x)`.
    pub fn value_and_gradient(&self, x: DVec3) -> (f64, DVec3) {
        let (mut f, mut g) = (-self.threshold, DVec3::ZERO);
        for &i in self.blobs_near(x) {
            let (fi, gi) = self.kernels[i as usize].value_and_gradient(x);
            f += fi;
            g += gi;
        }
        (f, g)
    }

    /// Blob `i`'s own field `f_i(x)`.
    #[inline]
    pub fn blob_value(&self, i: usize, x: DVec3) -> f64 {
        self.kernels[i].value(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn blobs() -> Vec<Blob> {
        (0..40)
            .map(|i| {
                let t = i as f64;
                Blob {
                    center: DVec3::new((t * 0.7).sin() * 3.0, (t * 1.3).cos() * 2.0, t * 0.1),
                    rotation: DQuat::from_euler(glam::EulerRot::XYZ, t, 2.0 * t, 0.5 * t),
                    semi_axes: DVec3::new(0.4 + 0.01 * t, 0.2, 0.7),
                    a: 0.5 + 0.05 * t,
                    b: 1.0 + 0.02 * t,
                }
            })
            .collect()
    }

    #[test]
    fn indexed_field_equals_brute_force() {
        let blobs = blobs();
        let field = BlobField::new(&blobs, 1.0);
        for i in 0..2000 {
            let t = i as f64 * 0.013;
            let x = DVec3::new((t * 7.0).sin() * 4.0, (t * 5.0).cos() * 3.0, t * 0.2 - 0.5);
            let brute: f64 = blobs.iter().map(|b| b.value(x)).sum::<f64>() - 1.0;
            assert!((field.value(x) - brute).abs() < 1e-12, "at {x}");
        }
    }

    #[test]
    fn is_inside_answers_as_the_full_sum_does() {
        let blobs = blobs();
        // Levels from below the weakest blob to above the strongest overlap, and the edge
        // cases: at 0 everywhere near a blob is inside, at −0.0 and a negative level too.
        for t in [-0.5, -0.0, 0.0, 0.05, 0.3, 1.0, 2.0, 5.0] {
            let field = BlobField::new(&blobs, t);
            let mut inside = 0;
            for i in 0..20_000 {
                let u = i as f64 * 0.00131;
                let x = DVec3::new((u * 7.0).sin() * 4.0, (u * 5.0).cos() * 3.0, u * 0.2 - 0.5);
                let full = field.value(x) >= 0.0;
                assert_eq!(field.is_inside(x), full, "level {t} at {x}");
                inside += full as usize;
            }
            if t > 0.0 && t < 5.0 {
                assert!(inside > 0 && inside < 20_000, "level {t}: {inside} inside");
            }
        }
    }

    #[test]
    fn gradient_matches_finite_differences() {
        let blobs = blobs();
        let field = BlobField::new(&blobs, 1.0);
        let x = blobs[3].center + DVec3::new(0.05, -0.03, 0.02);
        let (_, g) = field.value_and_gradient(x);
        let h = 1e-6;
        let fd = DVec3::new(
            field.value(x + DVec3::X * h) - field.value(x - DVec3::X * h),
            field.value(x + DVec3::Y * h) - field.value(x - DVec3::Y * h),
            field.value(x + DVec3::Z * h) - field.value(x - DVec3::Z * h),
        ) / (2.0 * h);
        assert!((g - fd).length() < 1e-5 * (1.0 + g.length()), "{g} vs {fd}");
    }
}
