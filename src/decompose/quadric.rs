//! Symmetric quadrics `Q(x) = xᵀA x + 2 bᵀx + c` (the 4×4 symmetric matrix `[[A, b], [bᵀ, c]]`)
//! and their conversion to ellipsoids.
//!
//! In: the growth stages' quadrics. Out: [`Ellipsoid`]s (centre, proper rotation, semi-axes) and
//! axis-aligned bounds of `Q < 0`. `A` is stored as its six unique entries, so a quadric is
//! symmetric by construction (the pitfall of transforming a half-filled matrix cannot happen).

use glam::{DMat3, DQuat, DVec3};

use super::eigen::symmetric_eigen;
use crate::geometry::{Aabb, Ellipsoid};

/// A symmetric quadric `Q(x) = xᵀA x + 2 bᵀx + c`; `Q < 0` is the inside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quadric {
    /// `A` entries `[xx, yy, zz, xy, xz, yz]`.
    pub a: [f64; 6],
    /// Linear part `b` (half the gradient at the origin).
    pub b: DVec3,
    /// Constant `c = Q(0)`.
    pub c: f64,
}

impl Quadric {
    /// From a matrix `A` (its symmetric part is used), `b` and `c`.
    pub fn new(a: &DMat3, b: DVec3, c: f64) -> Quadric {
        let s = |i: usize, j: usize| 0.5 * (a.col(j)[i] + a.col(i)[j]);
        Quadric {
            a: [s(0, 0), s(1, 1), s(2, 2), s(0, 1), s(0, 2), s(1, 2)],
            b,
            c,
        }
    }

    /// The sphere `|x − centre|² − r²`.
    pub fn sphere(centre: DVec3, r: f64) -> Quadric {
        Quadric::new(&DMat3::IDENTITY, -centre, centre.length_squared() - r * r)
    }

    /// The product `−(u·x − du)(v·x − dv)` of two plane functions, negated (the wedge term).
    pub fn neg_plane_product(u: DVec3, du: f64, v: DVec3, dv: f64) -> Quadric {
        let outer = DMat3::from_cols(v * u.x, v * u.y, v * u.z);
        let sym = (outer + outer.transpose()) * -0.5;
        Quadric::new(&sym, 0.5 * (dv * u + du * v), -du * dv)
    }

    /// `A` as a full symmetric matrix.
    pub fn matrix(&self) -> DMat3 {
        let [xx, yy, zz, xy, xz, yz] = self.a;
        DMat3::from_cols(
            DVec3::new(xx, xy, xz),
            DVec3::new(xy, yy, yz),
            DVec3::new(xz, yz, zz),
        )
    }

    /// Value at `x`.
    #[inline]
    pub fn eval(&self, x: DVec3) -> f64 {
        let [xx, yy, zz, xy, xz, yz] = self.a;
        x.x * (xx * x.x + 2.0 * (xy * x.y + xz * x.z + self.b.x))
            + x.y * (yy * x.y + 2.0 * (yz * x.z + self.b.y))
            + x.z * (zz * x.z + 2.0 * self.b.z)
            + self.c
    }

    /// `self + t·other`.
    #[must_use]
    pub fn add_scaled(&self, t: f64, other: &Quadric) -> Quadric {
        let mut a = self.a;
        for (x, y) in a.iter_mut().zip(other.a) {
            *x += t * y;
        }
        Quadric {
            a,
            b: self.b + t * other.b,
            c: self.c + t * other.c,
        }
    }

    /// `x ↦ Q(P x)` with `P = I − m mᵀ`, the projection onto the plane through the origin
    /// with unit normal `m`: the cylinder over the plane's cut, axis `m`.
    #[must_use]
    pub fn projected_along(&self, m: DVec3) -> Quadric {
        let p = DMat3::IDENTITY - DMat3::from_cols(m * m.x, m * m.y, m * m.z);
        Quadric::new(&(p * self.matrix() * p), p * self.b, self.c)
    }

    /// Centre `o = −A⁻¹b` and depth `k = −Q(o)` when `A` is positive definite and `k > 0`
    /// (the quadric is a non-empty ellipsoid).
    pub fn centre_depth(&self) -> Option<(DVec3, f64, DMat3)> {
        let m = self.matrix();
        let [xx, yy, _, xy, _, _] = self.a;
        let det = m.determinant();
        // Sylvester's criterion: positive definite iff all leading minors are positive.
        if !(xx > 0.0 && xx * yy - xy * xy > 0.0 && det > 0.0) || !det.is_finite() {
            return None;
        }
        let inv = m.inverse();
        let o = -(inv * self.b);
        let k = -(self.c + self.b.dot(o));
        (k > 0.0 && k.is_finite() && o.is_finite()).then_some((o, k, inv))
    }

