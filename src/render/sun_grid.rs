//! Optical depth toward the sun on a grid aligned with the sunlight, so each depth is a plain
//! running sum along one grid axis.
//!
//! A sweep through a world-aligned grid resamples the previous slice bilinearly at every step;
//! over a hundred slices that blurs the depth sideways by several cells, which dims a backlit
//! cloud's bright rim (the silver lining comes from light grazing its thin edge) and softens
//! shadow edges. In light space nothing is resampled along the way: the extinction is sampled
//! once per node (trilinearly from the world grid) and summed along the light.
//!
//! In: the world grid's extinction and the sun's direction. Out: [`SunGrid::lookup`] → depth and
//! transmittance toward the sun anywhere (trilinear in light space).

use glam::{Mat3A, Vec3A};
use rayon::prelude::*;

use super::lattice::{GridShape, trilinear};

/// Depth and transmittance toward the sun on a light-aligned grid.
#[derive(Clone, Debug)]
pub struct SunGrid {
    /// World → light coordinates (rows: across, along the light, across).
    to_light: Mat3A,
    /// Node grid in light coordinates; the light travels along its `y` axis.
    shape: GridShape,
    inv_h: f32,
    /// `[τ, e^{−τ}]` per node.
    values: Vec<f32>,
}

impl SunGrid {
    /// Sum the extinction `sigma` of the world grid `world` along `sun_dir` (unit, the way the
    /// light travels) on a light-aligned grid of the same spacing covering it.
    pub fn build(world: &GridShape, sigma: &[f32], sun_dir: Vec3A) -> SunGrid {
        let along = sun_dir.normalize_or(Vec3A::NEG_Y);
        let helper = if along.x.abs() < 0.9 {
            Vec3A::X
        } else {
            Vec3A::Z
        };
        let across = along.cross(helper).normalize();
        let across2 = across.cross(along);
        let to_light = Mat3A::from_cols(across, along, across2).transpose();
        // The world grid's box in light coordinates.
        let h = world.h;
        let size = Vec3A::new(
            (world.dims[0] - 1) as f32,
            (world.dims[1] - 1) as f32,
            (world.dims[2] - 1) as f32,
        ) * h;
        let (mut lo, mut hi) = (Vec3A::splat(f32::MAX), Vec3A::splat(f32::MIN));
        for c in 0..8 {
            let corner = world.origin
                + Vec3A::new(
                    if c & 1 == 0 { 0.0 } else { size.x },
                    if c & 2 == 0 { 0.0 } else { size.y },
                    if c & 4 == 0 { 0.0 } else { size.z },
                );
            let l = to_light * corner;
            lo = lo.min(l);
            hi = hi.max(l);
        }
        let n = |s: f32| (s / h).ceil() as usize + 1;
        let shape = GridShape {
            origin: lo,
            h,
            dims: [n(hi.x - lo.x), n(hi.y - lo.y), n(hi.z - lo.z)],
        };
        let [nx, ny, _] = shape.dims;
        let to_world = to_light.transpose();
        let inv_world_h = 1.0 / h;
        let mut values = vec![0.0f32; shape.len() * 2];
        // One slab per z: its columns along y (the light) are summed independently.
        values
            .par_chunks_mut(nx * ny * 2)
            .enumerate()
            .for_each(|(k, slab)| {
                for i in 0..nx {
                    let (mut tau, mut prev) = (0.0f32, 0.0f32);
                    for j in 0..ny {
                        let p = to_world * shape.node(i, j, k);
                        let mut s = [0.0f32; 1];
                        trilinear::<1>(world, inv_world_h, sigma, p, &mut s);
                        if j > 0 {
                            tau += 0.5 * (prev + s[0]) * h;
                        }
                        prev = s[0];
                        // No shift toward the light here (the world grid's sweep needs one):
                        // measured against Mitsuba, any shift made the cloud brighter than
                        // the reference.
                        let idx = 2 * (i + nx * j);
                        slab[idx] = tau;
                        slab[idx + 1] = (-tau).exp();
                    }
                }
            });
        SunGrid {
            to_light,
            inv_h: 1.0 / h,
            shape,
            values,
        }
    }

    /// `[τ, e^{−τ}]` toward the sun at world point `x` (clamped to the grid, whose border
    /// lies outside the cloud).
    #[inline]
    pub fn lookup(&self, x: Vec3A) -> [f32; 2] {
        let mut out = [0.0f32; 2];
        trilinear::<2>(
            &self.shape,
            self.inv_h,
            &self.values,
            self.to_light * x,
            &mut out,
        );
        out
    }
}
