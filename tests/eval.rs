//! Metro evaluation: a mesh against itself, against a scaled copy (analytic distances), sample
//! counts, determinism across thread counts, empty meshes.

use glam::DVec3;
use nephele::eval::{MetroConfig, compare, metro::area_samples};
use nephele::mesh::Mesh;

/// Icosphere of radius `r` about `c`, subdivided `levels` times (vertices projected).
fn icosphere(levels: usize, r: f64, c: DVec3) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut p: Vec<DVec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| DVec3::new(x, y, z).normalize())
    .collect();
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid = std::collections::HashMap::new();
        let mut next = Vec::with_capacity(f.len() * 4);
        let mut midpoint = |a: u32, b: u32, p: &mut Vec<DVec3>| -> u32 {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                p.push(((p[a as usize] + p[b as usize]) * 0.5).normalize());
                (p.len() - 1) as u32
            })
        };
        for &[a, b, c] in &f {
            let ab = midpoint(a, b, &mut p);
            let bc = midpoint(b, c, &mut p);
            let ca = midpoint(c, a, &mut p);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    Mesh {
        positions: p.iter().map(|&v| c + v * r).collect(),
        triangles: f,
    }
}

fn scaled(m: &Mesh, k: f64, about: DVec3) -> Mesh {
    Mesh {
        positions: m.positions.iter().map(|&p| about + (p - about) * k).collect(),
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
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/models/bunny.off");
    if !std::path::Path::new(path).exists() {
        eprintln!("skipping: {path} is absent");
        return;
    }
    let loaded = match nephele::mesh::load(path) {
        Ok(l) => l,
        Err(e) => panic!("{e}"),
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
