//! A sparse voxel grid of the renderer's extinction, sampled through the [`Medium`] contract.
//!
//! The lattice: voxel `ijk` (index space) has its centre at world `translation + voxel·ijk`,
//! and `translation` is itself a multiple of `voxel`, so every frame of a shot samples the same
//! world lattice `voxel·ℤ³`; only the index origin moves with the cloud (index `(0, 0, 0)` is
//! the lattice point just below the cloud's bounds, which keeps an OpenVDB tree inside as few
//! top nodes as possible).
//!
//! Sampling: the index box is cut into columns of 8×8 voxel columns (one OpenVDB leaf across);
//! per column one [`Medium::begin_tile`] with a frustum around it, then per voxel column one ray
//! along +Z and [`Medium::extinction`] at every voxel centre inside the ray's intervals (the
//! renderer's lattice sampler, `render/medium/lattice.rs`, which the light grid uses too). Leaves
//! (8³ voxels) with no positive value are dropped. Columns run in parallel with rayon; every
//! value is computed independently of the others, so the grid is identical at any thread count.

use glam::Vec3A;
use rayon::prelude::*;

use crate::render::Medium;
use crate::render::Ray;
use crate::render::medium::lattice::{Columns, sample_bundle};

/// Voxels along one side of a leaf (OpenVDB's `LeafNode` log2 dimension 3).
pub const LEAF_DIM: i32 = 8;

/// Values of one leaf.
pub const LEAF_VOXELS: usize = 512;

/// The most voxels a grid's index box may span along one axis (index coordinates are `i32`).
pub const MAX_AXIS_VOXELS: i64 = 1 << 28;

/// An 8³ block of voxels at a leaf-aligned index origin.
#[derive(Clone, Debug, PartialEq)]
pub struct Leaf {
    /// Index coordinates of the leaf's first voxel (multiples of [`LEAF_DIM`]).
    pub origin: [i32; 3],
    /// Extinction per voxel at index `(x << 6) | (y << 3) | z` (offsets inside the leaf);
    /// 0 where there is no medium.
    pub values: Box<[f32; LEAF_VOXELS]>,
}

impl Leaf {
    /// Offset inside the leaf of the value at `i` (`(x << 6) | (y << 3) | z`).
    #[inline]
    pub fn offset(i: usize) -> [i32; 3] {
        [(i >> 6) as i32, ((i >> 3) & 7) as i32, (i & 7) as i32]
    }

    /// The active (positive) voxels: `(index coordinates, value)`.
    pub fn active(&self) -> impl Iterator<Item = ([i32; 3], f32)> + '_ {
        self.values
            .iter()
            .enumerate()
            .filter(|(_, v)| **v > 0.0)
            .map(|(i, &v)| {
                let o = Leaf::offset(i);
                (std::array::from_fn(|a| self.origin[a] + o[a]), v)
            })
    }

    /// Active (positive) voxels.
    pub fn active_count(&self) -> usize {
        self.values.iter().filter(|&&v| v > 0.0).count()
    }
}

/// A sparse grid of extinction values (per world unit) on a uniform lattice.
#[derive(Clone, Debug, PartialEq)]
pub struct DensityGrid {
    /// Edge length of a voxel, world units.
    pub voxel: f64,
    /// World position of the centre of index voxel `(0, 0, 0)` (a multiple of `voxel`).
    pub translation: [f64; 3],
    /// Leaves holding at least one positive value, sorted by origin (x, then y, then z).
    pub leaves: Vec<Leaf>,
}

/// Why a grid cannot be sampled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    /// The voxel size is not a positive finite number.
    #[error("voxel size must be a positive number, got {0}")]
    BadVoxel(f64),
    /// The bounds span more voxels along an axis than index coordinates hold.
    #[error(
        "the cloud spans {voxels} voxels of {voxel} along one axis (at most {MAX_AXIS_VOXELS}); use a larger voxel size"
    )]
    TooLarge {
        /// Voxels along the longest axis.
        voxels: i64,
        /// The voxel size.
        voxel: f64,
    },
}

