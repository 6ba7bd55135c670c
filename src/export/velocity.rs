//! The velocity grid `vel` beside the density: what Houdini, Blender, Karma, Arnold and
//! RenderMan read to motion-blur a volume.
//!
//! Layout: the density grid's own lattice, leaves and active voxels (a voxel is active in `vel`
//! exactly where the density is positive, also where the cloud holds still and the velocity is
//! 0); the value of a voxel is the velocity of the density at the voxel's centre
//! ([`crate::animate::VelocityField`]), so the grid is **not staggered** (class `unknown`, not
//! OpenVDB's `staggered` MAC layout): both grids are sampled at the same points.
//!
//! Units and metadata: world units per second (the scene's units after its target transform),
//! in world space (`is_local_space` false, `vector_type` = `contravariant relative`, OpenVDB's
//! kind for velocities); `fps` (double) is the shot's frame rate, so a renderer that wants the
//! displacement per frame divides by it (Gaffer's `velocity_fps`, Blender's velocity scale
//! `1/fps`). The VDB writer attaches them ([`crate::export::velocity_vdb_grid`]), beside the
//! density's `fog volume` class.

use glam::DVec3;
use rayon::prelude::*;

use super::grid::{DensityGrid, LEAF_VOXELS, Leaf};
use crate::animate::VelocityField;

/// The velocity grid's name in VDB files (and the USD field's `fieldName`).
pub const VELOCITY_GRID_NAME: &str = "vel";

/// An 8³ block of vectors at a leaf-aligned index origin.
#[derive(Clone, Debug, PartialEq)]
pub struct VectorLeaf {
    /// Index coordinates of the leaf's first voxel (multiples of 8).
    pub origin: [i32; 3],
    /// Active voxels: bit `i` of the 512 for value `i`.
    pub mask: [u64; 8],
    /// Vectors at index `(x << 6) | (y << 3) | z` (offsets inside the leaf); 0 where inactive.
    pub values: Box<[[f32; 3]; LEAF_VOXELS]>,
}

impl VectorLeaf {
    /// True when value `i` is active.
    #[inline]
    pub fn is_active(&self, i: usize) -> bool {
        self.mask[i >> 6] & (1 << (i & 63)) != 0
    }
}

/// A sparse grid of vectors on the lattice of a [`DensityGrid`].
#[derive(Clone, Debug, PartialEq)]
pub struct VectorGrid {
    /// Edge length of a voxel, world units.
    pub voxel: f64,
    /// World position of the centre of index voxel `(0, 0, 0)`.
    pub translation: [f64; 3],
    /// Leaves, in the density grid's order.
    pub leaves: Vec<VectorLeaf>,
}

impl VectorGrid {
    /// Number of active voxels.
    pub fn active_count(&self) -> usize {
        self.leaves
            .iter()
            .map(|l| {
                l.mask
                    .iter()
                    .map(|w| w.count_ones() as usize)
                    .sum::<usize>()
            })
            .sum()
    }
}

/// The velocity of `field` at the centre of every active voxel of `density`, on its lattice.
/// Leaves in parallel; each value is computed on its own, so the grid is the same at any
/// thread count.
pub fn sample_velocity(density: &DensityGrid, field: &VelocityField) -> VectorGrid {
    let leaves = density
        .leaves
        .par_iter()
        .map(|leaf| {
            let mut mask = [0u64; 8];
            let mut values = Box::new([[0.0f32; 3]; LEAF_VOXELS]);
            for (i, &v) in leaf.values.iter().enumerate() {
                if v <= 0.0 {
                    continue;
                }
                mask[i >> 6] |= 1 << (i & 63);
                let o = Leaf::offset(i);
                let p = density.world(std::array::from_fn(|a| leaf.origin[a] + o[a]));
                values[i] = field.velocity(DVec3::from(p)).as_vec3().to_array();
            }
            VectorLeaf {
                origin: leaf.origin,
                mask,
                values,
            }
        })
        .collect();
    VectorGrid {
        voxel: density.voxel,
        translation: density.translation,
        leaves,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::sphere_blob;
    use crate::blobby::Blob;

    #[test]
    fn velocity_is_active_where_the_density_is_and_moves_with_the_blob() {
        let mut values = Box::new([0.0f32; LEAF_VOXELS]);
        values[0] = 1.0;
        values[73] = 0.5;
        let density = DensityGrid {
            voxel: 0.1,
            translation: [0.0, 0.0, 0.0],
            leaves: vec![Leaf {
                origin: [0, 0, 0],
                values,
            }],
        };
        let blob = sphere_blob(DVec3::splat(0.2), 2.0);
        let shift = |d: f64| Blob {
            center: blob.center + DVec3::new(d, 0.0, 0.0),
            ..blob
        };
        // 0.5 units in 0.25 s: 2 units per second along x.
        let field = VelocityField::new(&[shift(-0.25)], &[blob], &[shift(0.25)], 0.25);
        let grid = sample_velocity(&density, &field);
        assert_eq!(grid.active_count(), 2);
        let l = &grid.leaves[0];
        assert!(l.is_active(0) && l.is_active(73) && !l.is_active(1));
        for i in [0, 73] {
            let v = l.values[i];
            assert!((v[0] - 2.0).abs() < 1e-5 && v[1].abs() < 1e-6, "{v:?}");
        }
        assert_eq!(l.values[1], [0.0; 3]);
    }
}
