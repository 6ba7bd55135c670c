//! Metro evaluation: a mesh against itself, against a scaled copy (analytic distances), sample
//! counts, determinism across thread counts, empty meshes.

use glam::DVec3;
use nephele::eval::{MetroConfig, compare, metro::area_samples};
use nephele::mesh::Mesh;

use crate::eval_support;
use crate::shared_models;
use eval_support::icosphere;

fn scaled(m: &Mesh, k: f64, about: DVec3) -> Mesh {
    Mesh {
        positions: m
            .positions
            .iter()
            .map(|&p| about + (p - about) * k)
            .collect(),
        triangles: m.triangles.clone(),
    }
}

fn small() -> MetroConfig {
    MetroConfig {
        min_samples: 20_000,
        ..MetroConfig::default()
    }
}

#[test]
fn icosphere_is_closed_and_outward() {
    let m = icosphere(3, 1.0, DVec3::ZERO);
    assert_eq!(m.boundary_edge_count(), 0);
    assert!(m.signed_volume() > 4.0);
}

#[test]
fn mesh_against_itself_is_zero() {
    let m = icosphere(3, 2.5, DVec3::new(1.0, -2.0, 0.5));
    let r = compare(&m, &m, &small());
    let d = m.bounds().diagonal();
    assert!((r.diagonal - d).abs() < 1e-12);
    for s in [&r.a_to_b, &r.b_to_a] {
        assert!(s.max < 1e-9 * d, "{s:?}");
        assert!(s.samples == 20_000.max(10 * m.triangles.len()));
        assert_eq!(s.vertices, m.positions.len());
    }
    assert!(r.hausdorff_pct < 1e-7);
}

#[test]
fn scaled_sphere_matches_the_analytic_displacement() {
    // Every point of a sphere of radius R scaled by 1.01 about its centre is 0.01 R from the
    // original; the tessellation adds an error of order R·(edge/R)² that a level-4 icosphere
    // keeps well under a few percent of that.
    let (radius, c) = (3.0, DVec3::new(-1.0, 0.5, 2.0));
    let m = icosphere(4, radius, c);
    let k = scaled(&m, 1.01, c);
    let r = compare(&m, &k, &small());
    let expect = 0.01 * radius;
    for (name, s) in [("a->b", &r.a_to_b), ("b->a", &r.b_to_a)] {
        for (what, v) in [("mean", s.mean), ("rms", s.rms), ("max", s.max)] {
            assert!(
                (v / expect - 1.0).abs() < 0.03,
                "{name} {what} = {v}, expected {expect}"
            );
        }
        assert!(s.max >= s.rms && s.rms >= s.mean);
    }
    let d = m.bounds().diagonal();
    assert!((r.hausdorff_pct - 100.0 * r.hausdorff / d).abs() < 1e-12);
    assert!((r.a_to_b.mean_pct - 100.0 * r.a_to_b.mean / d).abs() < 1e-12);
}

#[test]
fn translated_copy_has_the_known_hausdorff_distance() {
    // Shifting a sphere by δ: the farthest points are at distance δ from the other sphere
    // (on the axis), so Hausdorff ≈ δ, and the mean is about δ/2 (the mean of |cos θ|·δ).
    let m = icosphere(4, 1.0, DVec3::ZERO);
    let delta = 0.02;
    let shifted = Mesh {
        positions: m.positions.iter().map(|&p| p + DVec3::X * delta).collect(),
        triangles: m.triangles.clone(),
    };
    let r = compare(&m, &shifted, &small());
    assert!((r.hausdorff / delta - 1.0).abs() < 0.03, "{r:?}");
    assert!((r.a_to_b.mean / (0.5 * delta) - 1.0).abs() < 0.05, "{r:?}");
}

#[test]
fn sample_counts_follow_the_larger_mesh() {
    let cfg = MetroConfig::default();
    assert_eq!(cfg.sample_count(10, 30_000), 300_000);
    assert_eq!(cfg.sample_count(100, 200), 200_000);
    assert_eq!(cfg.sample_count(1_000_000, 200), 1_000_000);
    let m = icosphere(2, 1.0, DVec3::ZERO);
    let pts = area_samples(&m, 1000, 3, 0);
    assert_eq!(pts.len(), 1000);
    assert!(pts.iter().all(|p| (p.length() - 1.0).abs() < 0.05));
}

#[test]
fn report_is_identical_at_any_thread_count() {
    let m = icosphere(3, 1.0, DVec3::ZERO);
    let k = scaled(&icosphere(2, 1.0, DVec3::ZERO), 1.02, DVec3::ZERO);
    let cfg = small();
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| compare(&m, &k, &cfg));
    let many = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap()
        .install(|| compare(&m, &k, &cfg));
    assert_eq!(one, many);
    let other_seed = compare(&m, &k, &MetroConfig { seed: 2, ..cfg });
    assert_ne!(one.a_to_b.mean, other_seed.a_to_b.mean);
}

#[test]
fn empty_mesh_gives_infinite_distances_without_panicking() {
    let m = icosphere(1, 1.0, DVec3::ZERO);
    let r = compare(&m, &Mesh::default(), &small());
    assert!(r.hausdorff.is_infinite() && r.a_to_b.mean.is_infinite());
    assert_eq!(r.b_to_a.samples, 0);
    let json = serde_json::to_string(&r).unwrap();
    assert!(json.contains("\"hausdorff\":null"), "{json}");
}

