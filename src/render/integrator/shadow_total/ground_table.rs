//! The ground plane's share of the sky the cloud takes, tabulated once a frame
//! ([`GroundTable`], see the parent module).

use std::f32::consts::PI;

use glam::Vec3A;
use rayon::prelude::*;

use super::{Extinction, ShadowTotal};
use crate::render::surfaces::Surfaces;
use crate::rng::{Stream, item_rng};

/// Angles (columns) and radii (rows) of the ground's table ([`GroundTable`]).
const TABLE_ANGLES: usize = 64;
const TABLE_RADII: usize = 48;
/// Strata a side of each table node's directions (256 a node).
const TABLE_SIDE: u32 = 16;

/// `∫ (1 − T(ω)) L(ω) cos θ dω` on the ground plane (facing up), at the nodes of a polar
/// table about the point under the cloud's centre: angle `2π·i/`[`TABLE_ANGLES`], radius
/// `r = s·v/(1 − v)` at `v = j/`[`TABLE_RADII`] (`s` the cloud's bounding radius: fine under
/// the cloud, the whole plane out to `47 s`), bilinear between them. The sky's shadow on the
/// ground is smooth (each point sees the whole cloud), so a table of 3,072 points with 256
/// directions each stands for every ground pixel at a fraction of their cost and without
/// their noise.
#[derive(Clone, Debug)]
pub(super) struct GroundTable {
    center: Vec3A,
    scale: f32,
    values: Vec<Vec3A>,
}

impl GroundTable {
    /// The table on the plane `y = height` for the cloud `cloud`; node `k`'s directions from
    /// `item_rng(seed, Stream::SkyShadow, u64::MAX − k)` (apart from the pixels' items).
    pub(super) fn build(
        total: &ShadowTotal,
        cloud: &Extinction,
        surfaces: &Surfaces,
        height: f32,
        seed: u64,
    ) -> GroundTable {
        let center = Vec3A::new(cloud.center.x, height, cloud.center.z);
        let scale = cloud.radius;
        let values = (0..TABLE_ANGLES * TABLE_RADII)
            .into_par_iter()
            .map(|k| {
                let (i, j) = (k % TABLE_ANGLES, k / TABLE_ANGLES);
                let a = 2.0 * PI * i as f32 / TABLE_ANGLES as f32;
                let v = j as f32 / TABLE_RADII as f32;
                let r = scale * v / (1.0 - v);
                let p = center + Vec3A::new(a.cos(), 0.0, a.sin()) * r;
                let mut rng = item_rng(seed, Stream::SkyShadow, u64::MAX - k as u64);
                total.sky_taken(cloud, surfaces, p, Vec3A::Y, TABLE_SIDE, &mut rng)
            })
            .collect();
        GroundTable {
            center,
            scale,
            values,
        }
    }

    /// The table's value at ground point `p` (bilinear; past its last radius, that radius's).
    pub(super) fn lookup(&self, p: Vec3A) -> Vec3A {
        let (dx, dz) = (p.x - self.center.x, p.z - self.center.z);
        let r = (dx * dx + dz * dz).sqrt();
        let a = dz.atan2(dx).rem_euclid(2.0 * PI);
        let fi = a / (2.0 * PI) * TABLE_ANGLES as f32;
        let fj = (r / (r + self.scale) * TABLE_RADII as f32).min((TABLE_RADII - 1) as f32);
        let (i0, j0) = (
            fi as usize % TABLE_ANGLES,
            (fj as usize).min(TABLE_RADII - 2),
        );
        let (wi, wj) = (fi - fi.floor(), (fj - j0 as f32).min(1.0));
        let i1 = (i0 + 1) % TABLE_ANGLES;
        let t = |i: usize, j: usize| self.values[j * TABLE_ANGLES + i];
        (t(i0, j0) * (1.0 - wi) + t(i1, j0) * wi) * (1.0 - wj)
            + (t(i0, j0 + 1) * (1.0 - wi) + t(i1, j0 + 1) * wi) * wj
    }
}
