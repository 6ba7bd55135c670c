//! Benchmark (docs/ARCHITECTURE.md, Evaluation and codec): fit every model in `../shared/models` at several blob counts with
//! ellipsoids and with spheres (also spheres at twice the count, i.e. about equal bytes: a
//! sphere costs 5 numbers in the codec, an ellipsoid 10), evaluate each fit with Metro, and print
//! one table.
//!
//! ```text
//! cargo test --release --test it -- --ignored --nocapture bench::
//! NEPHELE_BENCH_MODELS=bunny,horse NEPHELE_BENCH_BLOBS=100,300 cargo test --release --test it -- --ignored --nocapture bench::
//! ```
//! Environment: `NEPHELE_BENCH_MODELS` (file stems, default bunny,horse,armadillo,cow,fertility,
//! knight), `NEPHELE_BENCH_BLOBS` (default 100,300,1000), `NEPHELE_BENCH_RESOLUTION`
//! (polygonization cells on the longest side, default 200), `NEPHELE_BENCH_OPT` (a list of
//! `none`, `faithful`, `full`; default `full`, what `nephele fit` does), `NEPHELE_BENCH_SPHERES`
//! (`0` skips the sphere rows). A stage that fails or is not implemented yet prints its message in the row and the
//! benchmark goes on.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::Instant;

use nephele::blobby::fit::FaithfulConfig;
use nephele::blobby::optimise::FullConfig;
use nephele::decompose::Primitive;
use nephele::eval::{EvalConfig, evaluate_model};
use nephele::pipeline::{FitConfig, Optimisation, fit};

const MODELS_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/models");
const DEFAULT_MODELS: &str = "bunny,horse,armadillo,cow,fertility,knight";

fn env_or(name: &str, default: &str) -> String {
    std::env::var(name).unwrap_or_else(|_| default.to_string())
}

/// The mesh file in `dir` whose stem is `name` (any supported extension).
fn find_model(dir: &Path, name: &str) -> Option<PathBuf> {
    ["off", "ply", "obj", "stl"]
        .iter()
        .map(|ext| dir.join(format!("{name}.{ext}")))
        .find(|p| p.exists())
}

/// One table row (or the reason it has no numbers).
struct Row {
    model: String,
    opt: &'static str,
    primitive: &'static str,
    blobs: usize,
    result: Result<Numbers, String>,
}

struct Numbers {
    live: usize,
    lossless: usize,
    quantized: usize,
    mean_pct: f64,
    max_pct: f64,
    fit_s: f64,
    eval_s: f64,
}

impl Row {
    fn line(&self) -> String {
        let head = format!(
            "{:<10} {:<8} {:<9} {:>6}",
            self.model, self.opt, self.primitive, self.blobs
        );
        match &self.result {
            Ok(n) => format!(
                "{head} {:>6} {:>9} {:>9} {:>8.4} {:>8.4} {:>8.2} {:>8.2}",
                n.live, n.lossless, n.quantized, n.mean_pct, n.max_pct, n.fit_s, n.eval_s
            ),
            Err(e) => format!("{head}   -- {e}"),
        }
    }
}

fn header() -> String {
    format!(
        "{:<10} {:<8} {:<9} {:>6} {:>6} {:>9} {:>9} {:>8} {:>8} {:>8} {:>8}",
        "model",
        "opt",
        "primitive",
        "blobs",
        "live",
        "bytes",
        "q.bytes",
        "mean %",
        "max %",
        "fit s",
        "eval s"
    )
}

/// Run `f`, turning a panic (e.g. a stage not implemented yet) into its message.
fn guarded<T>(f: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(p) => Err(p
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_else(|| "panicked".into())),
    }
}

fn optimisation(name: &str) -> Option<(&'static str, Optimisation)> {
    match name {
        "none" => Some(("none", Optimisation::None)),
        "faithful" => Some((
            "faithful",
            Optimisation::Faithful(FaithfulConfig::default()),
        )),
        "full" => Some((
            "full",
            Optimisation::Full(FaithfulConfig::default(), FullConfig::default()),
        )),
        _ => None,
    }
}

fn run_one(
    path: &Path,
    opt: &(&'static str, Optimisation),
    primitive: Primitive,
    blobs: usize,
    resolution: usize,
) -> Row {
    let name = path.file_stem().unwrap_or_default().to_string_lossy();
    let result = guarded(|| {
        let loaded = nephele::mesh::load(&path.to_string_lossy()).map_err(|e| e.to_string())?;
        let cfg = FitConfig {
            blobs,
            primitive,
            optimisation: opt.1.clone(),
            ..FitConfig::default()
        };
        let t = Instant::now();
        let out = fit(&cfg, &loaded).map_err(|e| e.to_string())?;
        let fit_s = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let eval_cfg = EvalConfig {
            resolution,
            codec_error: false,
            ..EvalConfig::default()
        };
        let e = evaluate_model(&loaded.mesh, &out.model, &eval_cfg);
        Ok(Numbers {
            live: e.model.live,
            lossless: e.codec.lossless_bytes,
            quantized: e.codec.quantized_bytes,
            mean_pct: e.error.mean_pct(),
            max_pct: e.error.hausdorff_pct,
            fit_s,
            eval_s: t.elapsed().as_secs_f64(),
        })
    });
    Row {
        model: name.into_owned(),
        opt: opt.0,
        primitive: match primitive {
            Primitive::Ellipsoid => "ellipsoid",
            Primitive::Sphere => "sphere",
        },
        blobs,
        result,
    }
}

#[test]
#[ignore = "benchmark: cargo test --release --test it -- --ignored --nocapture bench::"]
fn fit_and_evaluate_every_model() {
    let dir = Path::new(MODELS_DIR);
    if !dir.exists() {
        eprintln!("skipping the benchmark: {MODELS_DIR} is absent");
        return;
    }
    let names = env_or("NEPHELE_BENCH_MODELS", DEFAULT_MODELS);
    let counts: Vec<usize> = env_or("NEPHELE_BENCH_BLOBS", "100,300,1000")
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    let resolution: usize = env_or("NEPHELE_BENCH_RESOLUTION", "200")
        .parse()
        .unwrap_or(200);
    let spheres = env_or("NEPHELE_BENCH_SPHERES", "1") != "0";
    let opts: Vec<_> = env_or("NEPHELE_BENCH_OPT", "full")
        .split(',')
        .filter_map(|s| optimisation(s.trim()))
        .collect();
    // Silence the panic messages of guarded stages; the row shows them.
    std::panic::set_hook(Box::new(|_| {}));
    let mut rows = Vec::new();
    eprintln!("{}", header());
    for name in names.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let Some(path) = find_model(dir, name) else {
            eprintln!("{name}: no such model in {MODELS_DIR}, skipped");
            continue;
        };
        for &n in &counts {
            let mut runs = vec![(Primitive::Ellipsoid, n)];
            if spheres {
                // Spheres at the same count, and at twice it: about the ellipsoids' bytes.
                runs.extend([(Primitive::Sphere, n), (Primitive::Sphere, 2 * n)]);
            }
            for opt in &opts {
                for &(primitive, blobs) in &runs {
                    let row = run_one(&path, opt, primitive, blobs, resolution);
                    eprintln!("{}", row.line());
                    rows.push(row);
                }
            }
        }
    }
    let _ = std::panic::take_hook();
    println!(
        "\nbytes = lossless codec, q.bytes = quantized codec; errors in % of the mesh's diagonal (Metro, symmetric mean = larger one-sided mean, max = Hausdorff); polygonization resolution {resolution}"
    );
    println!("{}", header());
    for r in &rows {
        println!("{}", r.line());
    }
}
