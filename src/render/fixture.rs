//! The renderer tests' cloud, the settings that frame it and a timer, in one file for the two test
//! binaries that measure it: the benchmark (a unit test, `src/render/bench.rs`, which needs the
//! renderer's internals) and the integration tests (`tests/it/render.rs`, which include this
//! file by path; its seeded hash is pinned on this very cloud). The names come from the
//! including module (`super`), since the library calls itself `crate` and the tests `nephele`.

use glam::{DQuat, DVec3, Vec3};
use rand::{RngExt, SeedableRng};

use super::{Blob, Camera, CloudMaterial, Quality, RenderSettings, Sky, Sun};

/// A blobby cloud about 2 units across: `n` ellipsoids (A = 1, B = (1+A)/A) in a body, a head
/// and a tail, with random sizes and orientations.
pub(crate) fn test_cloud(n: usize, seed: u64) -> Vec<Blob> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let lobes = [
        (DVec3::new(0.0, 0.0, 0.0), 0.75),
        (DVec3::new(0.65, 0.45, 0.1), 0.42),
        (DVec3::new(-0.7, 0.2, -0.1), 0.3),
    ];
    (0..n)
        .map(|i| {
            let (c, r) = lobes[[0, 0, 0, 1, 1, 2][i % 6]];
            let p = loop {
                let p = DVec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                if p.length() < 1.0 {
                    break p;
                }
            };
            let d = p.length();
            // Smaller blobs near the lobe's surface, bigger inside.
            let size = r * (0.45 - 0.25 * d);
            let axes = DVec3::new(
                size * rng.random_range(0.7..1.3),
                size * rng.random_range(0.5..1.0),
                size * rng.random_range(0.7..1.2),
            );
            let a = 1.0;
            Blob {
                center: c + p * (r * 0.8),
                rotation: DQuat::from_euler(
                    glam::EulerRot::XYZ,
                    rng.random_range(0.0..6.3),
                    rng.random_range(0.0..6.3),
                    rng.random_range(0.0..6.3),
                ),
                semi_axes: axes,
                a,
                b: (1.0 + a) / a,
            }
        })
        .collect()
}

/// The settings the renderer tests frame [`test_cloud`] with: `width × height`, `quality`, the
/// default sun, sky and cloud, seed 7.
pub(crate) fn settings(width: u32, height: u32, quality: Quality) -> RenderSettings {
    RenderSettings {
        width,
        height,
        camera: Camera {
            position: Vec3::new(0.3, 0.6, 4.2),
            look_at: Vec3::new(0.0, 0.1, 0.0),
            up: Vec3::Y,
            fov_deg: 38.0,
            shift: glam::Vec2::ZERO,
        },
        sun: Sun::default(),
        sky: Sky::default(),
        cloud: CloudMaterial::default(),
        exposure: 0.0,
        length_scale: 3.5,
        seed: 7,
        time: 0.0,
        quality,
        base: None,
        surfaces: None,
    }
}

/// `f`'s result and the wall-clock seconds it took.
pub(crate) fn time<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let t = std::time::Instant::now();
    let out = f();
    (out, t.elapsed().as_secs_f64())
}
