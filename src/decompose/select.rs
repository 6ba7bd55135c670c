//! Greedy weighted maximum coverage over a voxel grid (docs/ARCHITECTURE.md, Decomposition).
//!
//! In: candidates and the mesh bounds. Out: candidate indices in selection order. Each candidate
//! covers the voxels whose centres it contains, rasterised row by row inside its bounding box in
//! parallel and stored as CSR of u32 x-runs (a plain voxel list is ~50 M entries on the bunny).
//! A lazy max-heap on `w · (uncovered voxels)` with a byte array of covered voxels picks them,
//! ties broken by the lower index.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DMat3, DVec3};
use rayon::prelude::*;

use super::{Candidate, DecomposeConfig};
use crate::geometry::{Aabb, Ellipsoid};

/// A regular grid of cubic voxels centred on a box.
#[derive(Clone, Copy, Debug)]
pub struct VoxelGrid {
    /// Corner of voxel (0, 0, 0).
    pub origin: DVec3,
    /// Edge length of a voxel.
    pub cell: f64,
    /// Voxels per axis.
    pub dims: [usize; 3],
}

impl VoxelGrid {
    /// `cells` voxels along the longest side of `bounds`, enough on the others to cover it.
    pub fn new(bounds: &Aabb, cells: usize) -> VoxelGrid {
        let size = bounds.size();
        let cells = cells.max(1);
        let longest = size.max_element();
        let cell = if longest > 0.0 {
            longest / cells as f64
        } else {
            1.0
        };
        let dims = size
            .to_array()
            .map(|s| ((s / cell).ceil() as usize).clamp(1, cells));
        let extent = DVec3::new(dims[0] as f64, dims[1] as f64, dims[2] as f64) * cell;
        VoxelGrid {
            origin: bounds.center() - 0.5 * extent,
            cell,
            dims,
        }
    }

    /// Total number of voxels.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// True when the grid has no voxel (never, by construction).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Centre of voxel `(i, j, k)`.
    pub fn centre(&self, i: usize, j: usize, k: usize) -> DVec3 {
        self.origin + (DVec3::new(i as f64, j as f64, k as f64) + 0.5) * self.cell
    }

    /// The voxels whose centres lie strictly inside `e`, as runs `(first voxel, length)` along
    /// x, in ascending voxel order. Each row's run comes from solving the quadratic `ρ² < 1`
    /// along x, with its end voxels checked directly.
    pub fn rasterise(&self, e: &Ellipsoid, out: &mut Vec<(u32, u32)>) {
        let b = e.bounds();
        let range = |axis: usize| {
            let lo = ((b.min[axis] - self.origin[axis]) / self.cell - 0.5)
                .ceil()
                .max(0.0);
            let hi = ((b.max[axis] - self.origin[axis]) / self.cell - 0.5).floor();
            (lo as i64, hi.min(self.dims[axis] as f64 - 1.0) as i64)
        };
        let ((j0, j1), (k0, k1)) = (range(1), range(2));
        // ρ² = (x − c)ᵀ M (x − c) with M = R diag(s⁻²) Rᵀ.
        let r = DMat3::from_quat(e.rotation);
        let m = r * DMat3::from_diagonal(e.semi_axes.powf(-2.0)) * r.transpose();
        let nx = self.dims[0] as i64;
        for k in k0.max(0)..=k1 {
            for j in j0.max(0)..=j1 {
                // In voxel units along x: ρ² = a t² + 2 b t + c with t = i − i_c.
                let y = self.centre(0, j as usize, k as usize) - e.center;
                let a = m.x_axis.x;
                let bq = (m.y_axis.x * y.y + m.z_axis.x * y.z) * self.cell;
                let i_c = -y.x / self.cell; // centre of voxel i_c + (i) sits at offset i·cell
                let cq = y.y * (m.y_axis.y * y.y + 2.0 * m.z_axis.y * y.z) + m.z_axis.z * y.z * y.z;
                let aq = a * self.cell * self.cell;
                let disc = bq * bq - aq * (cq - 1.0);
                if !(disc > 0.0) || !(aq > 0.0) {
                    continue;
                }
                let root = disc.sqrt();
                // ρ² of voxel i of this row, by the same polynomial.
                let rho2 = |i: i64, _: i64, _: i64| {
                    let s = i as f64 - i_c;
                    (aq * s + 2.0 * bq) * s + cq
                };
                let mut lo = (i_c + (-bq - root) / aq).ceil().max(0.0) as i64;
                let mut hi = (i_c + (-bq + root) / aq).floor().min((nx - 1) as f64) as i64;
                while lo <= hi && rho2(lo, j, k) >= 1.0 {
                    lo += 1;
                }
                while lo <= hi && rho2(hi, j, k) >= 1.0 {
                    hi -= 1;
                }
                if lo > hi {
                    continue;
                }
                while lo > 0 && rho2(lo - 1, j, k) < 1.0 {
                    lo -= 1;
                }
                while hi + 1 < nx && rho2(hi + 1, j, k) < 1.0 {
                    hi += 1;
                }
                let row = (k * self.dims[1] as i64 + j) * nx;
                out.push(((row + lo) as u32, (hi - lo + 1) as u32));
            }
        }
    }
}