    /// Axis-aligned bounds of `Q < 0` when it is an ellipsoid.
    pub fn bounds(&self) -> Option<Aabb> {
        let (o, k, inv) = self.centre_depth()?;
        let half = DVec3::new(inv.x_axis.x, inv.y_axis.y, inv.z_axis.z) * k;
        if !half.cmpgt(DVec3::ZERO).all() {
            return None;
        }
        let half = half.map(f64::sqrt);
        Some(Aabb {
            min: o - half,
            max: o + half,
        })
    }

    /// The ellipsoid `Q < 0` (centre, proper rotation, semi-axes), or `None` when the quadric
    /// is not a non-degenerate ellipsoid.
    pub fn ellipsoid(&self) -> Option<Ellipsoid> {
        let (o, k, _) = self.centre_depth()?;
        let (values, vecs) = symmetric_eigen(&self.matrix());
        if !(values.z > 0.0) {
            return None;
        }
        let semi_axes = (DVec3::splat(k) / values).map(f64::sqrt);
        let rotation = DQuat::from_mat3(&vecs).normalize();
        (semi_axes.is_finite() && rotation.is_finite()).then_some(Ellipsoid {
            center: o,
            rotation,
            semi_axes,
        })
    }

    /// The quadric `ρ(x)² − 1` of an ellipsoid (inverse of [`Quadric::ellipsoid`] up to scale).
    pub fn from_ellipsoid(e: &Ellipsoid) -> Quadric {
        let r = DMat3::from_quat(e.rotation);
        let a = r * DMat3::from_diagonal(e.semi_axes.powf(-2.0)) * r.transpose();
        let b = -(a * e.center);
        Quadric::new(&a, b, e.center.dot(a * e.center) - 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_points() -> Vec<DVec3> {
        (0..500)
            .map(|i| {
                let f = i as f64;
                DVec3::new((f * 0.37).sin(), (f * 0.91).cos(), (f * 0.13).sin() * 1.7) * 3.0
            })
            .collect()
    }

    #[test]
    fn ellipsoid_round_trip() {
        let e = Ellipsoid {
            center: DVec3::new(0.5, -2.0, 1.0),
            rotation: DQuat::from_euler(glam::EulerRot::ZYX, 0.7, -0.4, 1.9),
            semi_axes: DVec3::new(0.4, 2.5, 1.1),
        };
        let q = Quadric::from_ellipsoid(&e).add_scaled(2.0, &Quadric::from_ellipsoid(&e)); // ×3
        let back = q.ellipsoid().unwrap();
        assert!((back.center - e.center).length() < 1e-12);
        for x in sample_points() {
            assert!((back.radius_squared(x) - e.radius_squared(x)).abs() < 1e-9);
            assert!((q.eval(x) - 3.0 * (e.radius_squared(x) - 1.0)).abs() < 1e-9);
        }
        let b = q.bounds().unwrap();
        let t = e.bounds();
        assert!((b.min - t.min).length() < 1e-12 && (b.max - t.max).length() < 1e-12);
        assert!(DMat3::from_quat(back.rotation).determinant() > 0.999_999);
    }

    #[test]
    fn wedge_and_projection_match_their_definitions() {
        let (u, v) = (DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.6, 0.0, -0.8));
        let w = Quadric::neg_plane_product(u, 0.3, v, -1.2);
        let m = DVec3::new(1.0, 2.0, -2.0) / 3.0;
        let s = Quadric::sphere(DVec3::new(0.1, 0.2, -0.7), 0.9).add_scaled(0.5, &w);
        let cyl = s.projected_along(m);
        for x in sample_points() {
            let expect = -(u.dot(x) - 0.3) * (v.dot(x) + 1.2);
            assert!((w.eval(x) - expect).abs() < 1e-12);
            let px = x - x.dot(m) * m;
            assert!((cyl.eval(x) - s.eval(px)).abs() < 1e-10);
            assert!((cyl.eval(x + 2.5 * m) - cyl.eval(x)).abs() < 1e-10);
        }
    }
}