#[test]
fn bunny_against_itself_and_a_scaled_copy() {
    let Some(loaded) = shared_models::load("bunny.off") else {
        return;
    };
    let m = loaded.mesh;
    let d = m.bounds().diagonal();
    let t = std::time::Instant::now();
    let r = compare(&m, &m, &MetroConfig::default());
    let self_secs = t.elapsed().as_secs_f64();
    assert!(r.hausdorff < 1e-9 * d, "{r:?}");
    let k = scaled(&m, 1.01, m.bounds().center());
    let t = std::time::Instant::now();
    let r = compare(&m, &k, &MetroConfig::default());
    let scaled_secs = t.elapsed().as_secs_f64();
    // Displacements are at most 1 % of the distance from the centre, below 0.5 % of D.
    assert!(r.hausdorff_pct < 0.5 && r.a_to_b.mean_pct > 0.05, "{r:?}");
    eprintln!(
        "bunny: {} faces; Metro vs itself {self_secs:.2} s, vs 1.01 copy {scaled_secs:.2} s: mean {:.4}% max {:.4}% of D",
        m.triangles.len(),
        r.mean_pct(),
        r.hausdorff_pct
    );
}

fn quick() -> nephele::eval::EvalConfig {
    nephele::eval::EvalConfig {
        resolution: 100,
        metro: MetroConfig {
            samples_per_face: 1,
            ..small()
        },
        codec_error: true,
        quantized_vs_mesh: true,
    }
}

#[test]
fn model_evaluation_against_a_fine_polygonization() {
    // The "mesh" is the model's own surface polygonized finely; the evaluation polygonizes at
    // a coarser resolution, so the error is small but not zero, and the codec's extra error is
    // below 0.1 % of D.
    let m = eval_support::model(40, false);
    let mesh = nephele::blobby::polygonize::polygonize(&m.field(), 200);
    let r = nephele::eval::evaluate_model(&mesh, &m, &quick());
    let d = mesh.bounds().diagonal();
    assert!((r.mesh.diagonal - d).abs() < 1e-12);
    assert_eq!(
        r.mesh.bytes,
        12 * (mesh.positions.len() + mesh.triangles.len())
    );
    assert_eq!((r.model.blobs, r.model.live), (40, 40));
    assert!(r.polygonization.faces > 1000);
    // Cells are ~0.7 % of D at resolution 100 and the thinnest blobs ~1.5 % of D across.
    assert!(
        r.error.hausdorff_pct < 1.5 && r.error.hausdorff_pct > 1e-4,
        "{:?}",
        r.error
    );
    assert!(r.error.mean_pct() < 0.1, "{:?}", r.error);
    let c = &r.codec;
    assert!(c.quantized_bytes < c.lossless_bytes && c.lossless_bytes < 45 * 40 + 200);
    assert!((c.reduction_quantized - r.mesh.bytes as f64 / c.quantized_bytes as f64).abs() < 1e-9);
    let extra = c.quantized_extra.expect("measured");
    eprintln!("{}", r.report());
    assert!(extra.hausdorff_pct < 0.1, "{extra:?}");
    assert!(
        (extra.diagonal - d).abs() < 1e-12,
        "extra error is relative to the mesh's D"
    );
    let q = c.quantized_error.expect("measured");
    assert!((q.hausdorff_pct - r.error.hausdorff_pct).abs() < 0.1);
    let text = r.report();
    assert!(
        text.contains("Hausdorff") && text.contains("quantized"),
        "{text}"
    );
    let names: Vec<&str> = r.timings.iter().map(|t| t.0.as_str()).collect();
    assert_eq!(names[..3], ["polygonize", "metro", "encode"]);
}

#[test]
fn cli_eval_prints_json_and_text() {
    let exe = env!("CARGO_BIN_EXE_nephele");
    let dir = std::env::temp_dir().join(format!("nephele-eval-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let m = eval_support::model(24, false);
    let model_path = dir.join("m.ron");
    nephele::blobby::save_model(&model_path, &m).unwrap();
    let mesh_path = dir.join("m.obj");
    let mesh = nephele::blobby::polygonize::polygonize(&m.field(), 120);
    nephele::mesh::io::write_mesh(&mesh_path, &mesh).unwrap();
    let run = |extra: &[&str]| {
        let mut c = std::process::Command::new(exe);
        c.arg("eval").arg(&mesh_path).arg(&model_path);
        c.args(["--resolution", "60", "--min-samples", "20000"]);
        c.args(extra).output().expect("runs")
    };
    let out = run(&["--json", "--timings"]);
    assert!(out.status.success(), "{out:?}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("valid JSON");
    assert_eq!(v["model"]["blobs"], 24);
    assert_eq!(v["model"]["primitive"], "Ellipsoid");
    assert!(v["error"]["hausdorff_pct"].as_f64().unwrap() < 3.0);
    assert!(
        v["codec"]["quantized_extra"]["hausdorff_pct"]
            .as_f64()
            .unwrap()
            < 0.1
    );
    assert!(v["timings"].as_array().unwrap().len() >= 5);
    assert!(String::from_utf8_lossy(&out.stderr).contains("total"));
    let out = run(&["--no-codec-error"]);
    assert!(out.status.success(), "{out:?}");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("mesh -> model") && text.contains("reduction"),
        "{text}"
    );
    // A missing model is a clear error naming the file.
    let out = std::process::Command::new(exe)
        .arg("eval")
        .arg(&mesh_path)
        .arg(dir.join("missing.ron"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.ron"));
    std::fs::remove_dir_all(&dir).unwrap();
}
