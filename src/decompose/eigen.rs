//! Symmetric 3×3 eigen-decomposition by cyclic Jacobi rotations.
//!
//! In: a symmetric [`DMat3`]. Out: eigenvalues and an orthonormal, right-handed eigenvector
//! basis (a proper rotation), so that `M = V · diag(λ) · Vᵀ`.

use glam::{DMat3, DVec3};

/// Eigenvalues `λ` and eigenvectors (columns of `V`, `det V = +1`) of a symmetric matrix,
/// sorted by decreasing eigenvalue. Only the upper triangle of `m` is read, so an almost
/// symmetric input is treated as its upper-triangle symmetrisation.
pub fn symmetric_eigen(m: &DMat3) -> (DVec3, DMat3) {
    // a[i][j] row-major working copy, symmetric from the upper triangle.
    let mut a = [[0.0f64; 3]; 3];
    for (i, row) in a.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let (r, c) = if i <= j { (i, j) } else { (j, i) };
            *v = m.col(c)[r];
        }
    }
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..50 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let scale = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if off <= 1e-30 * scale || off == 0.0 {
            break;
        }
        for (p, q) in [(0usize, 1usize), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            // Rotation that annihilates a[p][q] (Numerical Recipes' stable form).
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in a.iter_mut() {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
            for k in 0..3 {
                let (x, y) = (a[p][k], a[q][k]);
                a[p][k] = c * x - s * y;
                a[q][k] = s * x + c * y;
            }
            for row in v.iter_mut() {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| a[j][j].total_cmp(&a[i][i]));
    let col = |k: usize| DVec3::new(v[0][k], v[1][k], v[2][k]);
    let values = DVec3::new(
        a[order[0]][order[0]],
        a[order[1]][order[1]],
        a[order[2]][order[2]],
    );
    let (x, y) = (col(order[0]), col(order[1]));
    // Third axis from the cross product: orthonormal and right-handed by construction.
    let z = x.cross(y);
    (values, DMat3::from_cols(x, y, z))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn reconstruct(values: DVec3, vecs: DMat3) -> DMat3 {
        vecs * DMat3::from_diagonal(values) * vecs.transpose()
    }

    #[test]
    fn reconstructs_random_symmetric_matrices() {
        let mut s = 12345u64;
        let mut next = || {
            s = crate::rng::mix64(s);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..200 {
            let (a, b, c, d, e, f) = (next(), next(), next(), next(), next(), next());
            let m = DMat3::from_cols(
                DVec3::new(a, b, c),
                DVec3::new(b, d, e),
                DVec3::new(c, e, f),
            );
            let (values, vecs) = symmetric_eigen(&m);
            assert!((vecs.determinant() - 1.0).abs() < 1e-12);
            assert!(values.x >= values.y && values.y >= values.z);
            let r = reconstruct(values, vecs);
            for k in 0..3 {
                assert!((r.col(k) - m.col(k)).length() < 1e-12, "{m:?} vs {r:?}");
            }
        }
    }

    #[test]
    fn recovers_known_rotation_and_repeated_values() {
        let q = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0);
        let r = DMat3::from_quat(q);
        let m = r * DMat3::from_diagonal(DVec3::new(5.0, 2.0, 2.0)) * r.transpose();
        let (values, vecs) = symmetric_eigen(&m);
        assert!((values - DVec3::new(5.0, 2.0, 2.0)).length() < 1e-12);
        assert!(vecs.x_axis.dot(r.x_axis).abs() > 1.0 - 1e-12);
        let diag = symmetric_eigen(&DMat3::from_diagonal(DVec3::new(1.0, 3.0, 2.0)));
        assert_eq!(diag.0, DVec3::new(3.0, 2.0, 1.0));
    }
}
