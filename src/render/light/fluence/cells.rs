//! The piecewise-constant medium the photons fly through: one extinction per cubic cell, the
//! cell centred on a node of the light grid's coarse (sky) lattice, and the walk of a straight
//! line through the cells (Amanatides & Woo 1987, "A fast voxel traversal algorithm"), which
//! gives free flights analytically cell by cell: inside a cell the optical depth grows
//! linearly, so where a sampled optical depth runs out is one division.
//!
//! In: a [`GridShape`] and its extinction per node. Out: [`Cells`], in grid units (a cell has
//! side 1, optical depths are per cell side).

use glam::Vec3A;

use crate::render::medium::lattice::GridShape;

/// Cells of side 1 in grid coordinates: cell `(i, j, k)` spans `[i, i+1) × [j, j+1) × [k, k+1)`
/// and is centred on node `(i, j, k)` of the lattice it was made from.
#[derive(Clone, Debug)]
pub(crate) struct Cells {
    /// Cells along x, y, z.
    pub dims: [usize; 3],
    /// Optical depth per unit length (one cell side) of each cell, `σ_t · h`, flat index
    /// `i + nx·(j + ny·k)`.
    pub tau: Vec<f32>,
}

impl Cells {
    /// The cells of `shape`'s nodes with extinction `sigma` (one per node).
    pub(crate) fn new(shape: &GridShape, sigma: &[f32]) -> Cells {
        Cells {
            dims: shape.dims,
            tau: sigma.iter().map(|s| s.max(0.0) * shape.h).collect(),
        }
    }

    /// Number of cells.
    pub(crate) fn len(&self) -> usize {
        self.tau.len()
    }

    /// The box of the cells in grid coordinates: `[0, dims]`.
    fn upper(&self) -> Vec3A {
        Vec3A::new(
            self.dims[0] as f32,
            self.dims[1] as f32,
            self.dims[2] as f32,
        )
    }

    /// Where the line from `p` along unit `d` (grid coordinates) enters the cells' box: the
    /// point, or `None` when it misses it.
    pub(crate) fn entry(&self, p: Vec3A, d: Vec3A) -> Option<Vec3A> {
        let inv = d.recip();
        let a = -p * inv;
        let b = (self.upper() - p) * inv;
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element();
        (t1 > t0).then(|| p + d * t0)
    }

    /// Walk the cells the line from `p` (inside the box, or on its boundary) along unit `d`
    /// crosses, in order: `visit(cell, length)` for each piece of line in a cell; a visit that
    /// returns `Some(l)` ends the walk at `l` into its piece, and the walk returns that point.
    /// `None`: the line left the box.
    #[inline]
    pub(crate) fn walk(
        &self,
        p: Vec3A,
        d: Vec3A,
        mut visit: impl FnMut(usize, f32) -> Option<f32>,
    ) -> Option<Vec3A> {
        let n = [
            self.dims[0] as i64,
            self.dims[1] as i64,
            self.dims[2] as i64,
        ];
        let (pa, da) = (p.to_array(), d.to_array());
        let mut c = [0i64; 3];
        let mut step = [0i64; 3];
        let mut t_max = [f32::INFINITY; 3];
        let mut t_delta = [f32::INFINITY; 3];
        for a in 0..3 {
            c[a] = (pa[a].floor() as i64).clamp(0, n[a] - 1);
            if da[a] > 0.0 {
                step[a] = 1;
                t_delta[a] = 1.0 / da[a];
                t_max[a] = ((c[a] + 1) as f32 - pa[a]).max(0.0) * t_delta[a];
            } else if da[a] < 0.0 {
                step[a] = -1;
                t_delta[a] = -1.0 / da[a];
                t_max[a] = (pa[a] - c[a] as f32).max(0.0) * t_delta[a];
            }
        }
        let (sy, sz) = (n[0], n[0] * n[1]);
        let mut idx = c[0] + sy * c[1] + sz * c[2];
        let stride = [1, sy, sz];
        let mut t = 0.0f32;
        loop {
            let a = if t_max[0] < t_max[1] {
                if t_max[0] < t_max[2] { 0 } else { 2 }
            } else if t_max[1] < t_max[2] {
                1
            } else {
                2
            };
            let t_next = t_max[a];
            if let Some(l) = visit(idx as usize, (t_next - t).max(0.0)) {
                return Some(p + d * (t + l));
            }
            t = t_next;
            c[a] += step[a];
            if c[a] < 0 || c[a] >= n[a] {
                return None;
            }
            idx += step[a] * stride[a];
            t_max[a] += t_delta[a];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cells(n: usize) -> Cells {
        let shape = GridShape {
            origin: Vec3A::ZERO,
            h: 0.5,
            dims: [n, n + 1, n + 2],
        };
        Cells::new(&shape, &vec![2.0; shape.len()])
    }

    #[test]
    fn a_walk_crosses_the_box_by_its_chord() {
        let c = cells(8);
        for d in [
            Vec3A::X,
            Vec3A::new(0.3, -0.5, 0.8).normalize(),
            Vec3A::new(-1.0, 1.0, 0.0).normalize(),
        ] {
            let from = Vec3A::new(4.0, 4.5, 5.0) - d * 100.0;
            let p = c.entry(from, d).expect("aimed at the box");
            let mut total = 0.0;
            let mut pieces = 0;
            assert!(
                c.walk(p, d, |_, l| {
                    total += l;
                    pieces += 1;
                    None
                })
                .is_none()
            );
            // The exit: the entry point of the reversed line from far beyond.
            let q = c.entry(p + d * 100.0, -d).expect("from the other side");
            assert!(
                (total - (q - p).length()).abs() < 1e-3,
                "{total} vs {}",
                (q - p).length()
            );
            assert!(pieces >= 8);
            // Stopping half-way returns the point half-way.
            let mut left = 0.5 * total;
            let stop = c
                .walk(p, d, |_, l| {
                    if l > left {
                        Some(left)
                    } else {
                        left -= l;
                        None
                    }
                })
                .expect("stops inside");
            assert!((stop - (p + q) * 0.5).length() < 1e-3);
        }
        assert!(c.entry(Vec3A::new(-1.0, -1.0, -1.0), -Vec3A::X).is_none());
        // σ·h per cell side.
        assert_eq!(c.tau[0], 1.0);
        assert_eq!(c.len(), 8 * 9 * 10);
    }
}
