//! Small geometric value types shared by every stage: axis-aligned boxes and ellipsoids.
//!
//! All lengths are in the input mesh's own units (f64); tolerances elsewhere are relative to
//! [`Aabb::diagonal`] of the input mesh.

use glam::{DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

/// Axis-aligned bounding box. An empty box has `min > max` (see [`Aabb::EMPTY`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Aabb {
    /// Smallest corner.
    pub min: DVec3,
    /// Largest corner.
    pub max: DVec3,
}

impl Aabb {
    /// The empty box: growing it by a point gives that point.
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// Box around a set of points ([`Aabb::EMPTY`] for none).
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a DVec3>) -> Aabb {
        points.into_iter().fold(Aabb::EMPTY, |b, p| b.grown(*p))
    }

    /// This box grown to contain `p`.
    #[must_use]
    pub fn grown(self, p: DVec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// Smallest box containing both.
    #[must_use]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// True when the box contains no point.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// Edge lengths (zero for an empty box).
    pub fn size(&self) -> DVec3 {
        if self.is_empty() {
            DVec3::ZERO
        } else {
            self.max - self.min
        }
    }

    /// The eight corners (bit 0 picks x, bit 1 y, bit 2 z from `max`).
    pub fn corners(&self) -> [DVec3; 8] {
        std::array::from_fn(|i| {
            let pick = |bit: usize, lo: f64, hi: f64| if i & bit == 0 { lo } else { hi };
            DVec3::new(
                pick(1, self.min.x, self.max.x),
                pick(2, self.min.y, self.max.y),
                pick(4, self.min.z, self.max.z),
            )
        })
    }

    /// Centre point.
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }

    /// Length of the diagonal, the project's unit for every relative tolerance.
    pub fn diagonal(&self) -> f64 {
        self.size().length()
    }

    /// True when `p` lies inside or on the box.
    pub fn contains(&self, p: DVec3) -> bool {
        p.cmpge(self.min).all() && p.cmple(self.max).all()
    }

    /// True when the two boxes share at least one point.
    pub fn overlaps(&self, o: &Aabb) -> bool {
        self.min.cmple(o.max).all() && o.min.cmple(self.max).all()
    }

    /// Box grown by `margin` on every side.
    #[must_use]
    pub fn expanded(self, margin: f64) -> Aabb {
        Aabb {
            min: self.min - DVec3::splat(margin),
            max: self.max + DVec3::splat(margin),
        }
    }
}

/// A solid ellipsoid: `|diag(1/semi_axes) · Rᵀ (x − center)| ≤ 1`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ellipsoid {
    /// Centre.
    pub center: DVec3,
    /// Rotation from the ellipsoid's local frame (axes = columns) to the world.
    pub rotation: DQuat,
    /// Semi-axis lengths along the local x, y, z axes (all > 0).
    pub semi_axes: DVec3,
}

impl Ellipsoid {
    /// Squared ellipsoidal radius `ρ(x)²` (1 on the surface, < 1 inside).
    pub fn radius_squared(&self, x: DVec3) -> f64 {
        let local = self.rotation.inverse() * (x - self.center);
        (local / self.semi_axes).length_squared()
    }

    /// True when `x` is strictly inside.
    pub fn contains(&self, x: DVec3) -> bool {
        self.radius_squared(x) < 1.0
    }

    /// Volume `4/3 π abc`.
    pub fn volume(&self) -> f64 {
        4.0 / 3.0 * std::f64::consts::PI * self.semi_axes.x * self.semi_axes.y * self.semi_axes.z
    }

    /// Tight axis-aligned bounds of the ellipsoid scaled by `scale` about its centre.
    pub fn bounds_scaled(&self, scale: f64) -> Aabb {
        let m = DMat3::from_quat(self.rotation);
        // Half-extent along world axis i is |row_i(R · diag(s))|.
        let rs = DMat3::from_cols(
            m.x_axis * self.semi_axes.x,
            m.y_axis * self.semi_axes.y,
            m.z_axis * self.semi_axes.z,
        );
        let t = rs.transpose();
        let half = DVec3::new(t.x_axis.length(), t.y_axis.length(), t.z_axis.length()) * scale;
        Aabb {
            min: self.center - half,
            max: self.center + half,
        }
    }

    /// Tight axis-aligned bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds_scaled(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotated_ellipsoid_bounds_are_tight() {
        let e = Ellipsoid {
            center: DVec3::new(1.0, 2.0, 3.0),
            rotation: DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
            semi_axes: DVec3::new(3.0, 1.0, 0.5),
        };
        let b = e.bounds();
        assert!((b.size() - DVec3::new(2.0, 6.0, 1.0)).length() < 1e-12);
        assert!(e.contains(DVec3::new(1.0, 4.9, 3.0)));
        assert!(!e.contains(DVec3::new(2.1, 2.0, 3.0)));
    }
}
