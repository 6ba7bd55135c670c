//! Signed-distance building blocks for the toy figures (negative inside, in world units).
//!
//! The ellipsoid distance is Quílez's bound `k0 (k0 − 1) / k1`: exact zero set, close to the
//! true distance near the surface, which is all a smooth union and a polygonizer need.

use glam::{DQuat, DVec3};

/// An ellipsoid part: centre, rotation (local → world) and semi-axes.
#[derive(Clone, Copy, Debug)]
pub struct Part {
    center: DVec3,
    /// World → local rotation (inverse of the part's orientation).
    local_from_world: DQuat,
    semi_axes: DVec3,
}

impl Part {
    /// An axis-aligned ellipsoid.
    pub fn ellipsoid(center: DVec3, semi_axes: DVec3) -> Part {
        Part::rotated(center, semi_axes, DQuat::IDENTITY)
    }

    /// A sphere.
    pub fn sphere(center: DVec3, radius: f64) -> Part {
        Part::ellipsoid(center, DVec3::splat(radius))
    }

    /// An ellipsoid with orientation `world_from_local`.
    pub fn rotated(center: DVec3, semi_axes: DVec3, world_from_local: DQuat) -> Part {
        Part {
            center,
            local_from_world: world_from_local.inverse(),
            semi_axes,
        }
    }

    /// Approximate signed distance (negative inside; exact zero set).
    #[inline]
    pub fn distance(&self, p: DVec3) -> f64 {
        let q = self.local_from_world * (p - self.center);
        let k0 = (q / self.semi_axes).length();
        let k1 = (q / (self.semi_axes * self.semi_axes)).length();
        if k1 == 0.0 {
            // The centre: deepest point.
            -self.semi_axes.min_element()
        } else {
            k0 * (k0 - 1.0) / k1
        }
    }
}

/// Polynomial smooth minimum with blend width `k` (union with a fillet of size ≈ `k`).
#[inline]
pub fn smooth_min(a: f64, b: f64, k: f64) -> f64 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

/// Smooth maximum (intersection with a fillet of size ≈ `k`).
#[inline]
pub fn smooth_max(a: f64, b: f64, k: f64) -> f64 {
    -smooth_min(-a, -b, k)
}