impl DensityGrid {
    /// A grid with no active voxel.
    pub fn empty(voxel: f64) -> DensityGrid {
        DensityGrid {
            voxel,
            translation: [0.0; 3],
            leaves: Vec::new(),
        }
    }

    /// Number of active (positive) voxels.
    pub fn active_count(&self) -> usize {
        self.leaves.iter().map(Leaf::active_count).sum()
    }

    /// Largest value (0 when empty).
    pub fn max_value(&self) -> f32 {
        self.leaves
            .iter()
            .flat_map(|l| l.values.iter())
            .fold(0.0f32, |a, &b| a.max(b))
    }

    /// World position of the centre of index voxel `ijk`.
    pub fn world(&self, ijk: [i32; 3]) -> [f64; 3] {
        std::array::from_fn(|a| self.translation[a] + self.voxel * ijk[a] as f64)
    }

    /// Inclusive index bounds `(min, max)` of the active voxels, `None` when empty.
    pub fn active_index_bounds(&self) -> Option<([i32; 3], [i32; 3])> {
        let mut lo = [i32::MAX; 3];
        let mut hi = [i32::MIN; 3];
        for (ijk, _) in self.leaves.iter().flat_map(Leaf::active) {
            for a in 0..3 {
                lo[a] = lo[a].min(ijk[a]);
                hi[a] = hi[a].max(ijk[a]);
            }
        }
        (lo[0] <= hi[0]).then_some((lo, hi))
    }

    /// The value at index `ijk` (0 outside the stored leaves).
    pub fn value(&self, ijk: [i32; 3]) -> f32 {
        let origin = ijk.map(|c| c & !(LEAF_DIM - 1));
        match self.leaves.binary_search_by(|l| l.origin.cmp(&origin)) {
            Ok(n) => {
                let [x, y, z] = std::array::from_fn(|a| (ijk[a] - origin[a]) as usize);
                self.leaves[n].values[(x << 6) | (y << 3) | z]
            }
            Err(_) => 0.0,
        }
    }
}

/// Sample `medium`'s extinction at the centres of the lattice `voxel·ℤ³` inside the world box
/// `[lo, hi]` (outside it the medium must be empty, e.g. `BlobMedium::bounds`).
pub fn sample_medium<M: Medium>(
    medium: &M,
    lo: Vec3A,
    hi: Vec3A,
    voxel: f64,
) -> Result<DensityGrid, GridError> {
    if !(voxel.is_finite() && voxel > 0.0) {
        return Err(GridError::BadVoxel(voxel));
    }
    let (lo, hi) = (lo.to_array(), hi.to_array());
    // Index 0 is the lattice point at or below `lo`; the last one at or above `hi`.
    let first: [i64; 3] = std::array::from_fn(|a| (lo[a] as f64 / voxel).floor() as i64);
    let dims: [i64; 3] =
        std::array::from_fn(|a| (hi[a] as f64 / voxel).ceil() as i64 - first[a] + 1);
    let longest = dims.iter().copied().max().unwrap_or(0);
    if longest > MAX_AXIS_VOXELS {
        return Err(GridError::TooLarge {
            voxels: longest,
            voxel,
        });
    }
    let translation = first.map(|f| f as f64 * voxel);
    let dims = dims.map(|d| d.max(1) as usize);
    let leaf = LEAF_DIM as usize;
    let columns = [dims[0].div_ceil(leaf), dims[1].div_ceil(leaf)];
    let column_leaves: Vec<Vec<Leaf>> = (0..columns[0] * columns[1])
        .into_par_iter()
        .map_init(
            || (medium.scratch(), ColumnBuffer::default()),
            |(scratch, buf), c| {
                let column = [c / columns[1], c % columns[1]];
                let spec = ColumnSpec {
                    column,
                    dims,
                    voxel,
                    translation,
                };
                sample_column(medium, &spec, scratch, buf)
            },
        )
        .collect();
    Ok(DensityGrid {
        voxel,
        translation,
        leaves: column_leaves.into_iter().flatten().collect(),
    })
}

