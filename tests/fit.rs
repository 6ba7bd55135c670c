//! The fitting pipeline end to end on builtin shapes: optimisation lowers the objective, an
//! inside-out copy fits exactly like the original, and the model file is byte-identical at any
//! thread count.

use nephele::blobby::fit::FaithfulConfig;
use nephele::pipeline::{FitConfig, Optimisation, fit};

fn small(optimisation: Optimisation) -> FitConfig {
    FitConfig {
        blobs: 60,
        candidates: 600,
        samples: 12_000,
        optimisation,
        ..FitConfig::default()
    }
}

#[test]
fn optimisation_lowers_the_objective() {
    let duck = nephele::mesh::load("builtin:duck").unwrap();
    let faithful = fit(
        &small(Optimisation::Faithful(FaithfulConfig::default())),
        &duck,
    );
    let s = &faithful.stats;
    assert!(
        s.objective_after < 0.01 * s.objective_before,
        "faithful: {} -> {}",
        s.objective_before,
        s.objective_after
    );
    let full = fit(&small(FitConfig::default().optimisation), &duck);
    assert!(
        full.stats.objective_after < s.objective_after,
        "full {} is not below faithful {}",
        full.stats.objective_after,
        s.objective_after
    );
    assert!(
        full.model.blobs.iter().all(|b| b.is_live()),
        "full mode leaves dead blobs"
    );
}

#[test]
fn inside_out_copy_fits_the_same() {
    let dir = std::env::temp_dir().join(format!("nephele-fit-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let original = nephele::mesh::load("builtin:duck").unwrap();
    let mut inverted = original.mesh.clone();
    inverted.flip_orientation();
    let path = dir.join("inverted.obj");
    nephele::mesh::io::write_mesh(&path, &inverted).unwrap();
    let loaded = nephele::mesh::load(path.to_str().unwrap()).unwrap();
    assert!(
        loaded.warnings.iter().any(|w| w.contains("flipped")),
        "{:?}",
        loaded.warnings
    );
    let cfg = small(Optimisation::Faithful(FaithfulConfig::default()));
    let a = fit(&cfg, &original).model;
    let b = fit(&cfg, &loaded).model;
    assert_eq!(a.blobs, b.blobs);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn model_file_is_identical_at_one_and_two_threads() {
    let dir = std::env::temp_dir().join(format!("nephele-threads-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |threads: &str, out: &str| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_nephele"))
            .args([
                "fit",
                "builtin:torus-knot",
                "-o",
                out,
                "--blobs",
                "60",
                "--candidates",
                "600",
                "--samples",
                "12000",
                "--seed",
                "5",
            ])
            .env("RAYON_NUM_THREADS", threads)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(dir.join(out)).unwrap()
    };
    let one = run("1", "one.ron");
    let two = run("2", "two.ron");
    assert!(one == two, "model files differ between 1 and 2 threads");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn max_error_mode_adds_blobs_until_the_target() {
    const TARGET: f64 = 3.0;
    let knot = nephele::mesh::load("builtin:torus-knot").unwrap();
    let cfg = FitConfig {
        blobs: 8,
        ..small(Optimisation::Faithful(FaithfulConfig::default()))
    };
    let (out, rounds) = nephele::pipeline::fit_to_error(&cfg, &knot, TARGET, 200);
    assert!(rounds.len() >= 2, "{rounds:?}");
    assert!(
        rounds.windows(2).all(|w| w[1].blobs > w[0].blobs),
        "{rounds:?}"
    );
    let last = rounds.last().unwrap();
    assert!(
        last.hausdorff_pct <= TARGET || last.blobs == 200,
        "{rounds:?}"
    );
    assert!(last.hausdorff_pct < rounds[0].hausdorff_pct, "{rounds:?}");
    assert_eq!(out.model.blobs.len(), last.kept);
}
