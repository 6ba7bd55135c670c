//! Mitsuba's binary grid format (`.vol`, as read by `gridvolume` and `mi.VolumeGrid`): a dense
//! float grid over the active voxels' box, for the reference renders of the cloud look.
//!
//! Layout (little-endian): the bytes `VOL`, the version byte 3, `i32` encoding 1 (float32),
//! `i32` resolution x, y, z, `i32` channels 1, the bounding box as 6 `f32` (min x, y, z, max x,
//! y, z), then the values with x fastest: index `(z·ny + y)·nx + x`.
//!
//! The box is the outer box of the voxel cells: voxel `(x, y, z)` has its centre at
//! `min + (x + ½, y + ½, z + ½)·voxel`, the cell-centred convention of Mitsuba 3's grid lookup
//! (which maps the grid onto the unit cube of its `to_world`; put that box there). Values are
//! the renderer's extinction per world unit. An empty grid is written as one zero voxel.

use std::path::Path;

use super::grid::{DensityGrid, Leaf};

/// The most voxels a `.vol` file may hold (a dense 1 GiB of floats).
pub const MAX_VOL_VOXELS: u64 = 1 << 28;

/// Write `grid` as a Mitsuba `.vol` file, atomically.
pub fn write_vol(path: &Path, grid: &DensityGrid) -> std::io::Result<()> {
    crate::atomic::write_bytes_atomically(path, &encode_vol(grid)?)
}

/// Voxels of the dense box a `.vol` file of `grid` holds (its active voxels' bounding box; at
/// most [`MAX_VOL_VOXELS`] can be written).
pub fn vol_voxels(grid: &DensityGrid) -> u64 {
    vol_box(grid).1.iter().map(|&d| d as u64).product()
}

/// The dense box a `.vol` file of `grid` holds: its first voxel's index and its size.
fn vol_box(grid: &DensityGrid) -> ([i32; 3], [usize; 3]) {
    let (lo, hi) = grid.active_index_bounds().unwrap_or(([0; 3], [0; 3]));
    (lo, std::array::from_fn(|a| (hi[a] - lo[a] + 1) as usize))
}

/// The `.vol` file's bytes (see the module doc); an error when the dense box is larger than
/// [`MAX_VOL_VOXELS`].
pub fn encode_vol(grid: &DensityGrid) -> std::io::Result<Vec<u8>> {
    let (lo, dims) = vol_box(grid);
    let hi: [i32; 3] = std::array::from_fn(|a| lo[a] + dims[a] as i32 - 1);
    let count = dims.iter().map(|&d| d as u64).product::<u64>();
    if count > MAX_VOL_VOXELS {
        return Err(std::io::Error::other(format!(
            "the cloud's box is {}×{}×{} voxels, more than a .vol file's {MAX_VOL_VOXELS}; \
             use a larger output.voxel",
            dims[0], dims[1], dims[2]
        )));
    }
    let mut values = vec![0.0f32; count as usize];
    let [nx, ny, _] = dims;
    for (ijk, v) in grid.leaves.iter().flat_map(Leaf::active) {
        let [x, y, z] = std::array::from_fn(|a| (ijk[a] - lo[a]) as usize);
        values[(z * ny + y) * nx + x] = v;
    }
    let half = 0.5 * grid.voxel;
    let (min, max) = (grid.world(lo), grid.world(hi));
    let mut out = Vec::with_capacity(48 + 4 * values.len());
    out.extend_from_slice(b"VOL\x03");
    for v in [1, dims[0] as i32, dims[1] as i32, dims[2] as i32, 1] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for c in min
        .map(|c| c - half)
        .into_iter()
        .chain(max.map(|c| c + half))
    {
        out.extend_from_slice(&(c as f32).to_le_bytes());
    }
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::super::grid::LEAF_VOXELS;
    use super::*;

    #[test]
    fn dense_layout_is_x_fastest_over_the_active_box() {
        let mut values = Box::new([0.0; LEAF_VOXELS]);
        values[(1 << 6) | (2 << 3) | 3] = 1.5; // (9, 2, 3) with the leaf at x = 8
        values[(2 << 6) | (4 << 3) | 3] = 2.5; // (10, 4, 3)
        let grid = DensityGrid {
            voxel: 0.5,
            translation: [1.0, 0.0, -1.0],
            leaves: vec![Leaf {
                origin: [8, 0, 0],
                values,
            }],
        };
        let b = encode_vol(&grid).unwrap();
        let i32_at = |at: usize| i32::from_le_bytes(b[at..at + 4].try_into().unwrap());
        let f32_at = |at: usize| f32::from_le_bytes(b[at..at + 4].try_into().unwrap());
        assert_eq!(&b[..4], b"VOL\x03");
        assert_eq!(
            (i32_at(4), i32_at(8), i32_at(12), i32_at(16), i32_at(20)),
            (1, 2, 3, 1, 1)
        );
        // Box: x centres 1 + 0.5·9 = 5.5 and 6.0, so cells [5.25, 6.25].
        let bbox: Vec<f32> = (0..6).map(|k| f32_at(24 + 4 * k)).collect();
        assert_eq!(bbox, vec![5.25, 0.75, 0.25, 6.25, 2.25, 0.75]);
        let data: Vec<f32> = (0..6).map(|k| f32_at(48 + 4 * k)).collect();
        assert_eq!(data, vec![1.5, 0.0, 0.0, 0.0, 0.0, 2.5]);
        assert_eq!(b.len(), 48 + 4 * 6);
        // Empty: one zero voxel.
        let empty = encode_vol(&DensityGrid::empty(0.1)).unwrap();
        assert_eq!(empty.len(), 48 + 4);
    }
}