/// Where one leaf column sits in the sampled box.
struct ColumnSpec {
    /// Leaf column `(x, y)`.
    column: [usize; 2],
    /// Voxels of the box per axis.
    dims: [usize; 3],
    voxel: f64,
    translation: [f64; 3],
}

/// Reused per thread: per leaf of the current column (indexed by leaf `z`), the voxels that the
/// column's rays found inside the medium's intervals.
#[derive(Default)]
struct ColumnBuffer {
    candidates: Vec<[u64; 8]>,
}

/// Sample one column of leaves (all `z`), returning its leaves with a positive value in `z`
/// order.
///
/// Two passes: rays along the voxel columns find the voxels inside the medium's intervals
/// (widened by one voxel); then each such voxel is evaluated by its own ray starting at its
/// centre (`t = 0`) under the same column frustum. The value is thus the medium's extinction
/// at the centre itself, free of the rounding of a long ray parameter.
fn sample_column<M: Medium>(
    medium: &M,
    spec: &ColumnSpec,
    scratch: &mut M::Scratch,
    buf: &mut ColumnBuffer,
) -> Vec<Leaf> {
    let leaf = LEAF_DIM as usize;
    let [nx, ny, nz] = spec.dims;
    let h = spec.voxel;
    let x0 = spec.column[0] * leaf;
    let y0 = spec.column[1] * leaf;
    let (x1, y1) = ((x0 + leaf).min(nx), (y0 + leaf).min(ny));
    let centre = |i: usize, a: usize| spec.translation[a] + h * i as f64;
    // Rays start one voxel below the first voxel centre: voxel k sits at t = (k + 1)·h.
    let z_start = centre(0, 2) - h;
    let columns = Columns {
        start: glam::DVec3::new(centre(0, 0), centre(0, 1), z_start),
        u: glam::DVec3::X,
        v: glam::DVec3::Y,
        dir: glam::DVec3::Z,
        h,
        length: h * (nz + 1) as f64,
    };
    buf.candidates.clear();
    buf.candidates.resize(nz.div_ceil(leaf), [0; 8]);
    let ray = |i: usize, j: usize| Ray {
        origin: Vec3A::new(centre(i, 0) as f32, centre(j, 1) as f32, z_start as f32),
        dir: Vec3A::Z,
    };
    let candidates = &mut buf.candidates;
    sample_bundle(
        medium,
        scratch,
        &columns,
        x0..x1,
        y0..y1,
        ray,
        |s, i, j, _| {
            let within = ((i - x0) << 6) | ((j - y0) << 3);
            for iv in medium.intervals(s) {
                let k0 = ((iv[0] as f64 / h).floor() as i64 - 2).max(0);
                let k1 = ((iv[1] as f64 / h).ceil() as i64).min(nz as i64 - 1);
                for k in k0..=k1 {
                    let (k, bit) = (k as usize, within | (k as usize % leaf));
                    candidates[k / leaf][bit >> 6] |= 1 << (bit & 63);
                }
            }
        },
    );
    let mut leaves = Vec::new();
    for (lz, marks) in buf.candidates.iter().enumerate() {
        if marks.iter().all(|&w| w == 0) {
            continue;
        }
        let z0 = lz * leaf;
        let mut values = Box::new([0.0f32; LEAF_VOXELS]);
        let mut any = false;
        for (n, value) in values.iter_mut().enumerate() {
            if marks[n >> 6] & (1 << (n & 63)) == 0 {
                continue;
            }
            let o = Leaf::offset(n);
            let p = Vec3A::new(
                centre(x0 + o[0] as usize, 0) as f32,
                centre(y0 + o[1] as usize, 1) as f32,
                centre(z0 + o[2] as usize, 2) as f32,
            );
            *value = point_extinction(medium, scratch, p);
            any |= *value > 0.0;
        }
        if any {
            leaves.push(Leaf {
                origin: [x0 as i32, y0 as i32, z0 as i32],
                values,
            });
        }
    }
    leaves
}

