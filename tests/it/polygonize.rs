//! Marching cubes and blob polygonization: closed, outward, accurate, deterministic.

use crate::mesh_checks;

use std::f64::consts::PI;
use std::time::Instant;

use glam::{DQuat, DVec3, EulerRot};
use mesh_checks::{assert_closed_oriented, components, euler_characteristic, min_relative_area};
use nephele::blobby::polygonize::polygonize;
use nephele::blobby::{Blob, BlobField};
use nephele::geometry::{Aabb, Ellipsoid};
use nephele::mesh::Mesh;
use nephele::mesh::marching_cubes::marching_cubes;

fn sphere_blob(center: DVec3, r: f64) -> Blob {
    Blob::from_ellipsoid(
        &Ellipsoid {
            center,
            rotation: DQuat::IDENTITY,
            semi_axes: DVec3::splat(r),
        },
        1.0,
    )
}

/// Grid spacing `polygonize` uses for `field` at `resolution`.
fn cell_of(field: &BlobField, resolution: usize) -> f64 {
    let b = field.bounds();
    b.expanded(0.01 * b.diagonal()).size().max_element() / resolution as f64
}

#[test]
fn single_blob_matches_its_ellipsoid() {
    let e = Ellipsoid {
        center: DVec3::new(0.4, -1.0, 2.5),
        rotation: DQuat::from_euler(EulerRot::XYZ, 0.3, 1.1, -0.4),
        semi_axes: DVec3::new(1.2, 0.7, 0.45),
    };
    let field = BlobField::new(&[Blob::from_ellipsoid(&e, 0.8)], 1.0);
    let resolution = 60;
    let mesh = polygonize(&field, resolution);
    assert_closed_oriented(&mesh, "single blob");
    assert_eq!(euler_characteristic(&mesh), 2);
    let cell = cell_of(&field, resolution);
    let min_axis = e.semi_axes.min_element();
    let worst = mesh
        .positions
        .iter()
        .map(|&p| (e.radius_squared(p).sqrt() - 1.0).abs() * min_axis)
        .fold(0.0, f64::max);
    // Vertices sit on grid edges where the field is exact: far better than one cell.
    assert!(
        worst < 0.1 * cell,
        "ellipsoidal radius off by {worst} (cell {cell})"
    );
    let rel = (mesh.signed_volume() - e.volume()).abs() / e.volume();
    assert!(
        rel < 0.02,
        "volume {} vs {} ({rel})",
        mesh.signed_volume(),
        e.volume()
    );
    mesh.validate(std::path::Path::new("single")).unwrap();
    assert!(min_relative_area(&mesh) > 0.0);
}

#[test]
fn two_overlapping_blobs_form_one_closed_surface() {
    let blobs = [
        sphere_blob(DVec3::ZERO, 1.0),
        sphere_blob(DVec3::new(1.3, 0.2, 0.0), 0.8),
    ];
    let field = BlobField::new(&blobs, 1.0);
    let mesh = polygonize(&field, 70);
    assert_closed_oriented(&mesh, "two blobs");
    assert_eq!(components(&mesh), 1);
    assert_eq!(euler_characteristic(&mesh), 2);
    // Blending only adds volume to the union of the two balls.
    let union_lower = 4.0 / 3.0 * PI * 1.0;
    assert!(
        mesh.signed_volume() > union_lower,
        "{}",
        mesh.signed_volume()
    );
}

#[test]
fn separate_components_are_each_closed() {
    let blobs = [
        sphere_blob(DVec3::ZERO, 0.5),
        sphere_blob(DVec3::new(3.0, 0.0, 0.0), 0.4),
        sphere_blob(DVec3::new(0.0, 2.5, 1.0), 0.6),
    ];
    let field = BlobField::new(&blobs, 1.0);
    let mesh = polygonize(&field, 90);
    assert_closed_oriented(&mesh, "three blobs");
    assert_eq!(components(&mesh), 3);
    assert_eq!(euler_characteristic(&mesh), 6);
    let expect: f64 = [0.5f64, 0.4, 0.6]
        .iter()
        .map(|r| 4.0 / 3.0 * PI * r.powi(3))
        .sum();
    let rel = (mesh.signed_volume() - expect).abs() / expect;
    assert!(rel < 0.05, "volume {} vs {expect}", mesh.signed_volume());
}

