//! The toy figures `duck` and `bunny-toy`: smooth unions of ellipsoids, polygonized.
//!
//! Both face +X with +Y up and sit on a flat base. The polygonizer resolution is chosen for
//! about 15–25k triangles.

use std::f64::consts::PI;

use glam::{DQuat, DVec3};

use super::decimate::decimate;
use super::sdf::{Part, smooth_max, smooth_min};
use crate::geometry::Aabb;
use crate::mesh::Mesh;
use crate::mesh::marching_cubes::marching_cubes;

/// Grid cells along the longest side when polygonizing a figure.
const RESOLUTION: usize = 64;

/// Triangle budget after decimation.
const TRIANGLES: usize = 20_000;

/// Largest decimation error, as a fraction of the figure's extent.
const MAX_ERROR: f32 = 2e-3;

/// Polygonize the solid `distance < 0` inside `bounds`, then decimate to the budget.
fn solid(bounds: Aabb, distance: impl Fn(DVec3) -> f64 + Sync) -> Mesh {
    let dense = marching_cubes(&bounds, RESOLUTION, |p| -distance(p));
    decimate(&dense, TRIANGLES, MAX_ERROR)
}

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// A yellow rubber duck: round body, raised tail, head on a short neck, flat wide beak, eye
/// bumps, flat base. About 2.0 × 1.4 × 1.2 units.
pub fn duck() -> Mesh {
    let body = Part::ellipsoid(v(-0.05, -0.15, 0.0), v(0.82, 0.47, 0.58));
    let tail = Part::rotated(
        v(-0.72, 0.06, 0.0),
        v(0.28, 0.12, 0.2),
        DQuat::from_rotation_z(0.6),
    );
    let head = Part::sphere(v(0.42, 0.52, 0.0), 0.34);
    let cheeks = Part::ellipsoid(v(0.46, 0.44, 0.0), v(0.3, 0.26, 0.34));
    let beak = Part::rotated(
        v(0.8, 0.44, 0.0),
        v(0.22, 0.065, 0.17),
        DQuat::from_rotation_z(-0.12),
    );
    let eyes = [
        Part::sphere(v(0.64, 0.64, 0.17), 0.055),
        Part::sphere(v(0.64, 0.64, -0.17), 0.055),
    ];
    let base = -0.5;
    let distance = move |p: DVec3| {
        let mut d = smooth_min(body.distance(p), tail.distance(p), 0.12);
        d = smooth_min(d, head.distance(p), 0.14);
        d = smooth_min(d, cheeks.distance(p), 0.05);
        d = smooth_min(d, beak.distance(p), 0.04);
        for eye in &eyes {
            d = smooth_min(d, eye.distance(p), 0.015);
        }
        // Flat base: keep y > base.
        smooth_max(d, base - p.y, 0.05)
    };
    solid(
        Aabb {
            min: v(-1.05, -0.55, -0.65),
            max: v(1.05, 0.9, 0.65),
        },
        distance,
    )
}

/// A sitting toy rabbit: pear-shaped body, round head, two long upright ears leaning back,
/// round tail, front and hind feet. About 1.5 × 2.0 × 1.0 units.
pub fn bunny_toy() -> Mesh {
    let body = Part::ellipsoid(v(-0.1, -0.35, 0.0), v(0.5, 0.45, 0.42));
    let chest = Part::ellipsoid(v(0.12, -0.15, 0.0), v(0.3, 0.33, 0.3));
    let head = Part::ellipsoid(v(0.28, 0.28, 0.0), v(0.3, 0.27, 0.27));
    let muzzle = Part::sphere(v(0.5, 0.22, 0.0), 0.13);
    let ear = |side: f64| {
        let lean = DQuat::from_rotation_z(0.25) * DQuat::from_rotation_x(side * 0.18);
        Part::rotated(
            v(0.16, 0.78, side * 0.12) + lean * v(0.0, 0.0, 0.0),
            v(0.08, 0.36, 0.05),
            lean,
        )
    };
    let ears = [ear(1.0), ear(-1.0)];
    let tail = Part::sphere(v(-0.6, -0.3, 0.0), 0.12);
    let hind = [
        Part::ellipsoid(v(-0.12, -0.7, 0.28), v(0.28, 0.1, 0.12)),
        Part::ellipsoid(v(-0.12, -0.7, -0.28), v(0.28, 0.1, 0.12)),
    ];
    let front = [
        Part::ellipsoid(v(0.36, -0.68, 0.15), v(0.12, 0.09, 0.07)),
        Part::ellipsoid(v(0.36, -0.68, -0.15), v(0.12, 0.09, 0.07)),
    ];
    let base = -0.76;
    let distance = move |p: DVec3| {
        let mut d = smooth_min(body.distance(p), chest.distance(p), 0.1);
        d = smooth_min(d, head.distance(p), 0.1);
        d = smooth_min(d, muzzle.distance(p), 0.05);
        for ear in &ears {
            d = smooth_min(d, ear.distance(p), 0.06);
        }
        d = smooth_min(d, tail.distance(p), 0.05);
        for foot in hind.iter().chain(&front) {
            d = smooth_min(d, foot.distance(p), 0.06);
        }
        smooth_max(d, base - p.y, 0.03)
    };
    let _ = PI;
    solid(
        Aabb {
            min: v(-0.8, -0.8, -0.5),
            max: v(0.7, 1.25, 0.5),
        },
        distance,
    )
}
