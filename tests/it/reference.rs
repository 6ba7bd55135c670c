//! `quality: Reference`, the path tracer (`src/render/integrator/reference/`), and the march
//! checked against it per pixel: a billowed test cloud made in code, lit from the side, from
//! behind and from above, at 96×54.
//!
//! - `multiple_scattering_against_reference`: `Final`'s `multiple` pass (the octave
//!   approximation) against the reference's orders ≥ 2, per pixel (relative RMSE of linear
//!   luminance over the cloud's pixels, the reference's noise — measured from two path seeds —
//!   excluded) and in the mean. Prints the figures (`--nocapture`).
//! - `reference_single_scattering_converges`: the reference's order 1 against the march's
//!   single scattering (`cloud.multiple_scattering: false`), both nearly exact there.
//! - `reference_is_deterministic`: the same bits at 1 and 2 threads, another path seed other
//!   bits.

use crate::render::fixture::{settings, test_cloud};
use glam::Vec3;
use nephele::blobby::Blob;
use nephele::render::{
    BlobMedium, Film, Frame, FrameOptions, FrameRenderer, PathTracing, Quality, QualityPreset,
    RenderSettings, Sun, render_path_traced,
};

/// The test cloud: two dozen blobs, the default billows.
fn cloud() -> Vec<Blob> {
    test_cloud(24, 5)
}

/// The three lights: the default side light, a low sun behind the cloud (toward the camera),
/// and a sun straight above.
const LIGHTS: [(&str, Vec3); 3] = [
    ("side", Vec3::new(0.9, -0.6, -0.3)),
    ("behind", Vec3::new(-0.05, -0.3, 0.95)),
    ("above", Vec3::new(0.1, -1.0, 0.05)),
];

/// Per light, the bounds of `Final`'s MS term against the reference: (relative RMSE per pixel,
/// `|mean ratio − 1|`), about 1.3 × what the fluence estimate measures (96×54, 2 × 256 paths a
/// pixel, the reference's noise excluded; render version 8): side 0.146 / 0.953, behind
/// 0.135 / 0.933, above 0.095 / 0.974 — the backlit bound tighter, 1.1 ×, so that losing the
/// forward cone (`Shading::fluence_in`; 0.162 / 0.924 without it) fails. Render version 7
/// measured 0.151 / 0.973, 0.133 / 0.949, 0.102 / 0.995 (the sun's sub-cell detail,
/// `fluence::sun_detail`, takes 2 % off the term's mean and brings the full image's closer);
/// version 5 0.161 / 0.954, 0.170 / 0.912, 0.109 / 0.975; the octaves it replaced 0.430 /
/// 1.282, 0.966 / 1.819, 0.506 / 1.321. (The march's single scattering reads about 4–5 % above
/// Reference's order 1 on this cloud; Reference's is right — within 0.2 % of a quadrature,
/// `reference::quadrature::single_scattering_matches_a_quadrature`, and of Mitsuba with a
/// correct phase function, docs/MEASUREMENTS.md — so that offset is the march's, part of the
/// full image's figures.)
const MS_BOUNDS: [(f64, f64); 3] = [(0.19, 0.06), (0.15, 0.085), (0.125, 0.035)];

/// The full image's bounds (per pixel, `|mean ratio − 1|`) for every light: measured 0.108 /
/// 0.992, 0.122 / 1.008, 0.073 / 1.009 (render version 8; version 7: 0.113 / 1.007, 0.121 /
/// 1.017, 0.081 / 1.024; version 5: 0.117 / 1.022, 0.126 / 1.006, 0.089 / 1.038). The mean's
/// bound, 0.02, fails version 7 (above, 1.024): without the sun's sub-cell detail this fails.
const FULL_BOUNDS: (f64, f64) = (0.16, 0.02);

const SIZE: (u32, u32) = (96, 54);

fn lit(sun: Vec3, quality: Quality) -> RenderSettings {
    let mut s = settings(SIZE.0, SIZE.1, quality);
    s.sun = Sun {
        direction: sun,
        ..Sun::default()
    };
    s
}