#[test]
fn ring_of_blobs_is_a_torus() {
    let blobs: Vec<Blob> = (0..16)
        .map(|i| {
            let a = i as f64 / 16.0 * 2.0 * PI;
            sphere_blob(DVec3::new(a.cos(), 0.2 * a.sin(), a.sin()) * 1.5, 0.35)
        })
        .collect();
    let field = BlobField::new(&blobs, 1.0);
    let mesh = polygonize(&field, 80);
    assert_closed_oriented(&mesh, "ring");
    assert_eq!(components(&mesh), 1);
    assert_eq!(euler_characteristic(&mesh), 0, "genus 1 expected");
}

#[test]
fn analytic_torus_field() {
    let (big, small) = (1.0, 0.3);
    let f = |p: DVec3| {
        let q = DVec3::new((p.x * p.x + p.z * p.z).sqrt() - big, p.y, 0.0);
        small - q.length()
    };
    let b = Aabb {
        min: DVec3::new(-1.3, -0.3, -1.3),
        max: DVec3::new(1.3, 0.3, 1.3),
    };
    let mesh = marching_cubes(&b, 100, f);
    assert_closed_oriented(&mesh, "torus");
    assert_eq!(euler_characteristic(&mesh), 0);
    let expect = 2.0 * PI * PI * big * small * small;
    let rel = (mesh.signed_volume() - expect).abs() / expect;
    assert!(
        rel < 0.02,
        "torus volume {} vs {expect}",
        mesh.signed_volume()
    );
}

#[test]
fn field_touching_or_crossing_the_bounds_stays_closed() {
    let sphere = |p: DVec3| 1.0 - p.length();
    // The sphere exactly fills the box: the padding cell keeps it whole.
    let fits = marching_cubes(
        &Aabb {
            min: DVec3::splat(-1.0),
            max: DVec3::ONE,
        },
        40,
        sphere,
    );
    assert_closed_oriented(&fits, "sphere in its box");
    let rel = (fits.signed_volume() - 4.0 / 3.0 * PI).abs() / (4.0 / 3.0 * PI);
    assert!(rel < 0.02, "sphere volume {}", fits.signed_volume());
    // The field is still positive on the grid's border: the surface is clipped, yet closed.
    let half = Aabb {
        min: DVec3::splat(-0.5),
        max: DVec3::splat(0.5),
    };
    let clipped = marching_cubes(&half, 20, sphere);
    assert_closed_oriented(&clipped, "clipped sphere");
    assert_eq!(euler_characteristic(&clipped), 2);
    // A field positive everywhere becomes the padded box itself.
    let everywhere = marching_cubes(&half, 5, |_| 1.0);
    assert_closed_oriented(&everywhere, "everywhere inside");
}

#[test]
fn empty_inputs_give_empty_meshes() {
    let none = marching_cubes(&Aabb::EMPTY, 10, |_| 1.0);
    assert!(none.triangles.is_empty());
    let outside = marching_cubes(
        &Aabb {
            min: DVec3::ZERO,
            max: DVec3::ONE,
        },
        10,
        |_| -1.0,
    );
    assert_eq!(outside, Mesh::default());
    let nan = marching_cubes(
        &Aabb {
            min: DVec3::ZERO,
            max: DVec3::ONE,
        },
        10,
        |_| f64::NAN,
    );
    assert!(nan.triangles.is_empty());
    let dead = BlobField::new(
        &[Blob {
            b: 0.0,
            ..sphere_blob(DVec3::ZERO, 1.0)
        }],
        1.0,
    );
    assert!(polygonize(&dead, 50).triangles.is_empty());
}

