//! Shapes shared by the evaluation, codec and benchmark tests: an icosphere mesh and a blob
//! model built in code.
// Each test crate includes this module and uses only some of it.
#![allow(dead_code)]

use glam::{DQuat, DVec3};
use nephele::blobby::model_file::MODEL_VERSION;
use nephele::blobby::{Blob, BlobField, BlobModel, SourceInfo, THRESHOLD};
use nephele::decompose::Primitive;
use nephele::mesh::Mesh;

/// Icosphere of radius `r` about `c`, subdivided `levels` times (vertices projected).
pub fn icosphere(levels: usize, r: f64, c: DVec3) -> Mesh {
    let mut m = nephele::mesh::builtin::icosphere(levels as u32);
    for p in &mut m.positions {
        *p = *p * r + c;
    }
    m
}

/// A few dozen overlapping blobs along a bent tube, varied sizes, rotations, A and B.
pub fn model(n: usize, sphere: bool) -> BlobModel {
    let blobs: Vec<Blob> = (0..n)
        .map(|i| {
            let t = i as f64 / n as f64 * 5.0;
            let center = DVec3::new(t.cos() * 2.0, t * 0.3, t.sin() * 1.5) * 7.0 + 3.0;
            let rotation = DQuat::from_euler(glam::EulerRot::ZXY, t * 1.7, 0.3 + t, -t * 2.3);
            let semi_axes = if sphere {
                DVec3::splat(1.2 + 0.4 * (t * 3.0).sin())
            } else {
                DVec3::new(2.5 + (t * 2.0).sin(), 1.0 + 0.3 * t.cos(), 0.6 + 0.1 * t)
            };
            let a = 0.4 + 0.3 * (i % 7) as f64;
            Blob {
                center,
                rotation,
                semi_axes,
                a,
                b: (1.0 + a) / a * (0.7 + 0.05 * (i % 5) as f64),
            }
        })
        .collect();
    let field = BlobField::new(&blobs, THRESHOLD);
    BlobModel {
        version: MODEL_VERSION,
        primitive: if sphere {
            Primitive::Sphere
        } else {
            Primitive::Ellipsoid
        },
        threshold: THRESHOLD,
        source: SourceInfo {
            mesh: "builtin:tube-ünïcode".into(),
            bounds: field.bounds(),
            vertices: 12345,
            faces: 24686,
        },
        seed: 0xDEAD_BEEF_1234,
        blobs,
    }
}