fn with_passes(s: &RenderSettings, blobs: &[Blob]) -> Frame {
    let film = Film {
        passes: true,
        ..Film::default()
    };
    let options = FrameOptions {
        film: &film,
        ..FrameOptions::default()
    };
    FrameRenderer::render_once(s, blobs, &options).0
}

/// `quality: Reference` at `samples` paths a pixel, path seed `seed`.
fn reference(samples: u32, seed: u64) -> Quality {
    let mut q = Quality::preset(QualityPreset::Reference);
    q.reference = Some(PathTracing {
        samples,
        seed,
        ..PathTracing::default()
    });
    q
}

fn lum(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Per-pixel comparison of `test` with the mean of two reference renders `a`, `b` over the
/// pixels of `mask`: (relative RMSE with the reference's noise excluded, the reference's
/// relative noise, mean ratio).
fn compare(test: &[f64], a: &[f64], b: &[f64], mask: &[bool]) -> (f64, f64, f64) {
    let (mut mse, mut noise, mut sum_t, mut sum_r, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..test.len() {
        if !mask[i] {
            continue;
        }
        let m = 0.5 * (a[i] + b[i]);
        mse += (test[i] - m).powi(2);
        noise += (0.5 * (a[i] - b[i])).powi(2);
        sum_t += test[i];
        sum_r += m;
        n += 1.0;
    }
    assert!(n > 200.0, "only {n} cloud pixels");
    let scale = sum_r / n;
    (
        ((mse - noise) / n).max(0.0).sqrt() / scale,
        (noise / n).sqrt() / scale,
        sum_t / sum_r,
    )
}

fn layer(f: &Frame, pick: impl Fn(&nephele::render::Passes, usize) -> [f32; 3]) -> Vec<f64> {
    let p = f.passes.as_ref().expect("passes");
    (0..f.rgb.len()).map(|i| lum(pick(p, i))).collect()
}

#[test]
fn multiple_scattering_against_reference() {
    let blobs = cloud();
    for ((name, sun), (rmse_bound, ratio_bound)) in LIGHTS.into_iter().zip(MS_BOUNDS) {
        let fin = with_passes(&lit(sun, Quality::final_frame()), &blobs);
        let r1 = with_passes(&lit(sun, reference(256, 0)), &blobs);
        let r2 = with_passes(&lit(sun, reference(256, 1)), &blobs);
        let mask: Vec<bool> = fin.alpha.iter().map(|&a| a > 0.5).collect();
        let ms = |f: &Frame| layer(f, |p, i| p.multiple[i]);
        let (rmse, noise, ratio) = compare(&ms(&fin), &ms(&r1), &ms(&r2), &mask);
        let full = |f: &Frame| f.rgb.iter().map(|&c| lum(c)).collect::<Vec<_>>();
        let (full_rmse, full_noise, full_ratio) =
            compare(&full(&fin), &full(&r1), &full(&r2), &mask);
        println!(
            "{name}: MS rel RMSE {rmse:.3} (reference noise {noise:.3}), mean ratio {ratio:.3}; \
             full image rel RMSE {full_rmse:.3} (noise {full_noise:.3}), mean ratio {full_ratio:.3}"
        );
        assert!(rmse < rmse_bound, "{name}: MS per pixel {rmse}");
        assert!(
            (ratio - 1.0).abs() < ratio_bound,
            "{name}: MS mean ratio {ratio}"
        );
        assert!(
            full_rmse < FULL_BOUNDS.0,
            "{name}: full image per pixel {full_rmse}"
        );
        assert!(
            (full_ratio - 1.0).abs() < FULL_BOUNDS.1,
            "{name}: full image mean ratio {full_ratio}"
        );
    }
}

#[test]
fn reference_single_scattering_converges() {
    let blobs = cloud();
    for (name, sun) in LIGHTS {
        let mut q = Quality::final_frame();
        // Shadows as exact as the march gets them: a fine light grid.
        q.shadow_grid = 448;
        q.shadow_cell_pixels = 0.0;
        let mut march = lit(sun, q);
        march.cloud.multiple_scattering = false;
        let fin = with_passes(&march, &blobs);
        let r1 = with_passes(&lit(sun, reference(128, 0)), &blobs);
        let r2 = with_passes(&lit(sun, reference(128, 1)), &blobs);
        let mask: Vec<bool> = fin.alpha.iter().map(|&a| a > 0.5).collect();
        let single = |f: &Frame| layer(f, |p, i| [0, 1, 2].map(|c| p.sun[i][c] + p.sky[i][c]));
        let (rmse, noise, ratio) = compare(&single(&fin), &single(&r1), &single(&r2), &mask);
        let sun_only = |f: &Frame| layer(f, |p, i| p.sun[i]);
        let (sun_rmse, _, sun_ratio) =
            compare(&sun_only(&fin), &sun_only(&r1), &sun_only(&r2), &mask);
        let mean_alpha = |f: &Frame| f.alpha.iter().map(|&a| a as f64).sum::<f64>();
        let alpha_ratio = mean_alpha(&fin) / (0.5 * (mean_alpha(&r1) + mean_alpha(&r2)));
        println!(
            "{name}: single scattering rel RMSE {rmse:.3} (reference noise {noise:.3}), mean \
             ratio {ratio:.3}; the sun's alone {sun_rmse:.3}, {sun_ratio:.3}; coverage ratio \
             {alpha_ratio:.4}"
        );
        // Measured: side 0.143 / 1.054, behind 0.204 / 1.046, above 0.144 / 1.046 (the light
        // grid's shadows and one ray a pixel against the box filter's average are most of the
        // per-pixel figure); coverage 0.996.
        assert!(
            (ratio - 1.0).abs() < 0.08,
            "{name}: single scattering mean ratio {ratio}"
        );
        assert!(rmse < 0.27, "{name}: single scattering per pixel {rmse}");
        assert!(
            (alpha_ratio - 1.0).abs() < 0.02,
            "{name}: coverage ratio {alpha_ratio}"
        );
    }
}

#[test]
fn reference_is_deterministic() {
    let blobs = cloud();
    let s = {
        let mut s = lit(LIGHTS[0].1, reference(4, 0));
        (s.width, s.height) = (48, 27);
        s
    };
    let render = |threads: usize, s: &RenderSettings| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| with_passes(s, &blobs))
    };
    let bits = |f: &Frame| {
        let p = f.passes.as_ref().unwrap();
        let mut v: Vec<u32> = f.rgb.iter().flatten().map(|x| x.to_bits()).collect();
        v.extend(f.alpha.iter().map(|x| x.to_bits()));
        v.extend(f.depth.iter().map(|x| x.to_bits()));
        v.extend(p.multiple.iter().flatten().map(|x| x.to_bits()));
        v
    };
    let one = render(1, &s);
    let two = render(2, &s);
    assert!(one.alpha.iter().any(|&a| a > 0.5), "the cloud is in view");
    assert_eq!(bits(&one), bits(&two), "1 and 2 threads differ");
    // Another path seed draws other paths (same cloud: the billows follow the scene's seed).
    let mut other = s.clone();
    other.quality = reference(4, 9);
    assert_ne!(bits(&one), bits(&render(2, &other)));
    // The density evaluations a path takes, for the record.
    let m = BlobMedium::new(&s, &blobs);
    let (_, stats) = render_path_traced(&s, &m, &Film::default());
    println!(
        "{} paths: {:.1} collisions, {:.1} rays, {:.1} density evaluations a path",
        stats.paths,
        stats.collisions as f64 / stats.paths as f64,
        stats.rays as f64 / stats.paths as f64,
        stats.evaluations as f64 / stats.paths as f64
    );
    assert!(stats.paths == 48 * 27 * 4 && stats.evaluations > stats.collisions);
}
