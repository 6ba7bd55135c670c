//! Binary blob codec: lossless round trips, quantized size and extra error, isotropic layout,
//! and refusal of truncated, corrupt and future-version files.

use std::path::Path;

use glam::DVec3;
use nephele::blobby::codec::{self, Encoding, QUANTIZED_BLOB_BYTES};
use nephele::blobby::{Blob, BlobField, BlobModel, ModelError};
use nephele::geometry::Aabb;

use crate::eval_support;
use eval_support::model;

fn path() -> &'static Path {
    Path::new("test.blob")
}

/// Points on the zero set of `field`: from each blob centre inside the surface, march along
/// fixed directions to the first sign change, then bisect.
fn zero_set(model: &BlobModel, field: &BlobField) -> Vec<DVec3> {
    let dirs: Vec<DVec3> = (0..40)
        .map(|k| {
            let z = 1.0 - (k as f64 + 0.5) / 20.0;
            let phi = k as f64 * 2.399_963;
            let s = (1.0 - z * z).sqrt();
            DVec3::new(s * phi.cos(), z, s * phi.sin())
        })
        .collect();
    let mut out = Vec::new();
    for b in &model.blobs {
        if field.value(b.center) <= 0.0 {
            continue;
        }
        let step = b.support().semi_axes.max_element() / 200.0;
        for d in &dirs {
            let (mut lo, mut hi) = (0.0, step);
            while field.value(b.center + *d * hi) > 0.0 && hi < 1e3 {
                lo = hi;
                hi += step;
            }
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                if field.value(b.center + *d * mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            out.push(b.center + *d * (0.5 * (lo + hi)));
        }
    }
    out
}

/// Largest first-order distance `|F(p)| / |∇F(p)|` from points of one surface to the other.
fn max_distance(points: &[DVec3], other: &BlobField) -> f64 {
    points
        .iter()
        .map(|&p| {
            let (f, g) = other.value_and_gradient(p);
            f.abs() / g.length().max(1e-12)
        })
        .fold(0.0, f64::max)
}

#[test]
fn lossless_round_trip_is_byte_identical_and_field_exact_to_f32() {
    for sphere in [false, true] {
        let m = model(40, sphere);
        let bytes = codec::encode(&m, Encoding::Lossless);
        assert!(codec::is_encoded(&bytes));
        let back = codec::decode(path(), &bytes).unwrap();
        assert_eq!(codec::encode(&back, Encoding::Lossless), bytes);
        assert_eq!(back.blobs.len(), m.blobs.len());
        assert_eq!(back.primitive, m.primitive);
        assert_eq!((back.seed, back.threshold), (m.seed, m.threshold));
        assert_eq!(back.source.mesh, m.source.mesh);
        assert_eq!(
            (back.source.vertices, back.source.faces),
            (m.source.vertices, m.source.faces)
        );
        assert!(
            (back.source.bounds.min - m.source.bounds.min)
                .abs()
                .max_element()
                < 1e-5
        );
        // The field: every stored number is an f32 rounding (relative 6e-8), so values of
        // F (of order 1..10 near the surface) agree to ~1e-5 absolute.
        let (f, g) = (m.field(), back.field());
        let bounds = f.bounds();
        let mut worst: f64 = 0.0;
        for i in 0..20_000u64 {
            let h = |k: u64| (nephele::rng::mix64(i * 3 + k) >> 11) as f64 / (1u64 << 53) as f64;
            let x = bounds.min + bounds.size() * DVec3::new(h(0), h(1), h(2));
            worst = worst.max((f.value(x) - g.value(x)).abs());
        }
        assert!(worst < 2e-5, "field differs by {worst} (sphere = {sphere})");
        // Unoptimised blobs get their A and semi-axes back (the codec's A convention).
        let a = Blob::from_ellipsoid(&m.blobs[3].ellipsoid(), 0.7);
        let one = BlobModel {
            blobs: vec![a],
            ..m.clone()
        };
        let b = codec::decode(path(), &codec::encode(&one, Encoding::Lossless)).unwrap();
        assert!((b.blobs[0].a - 0.7).abs() < 1e-5, "{:?}", b.blobs[0]);
        assert!((b.blobs[0].semi_axes - a.semi_axes).abs().max_element() < 1e-5);
    }
}

#[test]
fn sizes_per_blob() {
    let m = model(50, false);
    let lossless = codec::encode(&m, Encoding::Lossless);
    let quantized = codec::encode(&m, Encoding::Quantized);
    let header = lossless.len() - 50 * 40;
    assert_eq!(header, 58 + m.source.mesh.len());
    assert_eq!(quantized.len(), header + 36 + 50 * QUANTIZED_BLOB_BYTES);
    const { assert!(QUANTIZED_BLOB_BYTES < 20) };
    let s = model(50, true);
    assert_eq!(
        codec::encode(&s, Encoding::Lossless).len(),
        header + 50 * 20
    );
    assert_eq!(
        codec::encode(&s, Encoding::Quantized).len(),
        header + 36 + 50 * 10
    );
}

#[test]
fn quantized_extra_error_is_below_a_thousandth_of_the_diagonal() {
    for sphere in [false, true] {
        let m = model(48, sphere);
        let bytes = codec::encode(&m, Encoding::Quantized);
        let q = codec::decode(path(), &bytes).unwrap();
        assert_eq!(q.blobs.len(), m.blobs.len());
        let (f, g) = (m.field(), q.field());
        let on_f = zero_set(&m, &f);
        let on_g = zero_set(&q, &g);
        assert!(on_f.len() > 1000 && on_g.len() > 1000);
        let d = Aabb::from_points(&on_f).diagonal();
        let e = max_distance(&on_f, &g).max(max_distance(&on_g, &f));
        eprintln!(
            "quantized extra error ({} blobs, sphere = {sphere}): {:.5}% of D, {} bytes",
            m.blobs.len(),
            100.0 * e / d,
            bytes.len()
        );
        assert!(e < 1e-3 * d, "extra error {e} = {}% of D", 100.0 * e / d);
        // And it is not trivially zero: the test can fail.
        assert!(e > 1e-8 * d);
    }
}

#[test]
fn dead_blobs_stay_dead() {
    let mut m = model(20, false);
    m.blobs[4].b = 0.0;
    m.blobs[7].semi_axes.y = 0.0;
    for enc in [Encoding::Lossless, Encoding::Quantized] {
        let q = codec::decode(path(), &codec::encode(&m, enc)).unwrap();
        assert_eq!(q.live_count(), m.live_count(), "{enc:?}");
        assert_eq!(q.live_count(), 18);
    }
}

#[test]
fn every_truncation_is_a_located_error() {
    for enc in [Encoding::Lossless, Encoding::Quantized] {
        let bytes = codec::encode(&model(6, false), enc);
        for len in 0..bytes.len() {
            let e = codec::decode(path(), &bytes[..len])
                .unwrap_err()
                .to_string();
            assert!(e.starts_with("test.blob: "), "{e}");
            if len >= 4 {
                assert!(e.contains("byte offset"), "{e}");
            }
        }
        let mut long = bytes.clone();
        long.push(0);
        let e = codec::decode(path(), &long).unwrap_err().to_string();
        assert!(e.contains("unexpected bytes"), "{e}");
    }
    let bytes = codec::encode(&model(6, false), Encoding::Lossless);
    let e = codec::decode(path(), &bytes[..bytes.len() - 41])
        .unwrap_err()
        .to_string();
    assert!(e.contains("blob 5 of 6"), "{e}");
}

#[test]
fn future_version_corrupt_header_and_huge_count_are_errors() {
    let bytes = codec::encode(&model(6, false), Encoding::Quantized);
    let mut v = bytes.clone();
    v[4] = 9;
    assert!(matches!(
        codec::decode(path(), &v),
        Err(ModelError::Version {
            found: 9,
            supported: 1,
            ..
        })
    ));
    let mut e = bytes.clone();
    e[5] = 7;
    let msg = codec::decode(path(), &e).unwrap_err().to_string();
    assert!(
        msg.contains("byte offset 5") && msg.contains("encoding"),
        "{msg}"
    );
    let mut m = bytes.clone();
    m[0] = b'X';
    assert!(codec::decode(path(), &m).is_err());
    // A claimed count far beyond the data is refused before anything is allocated for it.
    let mut c = bytes.clone();
    c[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    let msg = codec::decode(path(), &c).unwrap_err().to_string();
    assert!(msg.contains("truncated in blob 7 of 4294967295"), "{msg}");
    let mut z = bytes;
    z[8..12].copy_from_slice(&0u32.to_le_bytes());
    assert!(codec::decode(path(), &z).is_err());
}

#[test]
fn non_finite_blob_names_the_blob() {
    let m = model(6, false);
    let mut bytes = codec::encode(&m, Encoding::Lossless);
    let header = bytes.len() - 6 * 40;
    let at = header + 2 * 40 + 4; // blob 3, centre y
    bytes[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    let e = codec::decode(path(), &bytes).unwrap_err().to_string();
    assert!(e.contains("blob 3 of 6") && e.contains("non-finite"), "{e}");
}

#[test]
fn random_corruption_never_panics() {
    for enc in [Encoding::Lossless, Encoding::Quantized] {
        let bytes = codec::encode(&model(5, false), enc);
        for i in 0..4000u64 {
            let mut b = bytes.clone();
            let k = nephele::rng::mix64(i);
            let at = (k % b.len() as u64) as usize;
            b[at] ^= ((k >> 32) as u8) | 1;
            if let Ok(m) = codec::decode(path(), &b) {
                assert!(m.blobs.iter().all(|b| b.center.is_finite() && b.a > 0.0));
            }
        }
    }
}

#[test]
fn load_model_detects_an_encoded_file() {
    let dir = std::env::temp_dir().join(format!("nephele-codec-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let m = model(10, false);
    let file = dir.join("m.blob");
    std::fs::write(&file, codec::encode(&m, Encoding::Lossless)).unwrap();
    let back = nephele::blobby::load_model(&file).unwrap();
    assert_eq!(back.blobs.len(), 10);
    std::fs::write(&file, &codec::encode(&m, Encoding::Lossless)[..30]).unwrap();
    let e = nephele::blobby::load_model(&file).unwrap_err().to_string();
    assert!(e.contains("m.blob") && e.contains("truncated"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn cli_encode_decode_round_trip() {
    let exe = env!("CARGO_BIN_EXE_nephele");
    let dir = std::env::temp_dir().join(format!("nephele-codec-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let m = model(12, false);
    let ron = dir.join("m.ron");
    nephele::blobby::save_model(&ron, &m).unwrap();
    let run = |args: &[&Path]| {
        std::process::Command::new(exe)
            .args(args)
            .output()
            .expect("runs")
    };
    let blob = dir.join("m.blob");
    let out = run(&[
        Path::new("encode"),
        &ron,
        Path::new("-o"),
        &blob,
        Path::new("--quantized"),
    ]);
    assert!(out.status.success(), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("bytes"), "{stderr}");
    let expected = codec::encode(&m, Encoding::Quantized);
    assert_eq!(std::fs::read(&blob).unwrap(), expected);
    let back = dir.join("back.ron");
    let out = run(&[Path::new("decode"), &blob, Path::new("-o"), &back]);
    assert!(out.status.success(), "{out:?}");
    let decoded = nephele::blobby::load_model(&back).unwrap();
    assert_eq!(decoded, codec::decode(path(), &expected).unwrap());
    // Decoding a RON file is a clear error, and leaves no output.
    let nothing = dir.join("nothing.ron");
    let out = run(&[Path::new("decode"), &ron, Path::new("-o"), &nothing]);
    assert!(!out.status.success() && !nothing.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn quantized_extra_error_on_a_fitted_duck() {
    use nephele::blobby::fit::FaithfulConfig;
    use nephele::blobby::polygonize::polygonize;
    use nephele::eval::{MetroConfig, compare};
    use nephele::pipeline::{FitConfig, Optimisation, fit};
    let loaded = nephele::mesh::load("builtin:duck").unwrap();
    let cfg = FitConfig {
        blobs: 150,
        samples: 20_000,
        optimisation: Optimisation::Faithful(FaithfulConfig::default()),
        ..FitConfig::default()
    };
    let m = fit(&cfg, &loaded).unwrap().model;
    let lossless = codec::encode(&m, Encoding::Lossless);
    assert_eq!(
        codec::encode(
            &codec::decode(path(), &lossless).unwrap(),
            Encoding::Lossless
        ),
        lossless
    );
    let q = codec::decode(path(), &codec::encode(&m, Encoding::Quantized)).unwrap();
    let d = loaded.mesh.bounds().diagonal();
    let metro = MetroConfig {
        min_samples: 50_000,
        max_samples: 50_000,
        diagonal: Some(d),
        ..MetroConfig::default()
    };
    let r = compare(
        &polygonize(&m.field(), 120),
        &polygonize(&q.field(), 120),
        &metro,
    );
    eprintln!(
        "duck, {} blobs ({} live): quantized extra error mean {:.5}% max {:.5}% of D",
        m.blobs.len(),
        m.live_count(),
        r.mean_pct(),
        r.hausdorff_pct
    );
    assert!(r.hausdorff_pct < 0.1, "{r:?}");
    assert!(r.hausdorff_pct > 0.0);
}