/// Per-candidate covered voxels as CSR of x-runs: candidate `c` covers the runs
/// `runs[start[c]..start[c + 1]]`, each `(first voxel, length)`.
#[derive(Clone, Debug)]
pub struct Coverage {
    /// Offsets, one more than candidates.
    pub start: Vec<usize>,
    /// Runs `(first voxel, length)`.
    pub runs: Vec<(u32, u32)>,
}

impl Coverage {
    /// Rasterise every candidate (parallel, deterministic).
    pub fn new(grid: &VoxelGrid, candidates: &[Candidate]) -> Coverage {
        let lists: Vec<Vec<(u32, u32)>> = candidates
            .par_iter()
            .map(|c| {
                let mut v = Vec::new();
                grid.rasterise(&c.ellipsoid, &mut v);
                v
            })
            .collect();
        let mut start = Vec::with_capacity(lists.len() + 1);
        start.push(0);
        let mut total = 0;
        for l in &lists {
            total += l.len();
            start.push(total);
        }
        let mut runs = Vec::with_capacity(total);
        for l in lists {
            runs.extend_from_slice(&l);
        }
        Coverage { start, runs }
    }

    /// Runs of candidate `c`.
    pub fn of(&self, c: usize) -> &[(u32, u32)] {
        &self.runs[self.start[c]..self.start[c + 1]]
    }

    /// Number of voxels of candidate `c` not yet `covered`.
    pub fn uncovered(&self, c: usize, covered: &[u8]) -> usize {
        self.of(c)
            .iter()
            .map(|&(s, n)| {
                let row = &covered[s as usize..(s + n) as usize];
                n as usize - row.iter().map(|&b| b as usize).sum::<usize>()
            })
            .sum()
    }

    /// Mark every voxel of candidate `c` covered.
    pub fn cover(&self, c: usize, covered: &mut [u8]) {
        for &(s, n) in self.of(c) {
            covered[s as usize..(s + n) as usize].fill(1);
        }
    }
}

