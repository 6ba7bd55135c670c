//! `builtin:torus-knot`: a circular tube swept along a (2,3) torus knot (the trefoil).
//!
//! Centre line `c(t) = ((R + cos 3t) cos 2t, (R + cos 3t) sin 2t, sin 3t) · SCALE`, `R = 2`,
//! in the XY plane (facing a camera on +Z). The tube's frame is rotation-minimising (double
//! reflection, Wang et al. 2008) with its closing twist spread evenly along the curve, so the
//! tube joins itself without a seam.

use std::f64::consts::TAU;

use glam::DVec3;

use crate::mesh::Mesh;

/// Major radius of the knot's torus before scaling.
const MAJOR: f64 = 2.0;
/// Scale to about 2 units across (the knot reaches `(MAJOR + 1) · SCALE = 1` from the axis).
const SCALE: f64 = 1.0 / 3.0;
/// Tube radius after scaling. Distinct strands stay ≥ 0.55 apart and the centre line's radius
/// of curvature exceeds 0.3, so the tube never touches itself.
const TUBE_RADIUS: f64 = 0.13;
/// Rings along the curve.
const RINGS: usize = 384;
/// Vertices around each ring.
const SIDES: usize = 20;

fn centre(t: f64) -> DVec3 {
    let r = MAJOR + (3.0 * t).cos();
    DVec3::new(r * (2.0 * t).cos(), r * (2.0 * t).sin(), (3.0 * t).sin()) * SCALE
}

/// Unit tangent, by the analytic derivative.
fn tangent(t: f64) -> DVec3 {
    let r = MAJOR + (3.0 * t).cos();
    let dr = -3.0 * (3.0 * t).sin();
    DVec3::new(
        dr * (2.0 * t).cos() - 2.0 * r * (2.0 * t).sin(),
        dr * (2.0 * t).sin() + 2.0 * r * (2.0 * t).cos(),
        3.0 * (3.0 * t).cos(),
    )
    .normalize()
}

/// The closed knot tube: `RINGS · SIDES` vertices, `2 · RINGS · SIDES` outward triangles.
pub fn torus_knot() -> Mesh {
    let ts: Vec<f64> = (0..=RINGS).map(|i| TAU * i as f64 / RINGS as f64).collect();
    let points: Vec<DVec3> = ts.iter().map(|&t| centre(t)).collect();
    let tangents: Vec<DVec3> = ts.iter().map(|&t| tangent(t)).collect();
    // Rotation-minimising normals by double reflection.
    let mut normals = vec![tangents[0].any_orthonormal_vector(); RINGS + 1];
    for i in 0..RINGS {
        let v1 = points[i + 1] - points[i];
        let c1 = v1.length_squared();
        let r_l = normals[i] - (2.0 / c1) * v1.dot(normals[i]) * v1;
        let t_l = tangents[i] - (2.0 / c1) * v1.dot(tangents[i]) * v1;
        let v2 = tangents[i + 1] - t_l;
        let c2 = v2.length_squared();
        let n = if c2 > 0.0 {
            r_l - (2.0 / c2) * v2.dot(r_l) * v2
        } else {
            r_l
        };
        // Re-orthonormalise against drift.
        normals[i + 1] = (n - tangents[i + 1] * n.dot(tangents[i + 1])).normalize();
    }
    // Closing twist: angle from the transported end normal back to the start normal.
    let t0 = tangents[0];
    let (n0, b0) = (normals[0], t0.cross(normals[0]));
    let end = normals[RINGS];
    let twist = end.dot(b0).atan2(end.dot(n0));
    let mut positions = Vec::with_capacity(RINGS * SIDES);
    for i in 0..RINGS {
        let (t, n) = (tangents[i], normals[i]);
        let b = t.cross(n);
        let base = -twist * i as f64 / RINGS as f64;
        for j in 0..SIDES {
            let phi = base + TAU * j as f64 / SIDES as f64;
            positions.push(points[i] + TUBE_RADIUS * (phi.cos() * n + phi.sin() * b));
        }
    }
    let id = |i: usize, j: usize| ((i % RINGS) * SIDES + j % SIDES) as u32;
    let mut triangles = Vec::with_capacity(2 * RINGS * SIDES);
    for i in 0..RINGS {
        for j in 0..SIDES {
            // The ring runs counter-clockwise about the tangent, so (along ring, along curve)
            // winds outward.
            let (a, b, c, d) = (id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh {
        positions,
        triangles,
    }
}