/// A deterministic pseudo-random model of `n` overlapping ellipsoidal blobs.
fn many_blobs(n: usize) -> Vec<Blob> {
    (0..n)
        .map(|i| {
            let t = i as f64;
            let e = Ellipsoid {
                center: DVec3::new(
                    (t * 0.71).sin(),
                    (t * 1.37).cos() * 0.8,
                    (t * 0.23).sin() * 0.6,
                ),
                rotation: DQuat::from_euler(EulerRot::XYZ, t, 2.0 * t, 0.5 * t),
                semi_axes: DVec3::new(0.12 + 0.03 * (t * 0.9).sin(), 0.08, 0.15),
            };
            Blob::from_ellipsoid(&e, 0.6)
        })
        .collect()
}

#[test]
fn deterministic_across_thread_counts() {
    let field = BlobField::new(&many_blobs(60), 1.0);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| polygonize(&field, 64))
    };
    let one = run(1);
    assert_closed_oriented(&one, "many blobs");
    for threads in [2, 3, 5] {
        assert!(run(threads) == one, "output differs with {threads} threads");
    }
}

#[test]
fn three_hundred_blobs_at_resolution_200() {
    let field = BlobField::new(&many_blobs(300), 1.0);
    let start = Instant::now();
    let mesh = polygonize(&field, 200);
    let secs = start.elapsed().as_secs_f64();
    println!(
        "300 blobs, resolution 200: {} vertices, {} triangles, {secs:.3} s",
        mesh.positions.len(),
        mesh.triangles.len()
    );
    assert_closed_oriented(&mesh, "300 blobs");
}

/// A fresh scratch directory under the system temp dir.
fn scratch(name: &str) -> std::path::PathBuf {
    let dir =
        std::env::temp_dir().join(format!("nephele-polygonize-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn model_of(blobs: Vec<Blob>) -> nephele::blobby::BlobModel {
    let field = BlobField::new(&blobs, 1.0);
    nephele::blobby::BlobModel {
        version: nephele::blobby::model_file::MODEL_VERSION,
        primitive: nephele::decompose::Primitive::Ellipsoid,
        threshold: 1.0,
        source: nephele::blobby::SourceInfo {
            mesh: "test".into(),
            bounds: field.bounds(),
            vertices: 0,
            faces: 0,
        },
        seed: 1,
        blobs,
    }
}

#[test]
fn cli_mesh_writes_a_closed_obj_and_ply() {
    let dir = scratch("cli");
    let model_path = dir.join("model.ron");
    nephele::blobby::save_model(&model_path, &model_of(many_blobs(40))).unwrap();
    for ext in ["obj", "ply"] {
        let out = dir.join(format!("surface.{ext}"));
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_nephele"))
            .args([
                "mesh",
                model_path.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ])
            .args(["--resolution", "48"])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&status.stdout);
        assert!(
            status.status.success(),
            "{stdout} {}",
            String::from_utf8_lossy(&status.stderr)
        );
        assert!(stdout.contains("triangles"), "{stdout}");
        let mesh = nephele::mesh::io::read_mesh(&out).unwrap();
        assert_closed_oriented(&mesh, ext);
        let direct = polygonize(
            &nephele::blobby::load_model(&model_path).unwrap().field(),
            48,
        );
        assert_eq!(mesh.triangles.len(), direct.triangles.len(), "{ext}");
    }
    // Bad input: a missing model and a wrong extension fail with a message, no panic.
    let missing = std::process::Command::new(env!("CARGO_BIN_EXE_nephele"))
        .args(["mesh", dir.join("nope.ron").to_str().unwrap(), "-o"])
        .arg(dir.join("x.obj"))
        .output()
        .unwrap();
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("nope.ron"));
    let bad_ext = std::process::Command::new(env!("CARGO_BIN_EXE_nephele"))
        .args(["mesh", model_path.to_str().unwrap(), "-o"])
        .arg(dir.join("x.stl"))
        .output()
        .unwrap();
    assert!(!bad_ext.status.success());
    assert!(String::from_utf8_lossy(&bad_ext.stderr).contains(".obj or .ply"));
    let _ = std::fs::remove_dir_all(&dir);
}