/// Greedy weighted maximum coverage; see [`super::select_greedy`].
pub fn select_greedy(cfg: &DecomposeConfig, bounds: &Aabb, candidates: &[Candidate]) -> Vec<usize> {
    let grid = VoxelGrid::new(bounds, cfg.voxels);
    let coverage = Coverage::new(&grid, candidates);
    let mut covered = vec![0u8; grid.len()];
    let gain_of =
        |c: usize, covered: &[u8]| candidates[c].weight * coverage.uncovered(c, covered) as f64;
    // Non-negative finite f64 order like their bit patterns; ties pop the lower index first.
    let initial: Vec<f64> = (0..candidates.len())
        .into_par_iter()
        .map(|c| gain_of(c, &covered))
        .collect();
    let mut heap: BinaryHeap<(u64, Reverse<usize>)> = initial
        .into_iter()
        .enumerate()
        .map(|(c, g)| (g, c))
        .filter(|&(g, _)| g > 0.0 && g.is_finite())
        .map(|(g, c)| (g.to_bits(), Reverse(c)))
        .collect();
    let mut order = Vec::new();
    let mut total = 0.0;
    while order.len() < cfg.max_selected {
        let Some((bits, Reverse(c))) = heap.pop() else {
            break;
        };
        let gain = gain_of(c, &covered);
        if gain <= 0.0 {
            continue;
        }
        if gain < f64::from_bits(bits) {
            heap.push((gain.to_bits(), Reverse(c)));
            continue;
        }
        if gain < cfg.min_gain_fraction * total {
            break;
        }
        coverage.cover(c, &mut covered);
        total += gain;
        order.push(c);
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn candidate(center: DVec3, semi_axes: DVec3, weight: f64) -> Candidate {
        Candidate {
            ellipsoid: Ellipsoid {
                center,
                rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4),
                semi_axes,
            },
            seed_vertex: 0,
            seed: (center, DVec3::Z),
            sphere_radius: semi_axes.min_element(),
            weight,
            stage: 3,
        }
    }

    #[test]
    fn runs_match_brute_force_rasterisation() {
        let bounds = Aabb {
            min: DVec3::new(-1.0, -0.7, -0.3),
            max: DVec3::new(1.3, 0.9, 0.5),
        };
        let grid = VoxelGrid::new(&bounds, 40);
        for c in [
            candidate(DVec3::new(0.1, 0.2, 0.0), DVec3::new(0.9, 0.3, 0.2), 1.0),
            // Sticks out of the grid on several sides.
            candidate(DVec3::new(1.2, -0.6, 0.4), DVec3::new(0.5, 0.6, 0.7), 1.0),
        ] {
            let mut runs = Vec::new();
            grid.rasterise(&c.ellipsoid, &mut runs);
            let from_runs: Vec<u32> = runs.iter().flat_map(|&(s, n)| s..s + n).collect();
            let mut brute = Vec::new();
            for k in 0..grid.dims[2] {
                for j in 0..grid.dims[1] {
                    for i in 0..grid.dims[0] {
                        if c.ellipsoid.contains(grid.centre(i, j, k)) {
                            brute.push(((k * grid.dims[1] + j) * grid.dims[0] + i) as u32);
                        }
                    }
                }
            }
            assert!(!brute.is_empty());
            assert_eq!(from_runs, brute);
        }
    }

    #[test]
    fn greedy_order_weights_and_redundancy() {
        let bounds = Aabb {
            min: DVec3::splat(-2.0),
            max: DVec3::splat(2.0),
        };
        let cands = vec![
            candidate(DVec3::new(-1.0, 0.0, 0.0), DVec3::splat(0.5), 1.0), // small
            candidate(DVec3::new(1.0, 0.0, 0.0), DVec3::splat(0.8), 1.0),  // big
            candidate(DVec3::new(1.0, 0.0, 0.0), DVec3::splat(0.7), 4.0),  // inside big, heavy
            candidate(DVec3::new(-1.0, 0.0, 0.0), DVec3::splat(0.5), 1.0), // duplicate of 0
        ];
        let cfg = DecomposeConfig {
            voxels: 60,
            max_selected: 10,
            ..DecomposeConfig::default()
        };
        let order = select_greedy(&cfg, &bounds, &cands);
        // Heavy candidate first (4 × 0.343 > 0.512), then the big one's shell, then the small
        // one; the duplicate adds nothing (tie broken by index: 0 before 3).
        assert_eq!(order, vec![2, 1, 0]);
    }
}