/// `medium`'s extinction at `p`, by a ray along +Z starting at `p` (0 outside the medium).
/// The last tile must contain `p`.
pub fn point_extinction<M: Medium>(medium: &M, scratch: &mut M::Scratch, p: Vec3A) -> f32 {
    let ray = Ray {
        origin: p,
        dir: Vec3A::Z,
    };
    medium.begin_ray(&ray, scratch);
    match medium.intervals(scratch).first() {
        Some(iv) if iv[0] == 0.0 => medium.extinction(scratch, 0.0, p),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{Homogeneous, Shape};

    fn ball(radius: f32) -> Homogeneous {
        Homogeneous {
            shape: Shape::Ball {
                center: Vec3A::new(0.3, -0.2, 1.1),
                radius,
            },
            sigma_t: 2.5,
            step: 0.01,
        }
    }

    #[test]
    fn ball_grid_matches_the_ball() {
        let m = ball(0.5);
        let h = 0.02;
        let g = sample_medium(
            &m,
            Vec3A::new(-0.3, -0.8, 0.5),
            Vec3A::new(0.9, 0.4, 1.7),
            h,
        )
        .unwrap();
        // Lattice-aligned translation and sorted leaves.
        for a in 0..3 {
            let r = g.translation[a] / h;
            assert!((r - r.round()).abs() < 1e-9);
        }
        assert!(g.leaves.windows(2).all(|w| w[0].origin < w[1].origin));
        // Every active voxel is inside the ball, every lattice point well inside is active.
        let centre = [0.3, -0.2, 1.1];
        let inside = |p: [f64; 3]| {
            (0..3)
                .map(|a| (p[a] - centre[a]).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        for leaf in &g.leaves {
            for (i, &v) in leaf.values.iter().enumerate() {
                if v > 0.0 {
                    let o = Leaf::offset(i);
                    let p = g.world(std::array::from_fn(|a| leaf.origin[a] + o[a]));
                    assert!(inside(p) < 0.5 + 1e-4, "{p:?}");
                    assert_eq!(v, 2.5);
                }
            }
        }
        // Count against the lattice points in the ball (boundary points may go either way).
        let n = g.active_count() as f64;
        let volume = 4.0 / 3.0 * std::f64::consts::PI * 0.125 / (h * h * h);
        assert!((n / volume - 1.0).abs() < 0.02, "{n} vs {volume}");
        let probe = [((0.3 - g.translation[0]) / h).round() as i32, 0, 0];
        let probe = [
            probe[0],
            ((-0.2 - g.translation[1]) / h).round() as i32,
            ((1.1 - g.translation[2]) / h).round() as i32,
        ];
        assert_eq!(g.value(probe), 2.5);
    }

    #[test]
    fn empty_medium_gives_no_leaves_and_bad_voxels_are_errors() {
        let m = ball(0.5);
        let far = sample_medium(&m, Vec3A::splat(5.0), Vec3A::splat(5.5), 0.05).unwrap();
        assert!(far.leaves.is_empty() && far.active_index_bounds().is_none());
        for v in [0.0, -1.0, f64::NAN] {
            assert!(matches!(
                sample_medium(&m, Vec3A::ZERO, Vec3A::ONE, v),
                Err(GridError::BadVoxel(_))
            ));
        }
        assert!(matches!(
            sample_medium(&m, Vec3A::ZERO, Vec3A::splat(1e6), 1e-4),
            Err(GridError::TooLarge { .. })
        ));
    }
}
