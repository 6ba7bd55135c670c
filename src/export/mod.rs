//! Clouds that leave nephele: the renderer's density as OpenVDB and Mitsuba `.vol` grids (the
//! shot's USD stage, which points at them, is written by [`crate::scene::shot::usd`]).
//!
//! In: a frame's blobs and [`RenderSettings`] (the same the frame is rendered with). Out: a
//! [`DensityGrid`] sampled through the renderer's own [`crate::render::Medium`] (so the files
//! hold exactly the extinction the renderer marches through, noise included), written by
//! [`vdb`] and [`vol`]; [`velocity`] samples the cloud's velocity on the density's voxels (the
//! VDB's `vel` grid).
//!
//! Units: world (the scene's, after the target transform); values are extinction per world unit.

pub mod grid;
pub mod vdb;
pub mod velocity;
pub mod vol;

pub use grid::{DensityGrid, GridError, Leaf, sample_medium};
pub use vdb::{Precision, VdbGrid, velocity_vdb_grid, write_vdb, write_vdb_grids};
pub use velocity::{VELOCITY_GRID_NAME, VectorGrid, sample_velocity};
pub use vol::write_vol;

use crate::blobby::Blob;
use crate::geometry::Aabb;
use crate::render::{BlobMedium, RenderSettings};

/// Default voxel size: this fraction of the target's bounding-box diagonal. Set by the look:
/// the cloud's edge ramp (0.008 of the diagonal) spans four voxels, which a grid reconstructs
/// (at under three a voxel grid's rim came out fatter than the frame's), and the finest billows
/// of a 640×360 frame (a few pixels) are a few voxels wide. The grid is sparse: finer voxels cost
/// only where the cloud is.
pub const DEFAULT_VOXELS_PER_DIAGONAL: f64 = 512.0;

/// Most voxels the target's box may hold at the chosen voxel size (beyond, the voxel size is
/// taken for a mistake).
pub const MAX_TARGET_VOXELS: u64 = 1 << 31;

/// The grid's name in VDB files.
pub const GRID_NAME: &str = "density";

/// The voxel size for `target` bounds: `voxel` if given, else the diagonal / [`DEFAULT_VOXELS_PER_DIAGONAL`].
pub fn voxel_size(voxel: Option<f64>, target: &Aabb) -> f64 {
    voxel.unwrap_or(target.diagonal() / DEFAULT_VOXELS_PER_DIAGONAL)
}

/// Width in world units of one pixel's footprint at `point`, seen by `camera` in an image
/// `height` pixels tall: `2·d·tan(fov/2) / height`, `d` the distance from the eye to `point`
/// (the camera's field of view is vertical, its pixels square).
pub fn pixel_footprint(camera: &crate::render::Camera, height: u32, point: glam::DVec3) -> f64 {
    let fov = f64::from(camera.fov_deg.clamp(0.1, 179.0)).to_radians();
    let d = (point - camera.position.as_dvec3()).length();
    2.0 * d * (0.5 * fov).tan() / f64::from(height.max(1))
}

/// The voxel size `pixels` pixels wide (`output.voxel_pixels`): `pixels` times the smallest
/// [`pixel_footprint`] at the centre of the target's box over `cameras` (every frame's camera
/// of the shot, so the whole shot shares one lattice and no frame's grid is coarser than it
/// asked for), in an image `height` pixels tall. `None` without cameras.
pub fn footprint_voxel<'a>(
    pixels: f64,
    cameras: impl IntoIterator<Item = &'a crate::render::Camera>,
    height: u32,
    target: &Aabb,
) -> Option<f64> {
    let centre = 0.5 * (target.min + target.max);
    cameras
        .into_iter()
        .map(|c| pixel_footprint(c, height, centre))
        .min_by(f64::total_cmp)
        .map(|f| pixels * f)
}

/// Voxels the target's box holds at `voxel` (each side rounded up); an error message when it
/// is more than [`MAX_TARGET_VOXELS`] or `voxel` is not positive.
pub fn check_voxel_budget(voxel: f64, target: &Aabb) -> Result<u64, String> {
    if !(voxel.is_finite() && voxel > 0.0) {
        return Err(format!("must be a positive number, got {voxel}"));
    }
    let size = target.max - target.min;
    let count = [size.x, size.y, size.z]
        .iter()
        .map(|&s| (s / voxel).ceil().max(1.0))
        .product::<f64>();
    if count > MAX_TARGET_VOXELS as f64 {
        return Err(format!(
            "{voxel} gives {count:.3e} voxels over the target's box, more than {MAX_TARGET_VOXELS}; \
             use a larger voxel (the default is the target's diagonal / {DEFAULT_VOXELS_PER_DIAGONAL} = {:.6})",
            target.diagonal() / DEFAULT_VOXELS_PER_DIAGONAL
        ));
    }
    Ok(count as u64)
}

/// The extinction grid of one frame: `blobs` as the renderer sees them with `settings`,
/// sampled at voxel centres on the lattice `voxel·ℤ³`. Empty when no blob is live.
pub fn frame_grid(
    settings: &RenderSettings,
    blobs: &[Blob],
    voxel: f64,
) -> Result<DensityGrid, GridError> {
    let medium = BlobMedium::new(settings, blobs);
    match medium.bounds() {
        Some((lo, hi)) => sample_medium(&medium, lo, hi, voxel),
        None if voxel.is_finite() && voxel > 0.0 => Ok(DensityGrid::empty(voxel)),
        None => Err(GridError::BadVoxel(voxel)),
    }
}
