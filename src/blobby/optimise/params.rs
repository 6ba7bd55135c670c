//! One blob in optimisation coordinates, and its field with the analytic Jacobian.

use glam::{DMat3, DQuat, DVec3};

use crate::blobby::Blob;

/// One blob in optimisation coordinates.
#[derive(Clone, Copy, Debug)]
pub(super) struct Params {
    pub(super) c: DVec3,
    pub(super) q: DQuat,
    pub(super) log_r: DVec3,
    pub(super) log_b: f64,
}

impl Params {
    pub(super) fn from_blob(b: &Blob) -> Params {
        let r = b.semi_axes * (1.0 + b.a).sqrt();
        Params {
            c: b.center,
            q: b.rotation,
            log_r: DVec3::new(r.x.ln(), r.y.ln(), r.z.ln()),
            log_b: b.b.abs().max(1e-12).ln(),
        }
    }

    pub(super) fn to_blob(self, a: f64) -> Blob {
        let r = DVec3::new(self.log_r.x.exp(), self.log_r.y.exp(), self.log_r.z.exp());
        Blob {
            center: self.c,
            rotation: self.q.normalize(),
            semi_axes: r / (1.0 + a).sqrt(),
            a,
            b: self.log_b.exp(),
        }
    }

    /// Apply a step `[dc (3, in units of `scale`), ω (3), d log r (3), d log B]`, keeping the
    /// influence radii within `[1e-3, 0.5]·scale`, their ratio within 8 and `B` within
    /// `[1e-3, 50]` (beyond these a blob is a needle or a spike that no sample constrains).
    pub(super) fn stepped(self, d: &[f64; 10], scale: f64) -> Params {
        let w = DVec3::new(d[3], d[4], d[5]);
        let lo = (1e-3 * scale).ln();
        let hi = (0.5 * scale).ln();
        let mut log_r =
            (self.log_r + DVec3::new(d[6], d[7], d[8])).clamp(DVec3::splat(lo), DVec3::splat(hi));
        let max_ratio = 8f64.ln();
        log_r = log_r.max(DVec3::splat(log_r.max_element() - max_ratio));
        Params {
            c: self.c + DVec3::new(d[0], d[1], d[2]) * scale,
            q: (self.q * DQuat::from_scaled_axis(w)).normalize(),
            log_r,
            log_b: (self.log_b + d[9]).clamp(1e-3f64.ln(), 50f64.ln()),
        }
    }
}

/// A blob's field prepared for evaluation: `y = Rᵀ(x−c)`, `u = Σ (y_k/r_k)²`.
pub(super) struct Eval {
    pub(super) c: DVec3,
    pub(super) rt: DMat3,
    inv_r2: DVec3,
    b2: f64,
}

impl Eval {
    pub(super) fn new(p: &Params) -> Eval {
        let r = DVec3::new(p.log_r.x.exp(), p.log_r.y.exp(), p.log_r.z.exp());
        Eval {
            c: p.c,
            rt: DMat3::from_quat(p.q).transpose(),
            inv_r2: DVec3::ONE / (r * r),
            b2: (2.0 * p.log_b).exp(),
        }
    }

    #[inline]
    pub(super) fn value(&self, x: DVec3) -> f64 {
        let y = self.rt * (x - self.c);
        let u = (y * y * self.inv_r2).element_sum();
        if u < 1.0 {
            self.b2 * (1.0 - u) * (1.0 - u)
        } else {
            0.0
        }
    }

    /// `f` and `∂f/∂θ` for `θ = [c/scale, ω, log r, log B]`.
    #[inline]
    pub(super) fn value_and_jacobian(&self, x: DVec3, scale: f64) -> (f64, [f64; 10]) {
        let y = self.rt * (x - self.c);
        let v = y * self.inv_r2;
        let u = (y * v).element_sum();
        if u >= 1.0 {
            return (0.0, [0.0; 10]);
        }
        let k = 1.0 - u;
        let f = self.b2 * k * k;
        let df_du = -2.0 * self.b2 * k;
        // ∂u/∂c = −2 R v; ∂u/∂ω = 2 (v × y); ∂u/∂log r_k = −2 y_k v_k.
        let du_dc = self.rt.transpose() * v * (-2.0 * scale);
        let du_dw = v.cross(y) * 2.0;
        let du_dlr = y * v * -2.0;
        let j = [
            df_du * du_dc.x,
            df_du * du_dc.y,
            df_du * du_dc.z,
            df_du * du_dw.x,
            df_du * du_dw.y,
            df_du * du_dw.z,
            df_du * du_dlr.x,
            df_du * du_dlr.y,
            df_du * du_dlr.z,
            2.0 * f,
        ];
        (f, j)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    pub(super) fn jacobian_matches_finite_differences() {
        let p = Params {
            c: DVec3::new(0.1, -0.2, 0.3),
            q: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.5, 1.0),
            log_r: DVec3::new(0.2, -0.1, 0.05),
            log_b: 0.4,
        };
        let x = DVec3::new(0.5, 0.1, 0.2);
        let scale = 4.0;
        let (_, j) = Eval::new(&p).value_and_jacobian(x, scale);
        for a in 0..10 {
            let h = 1e-6;
            let mut d = [0.0; 10];
            d[a] = h;
            let fp = Eval::new(&p.stepped(&d, scale)).value(x);
            d[a] = -h;
            let fm = Eval::new(&p.stepped(&d, scale)).value(x);
            let fd = (fp - fm) / (2.0 * h);
            assert!(
                (fd - j[a]).abs() < 1e-5 * (1.0 + fd.abs()),
                "param {a}: analytic {} vs fd {fd}",
                j[a]
            );
        }
    }

    #[test]
    pub(super) fn blob_params_round_trip() {
        let b = Blob {
            center: DVec3::new(1.0, 2.0, 3.0),
            rotation: DQuat::from_rotation_y(0.7),
            semi_axes: DVec3::new(0.5, 0.25, 1.5),
            a: 1.3,
            b: 2.2,
        };
        let back = Params::from_blob(&b).to_blob(b.a);
        assert!((back.semi_axes - b.semi_axes).length() < 1e-12 && (back.b - b.b).abs() < 1e-12);
    }
}
