//! Greedy weighted maximum coverage over a voxel grid (DESIGN.md §3.5).
//!
//! In: candidates and the mesh bounds. Out: candidate indices in selection order. Each candidate
//! covers the voxels whose centres it contains (rasterised inside its bounding box, in parallel,
//! stored as u32 CSR); a lazy max-heap on `w · (uncovered voxels)` with a byte array of covered
//! voxels picks them, ties broken by the lower index.

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
        let cell = if longest > 0.0 { longest / cells as f64 } else { 1.0 };
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

    /// Linear indices of the voxels whose centres lie strictly inside `e`, ascending.
    pub fn rasterise(&self, e: &Ellipsoid, out: &mut Vec<u32>) {
        let b = e.bounds();
        let range = |axis: usize| {
            let lo = ((b.min[axis] - self.origin[axis]) / self.cell - 0.5).ceil().max(0.0);
            let hi = ((b.max[axis] - self.origin[axis]) / self.cell - 0.5).floor();
            let hi = hi.min(self.dims[axis] as f64 - 1.0);
            (lo as usize, hi)
        };
        let ((i0, i1), (j0, j1), (k0, k1)) = (range(0), range(1), range(2));
        if i1 < i0 as f64 || j1 < j0 as f64 || k1 < k0 as f64 {
            return;
        }
        // ρ² = (x − c)ᵀ M (x − c) with M = R diag(s⁻²) Rᵀ.
        let r = DMat3::from_quat(e.rotation);
        let m = r * DMat3::from_diagonal(e.semi_axes.powf(-2.0)) * r.transpose();
        for k in k0..=k1 as usize {
            for j in j0..=j1 as usize {
                let row = (k * self.dims[1] + j) * self.dims[0];
                for i in i0..=i1 as usize {
                    let d = self.centre(i, j, k) - e.center;
                    if d.dot(m * d) < 1.0 {
                        out.push((row + i) as u32);
                    }
                }
            }
        }
    }
}

/// Per-candidate covered voxels as CSR: candidate `c` covers `voxels[start[c]..start[c + 1]]`.
#[derive(Clone, Debug)]
pub struct Coverage {
    /// Offsets, one more than candidates.
    pub start: Vec<usize>,
    /// Voxel indices.
    pub voxels: Vec<u32>,
}

impl Coverage {
    /// Rasterise every candidate (parallel, deterministic).
    pub fn new(grid: &VoxelGrid, candidates: &[Candidate]) -> Coverage {
        let lists: Vec<Vec<u32>> = candidates
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
        let mut voxels = Vec::with_capacity(total);
        for l in lists {
            voxels.extend_from_slice(&l);
        }
        Coverage { start, voxels }
    }

    /// Voxels of candidate `c`.
    pub fn of(&self, c: usize) -> &[u32] {
        &self.voxels[self.start[c]..self.start[c + 1]]
    }
}

/// Greedy weighted maximum coverage; see [`super::select_greedy`].
pub fn select_greedy(cfg: &DecomposeConfig, bounds: &Aabb, candidates: &[Candidate]) -> Vec<usize> {
    let grid = VoxelGrid::new(bounds, cfg.voxels);
    let coverage = Coverage::new(&grid, candidates);
    let mut covered = vec![false; grid.len()];
    let gain_of = |c: usize, covered: &[bool]| {
        let fresh = coverage.of(c).iter().filter(|&&v| !covered[v as usize]).count();
        candidates[c].weight * fresh as f64
    };
    // Non-negative finite f64 order like their bit patterns; ties pop the lower index first.
    let mut heap: BinaryHeap<(u64, Reverse<usize>)> = (0..candidates.len())
        .map(|c| (gain_of(c, &covered), c))
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
        for &v in coverage.of(c) {
            covered[v as usize] = true;
        }
        total += gain;
        order.push(c);
    }
    order
}
