//! Nephele against Mitsuba 3 (a physically based volumetric path tracer) on the same density
//! grid, camera, sun and sky: single scattering (`volpath`, `max_depth` 2) and full transport.
//!
//! The grid is the volume export's (`nephele::export::grid::sample_medium` through the frame's
//! `Medium`, written by `export::vol::write_vol` as Mitsuba's `.vol`). Nephele renders the
//! frame itself (from the blobs, as in production: "end to end") and also marches that very
//! grid (`mitsuba_support/grid_medium.rs`: "same grid", the light transport alone);
//! `tools/mitsuba_compare.py` renders the grid in Mitsuba and prints the comparison.
//!
//! Always-run test: a small comparison when Python with `mitsuba` is importable (set
//! `NEPHELE_PYTHON` to pick the interpreter; `.ci/run` makes `target/mitsuba-venv`), otherwise
//! it prints that it skipped, or fails under `NEPHELE_REQUIRE_READERS=1` (`readers_support`).
//! Full comparison (documented in docs/MEASUREMENTS.md, "Checked against Mitsuba 3"):
//! `cargo test --release --test it -- --ignored --nocapture mitsuba::mitsuba_full`
//! with optional `NEPHELE_MITSUBA_SCENE=scenes/x.ron NEPHELE_MITSUBA_FRAME=n` (default: the
//! duck's last frame), `NEPHELE_MITSUBA_SPP`, `NEPHELE_MITSUBA_GRID` (cells along the cloud's
//! longest side, 1,024, fewer where a `.vol` file's 2²⁸ voxels cannot hold them),
//! `NEPHELE_MITSUBA_DIR` (under the temp dir), `NEPHELE_MITSUBA_REUSE` (reuse its Mitsuba
//! renders), `NEPHELE_MITSUBA_ONLY_SS`. Diagnosis: `NEPHELE_MITSUBA_QUALITY=grid,step,rays[,coarse[,edge[,cell_px]]]`
//! overrides the quality, `NEPHELE_MITSUBA_BLACK_SKY` lights by the sun alone,
//! `NEPHELE_MITSUBA_EXACT` marches the same-grid image's light depths exactly (minutes; `=N`
//! averages each sky cell's transmittance over N directions across it),
//! `NEPHELE_MITSUBA_EXACT_SUN` the end-to-end single-scattering image's depth toward the sun
//! (through the exported grid; a minute): what the light grid's resolution costs.
//! `NEPHELE_MITSUBA_REFERENCE=spp` also renders nephele's `quality: Reference` (its path
//! tracer, max depth 64, two path seeds) through the blobs and through the exported grid, and
//! the script compares it with Mitsuba's full transport (`ref_*` keys; with
//! `NEPHELE_MITSUBA_REFERENCE_DEPTH=2`, single scattering against Mitsuba's `max_depth` 2).
//!
//! The phase function Mitsuba renders with is the script's `TwoLobe`, not Mitsuba's
//! `blendphase`: Mitsuba 3.6.4's `blendphase` returns the picked lobe's pdf from `sample`, so
//! its MIS with the envmap over-counts the sky's light (a slab under a constant sky: 1.20–1.39×
//! the closed form; `tools/mitsuba_compare.py`'s doc). Figures measured before 2026-12-06
//! evening were against that biased reference; `NEPHELE_MITSUBA_BLENDPHASE` renders with it
//! again (and reuses the renders made with it).
//!
//! The plate's light (`environment_single_scattering_matches_mitsuba`, always run): a test EXR
//! as the sky, the same file for Mitsuba's `envmap`. `NEPHELE_MITSUBA_ENV_SIZE=640` runs it at
//! 640×360, `NEPHELE_MITSUBA_ENV_CELLS` leaves the bright patch in the sky cells (no
//! `sun_from_map`), `NEPHELE_MITSUBA_ENV_PATCH=0` drops it, `NEPHELE_MITSUBA_ENV_ANALYTIC` lights
//! by an analytic gradient sky instead, `NEPHELE_MITSUBA_BILLOWS` keeps the billows, `NEPHELE_MITSUBA_KEEP` leaves
//! its folder (printed) for `tools/mitsuba_compare.py --reuse`, `NEPHELE_MITSUBA_THIN=k` scales
//! the grid's density by `k` (≪ 1: the sky's light with almost nothing in the way).

#[path = "mitsuba_support/grid_medium.rs"]
mod grid_medium;

use crate::readers_support::skip_or_fail;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use nephele::render::CameraRays;
use nephele::render::phase::{BACK_LOBE_RATIO, BACK_LOBE_WEIGHT};
use nephele::render::{
    BlobMedium, Film, LightGrid, PathTracing, RenderSettings, SkyDome, render_medium,
    render_path_traced,
};
use nephele::scene::{RenderOptions, Shot, load_scene};

/// The Python interpreter with mitsuba and numpy: `$NEPHELE_PYTHON`, the venv `.ci/run` makes
/// in `target/mitsuba-venv`, `/tmp/mi/bin/python` or `python3`, the first that imports them;
/// `None` (after [`skip_or_fail`]) when none does.
fn python() -> Option<String> {
    let venv = repo().join("target/mitsuba-venv/bin/python");
    let candidates = std::env::var("NEPHELE_PYTHON").ok().into_iter().chain([
        venv.to_string_lossy().into_owned(),
        "/tmp/mi/bin/python".to_string(),
        "python3".to_string(),
    ]);
    let found = candidates.into_iter().find(|p| {
        Command::new(p)
            .args(["-c", "import mitsuba, numpy"])
            .output()
            .is_ok_and(|o| o.status.success())
    });
    if found.is_none() {
        skip_or_fail(
            "Mitsuba",
            "no Python with `mitsuba` and `numpy` (`python3 -m venv target/mitsuba-venv && \
             target/mitsuba-venv/bin/pip install mitsuba numpy`, as .ci/run does; \
             NEPHELE_PYTHON selects the interpreter)",
        );
    }
    found
}

fn write_f32(path: &Path, v: impl IntoIterator<Item = f32>) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for x in v {
        f.write_all(&x.to_le_bytes()).unwrap();
    }
}

/// Nephele's frame composited over the sky, linear RGB, row-major, and its alpha.
fn composite(s: &RenderSettings, f: &nephele::render::Frame) -> Vec<f32> {
    let cam = CameraRays::new(&s.camera, s.width, s.height);
    let dome = SkyDome::new(&s.sky, &s.sun);
    let mut out = Vec::with_capacity(f.rgb.len() * 4);
    for y in 0..s.height {
        for x in 0..s.width {
            let i = (y * s.width + x) as usize;
            // The sky over the pixel's area (4×4 rays), as Mitsuba's box filter sees it: at
            // the horizon one ray per pixel is a step that the reference does not have.
            let mut sky = glam::Vec3::ZERO;
            for k in 0..16 {
                let (u, v) = ((k % 4) as f32 + 0.5, (k / 4) as f32 + 0.5);
                let ray = cam.ray(x as f32 + u / 4.0, y as f32 + v / 4.0);
                sky += dome.radiance(ray.dir.into()) / 16.0;
            }
            let a = f.alpha[i];
            for c in 0..3 {
                out.push(f.rgb[i][c] + (1.0 - a) * sky[c]);
            }
            out.push(a);
        }
    }
    out
}

/// The sky as a lat-long map in Mitsuba's `envmap` convention: texel `(u, v)` looks along
/// `(sin θ sin φ, cos θ, −sin θ cos φ)` with `φ = 2πu`, `θ = πv`.
fn sky_map(s: &RenderSettings, w: usize, h: usize) -> Vec<f32> {
    let dome = SkyDome::new(&s.sky, &s.sun);
    let mut out = Vec::with_capacity(w * h * 3);
    for j in 0..h {
        let theta = std::f32::consts::PI * (j as f32 + 0.5) / h as f32;
        for i in 0..w {
            let phi = 2.0 * std::f32::consts::PI * (i as f32 + 0.5) / w as f32;
            let d = glam::Vec3::new(
                theta.sin() * phi.sin(),
                theta.cos(),
                -theta.sin() * phi.cos(),
            );
            out.extend(dome.radiance(d).to_array());
        }
    }
    out
}

/// Write the comparison inputs for frame `frame` (1-based; `None` = the shot's last frame) of
/// `scene` into `dir`; returns
/// nephele's seconds per frame (single scattering, multiple-scattering approximation).
fn write_inputs(
    scene: &Path,
    frame: Option<u32>,
    size: (u32, u32),
    grid_res: u32,
    dir: &Path,
) -> (f64, f64) {
    write_inputs_with(
        scene,
        frame,
        size,
        grid_res,
        dir,
        reference_from_env(),
        &|_| {},
    )
}

/// nephele's image of the frame `s` (the blobs' own density and light grid; with `exact_sun`,
/// the sun's depths marched through that grid) into `nephele_ms.f32` or `nephele_ss.f32` in
/// `dir`, as `s.cloud.multiple_scattering` says. Returns the render's seconds.
fn render_nephele(
    s: &RenderSettings,
    blobs: &[nephele::blobby::Blob],
    exact_sun: Option<&grid_medium::DenseGrid>,
    dir: &Path,
) -> f64 {
    let start = Instant::now();
    let m = BlobMedium::new(s, blobs);
    let lg = LightGrid::for_frame(s, &m.for_light_grid(s));
    let f = match exact_sun {
        Some(grid) => {
            let l = grid_medium::ExactSun {
                grid,
                sun_dir: s.sun.travel_dir().into(),
                base: &lg,
            };
            render_medium(s, &m, &l, &Film::default())
        }
        None => render_medium(s, &m, &lg, &Film::default()),
    };
    let seconds = start.elapsed().as_secs_f64();
    let name = if s.cloud.multiple_scattering {
        "nephele_ms.f32"
    } else {
        "nephele_ss.f32"
    };
    write_f32(&dir.join(name), composite(s, &f));
    seconds
}

/// [`write_inputs`] with the frame's settings changed by `adjust` (an `Environment` sky is
/// passed to Mitsuba as its file, with its rotation and intensity).
fn write_inputs_with(
    scene: &Path,
    frame: Option<u32>,
    size: (u32, u32),
    grid_res: u32,
    dir: &Path,
    reference: Option<(u32, u32)>,
    adjust: &dyn Fn(&mut RenderSettings),
) -> (f64, f64) {
    let mut scene = load_scene(scene).unwrap();
    (scene.file.shot.width, scene.file.shot.height) = size;
    let opts = RenderOptions {
        output: Some(std::env::temp_dir().join("nephele-mitsuba-cache")),
        ..RenderOptions::default()
    };
    let shot = Shot::open(scene, &opts).unwrap();
    let k = shot.index(frame.unwrap_or(shot.total()));
    let blobs = shot.blobs(k).unwrap();
    let mut s = shot.settings(k).unwrap();
    if let Ok(q) = std::env::var("NEPHELE_MITSUBA_QUALITY") {
        // Experiments: "shadow_grid,optical_step,samples[,step_scale[,edge_samples[,cell_px]]]".
        let v: Vec<f32> = q.split(',').map(|x| x.parse().unwrap()).collect();
        s.quality.shadow_grid = v[0] as u32;
        s.quality.optical_step = v[1];
        s.quality.samples = v[2] as u32;
        if let Some(&step) = v.get(3) {
            s.quality.step_scale = step;
        }
        if let Some(&edge) = v.get(4) {
            s.quality.edge_samples = edge as u32;
        }
        if let Some(&cell) = v.get(5) {
            s.quality.shadow_cell_pixels = cell;
        }
    }
    if std::env::var("NEPHELE_MITSUBA_BLACK_SKY").is_ok() {
        // Not exactly 0: Mitsuba's envmap sampling needs some light.
        s.sky = nephele::render::Sky::Gradient {
            zenith: glam::Vec3::splat(1e-4),
            horizon: glam::Vec3::splat(1e-4),
        };
    }
    adjust(&mut s);
    std::fs::create_dir_all(dir).unwrap();
    // NEPHELE_MITSUBA_MS_ONLY (experiments on the multiple scattering, with a folder of an
    // earlier run): only nephele's full image is rendered again; the grid and the rest are kept.
    if std::env::var("NEPHELE_MITSUBA_MS_ONLY").is_ok() && dir.join("grid.vol").exists() {
        s.cloud.multiple_scattering = true;
        return (0.0, render_nephele(&s, &blobs, None, dir));
    }
    // The grid the volume export writes (`nephele::export`), sampled through the `Medium`.
    let m = BlobMedium::new(&s, &blobs);
    let (lo, hi) = m.bounds().expect("a live cloud");
    let mut voxel = ((hi - lo).max_element() / grid_res as f32) as f64;
    // As fine as asked, or as a `.vol` file holds (a wide cloud's box at 1,024 cells does not
    // fit its 2²⁸ voxels): the reference's grid is what limits how well it rebuilds the rim.
    let grid = loop {
        let grid = nephele::export::grid::sample_medium(&m, lo, hi, voxel).unwrap();
        let count = nephele::export::vol::vol_voxels(&grid);
        let max = nephele::export::vol::MAX_VOL_VOXELS;
        if count <= max {
            break grid;
        }
        voxel *= (count as f64 / max as f64).cbrt() * 1.01;
        eprintln!(
            "{count} voxels do not fit a .vol file: {:.0} cells instead of {grid_res}",
            (hi - lo).max_element() as f64 / voxel
        );
    };
    let mut grid = grid;
    // Diagnosis: NEPHELE_MITSUBA_THIN=k scales the grid's density (the same-grid image and
    // Mitsuba's): k ≪ 1 compares the light the sky sends with almost nothing in the way.
    if let Some(k) = std::env::var("NEPHELE_MITSUBA_THIN")
        .ok()
        .and_then(|v| v.parse::<f32>().ok())
    {
        for leaf in &mut grid.leaves {
            for v in leaf.values.iter_mut() {
                *v *= k;
            }
        }
    }
    let grid_cells = ((hi - lo).max_element() as f64 / voxel).round();
    nephele::export::vol::write_vol(&dir.join("grid.vol"), &grid).unwrap();
    let mut times = [0.0; 2];
    let dense = grid_medium::DenseGrid::new(&grid);
    for (idx, ms) in [(0, false), (1, true)] {
        s.cloud.multiple_scattering = ms;
        let exact_sun =
            (!ms && std::env::var("NEPHELE_MITSUBA_EXACT_SUN").is_ok()).then_some(&dense);
        times[idx] = render_nephele(&s, &blobs, exact_sun, dir);
    }
    // The light transport alone: nephele's integrator on Mitsuba's very grid, with a light grid
    // of the frame's quality (or, with NEPHELE_MITSUBA_EXACT, depths marched exactly: slow).
    s.cloud.multiple_scattering = false;
    let light_dir: glam::Vec3A = s.sun.travel_dir().into();
    let same_grid = if let Ok(exact) = std::env::var("NEPHELE_MITSUBA_EXACT") {
        // NEPHELE_MITSUBA_EXACT=N (N > 1): each sky cell's transmittance averaged over N
        // directions spread over it (what the cell's one direction stands for).
        let lights = match exact.parse::<usize>() {
            Ok(n) if n > 1 => grid_medium::ExactLights::cell_mean(&dense, light_dir, n),
            _ => grid_medium::ExactLights::new(&dense, light_dir),
        };
        render_medium(&s, &dense, &lights, &Film::default())
    } else {
        let lights = LightGrid::build(&dense, light_dir, s.quality.shadow_grid);
        render_medium(&s, &dense, &lights, &Film::default())
    };
    write_f32(&dir.join("nephele_grid_ss.f32"), composite(&s, &same_grid));
    if let Some((spp, max_depth)) = reference {
        write_reference(&s, &blobs, &dense, spp, max_depth, dir);
    }
    // The sky map's texels no larger than the frame's pixels: Mitsuba interpolates the map
    // bilinearly, and a 256-row map blurred the horizon over ±7 pixels at 640×360 — behind the
    // cloud's lower fringe that was 1.0 point of the backlit shot's 6.1 % (the blur is the
    // reference's, not nephele's).
    let sh = ((180.0 * s.height as f32 / s.camera.fov_deg).ceil() as usize)
        .next_power_of_two()
        .clamp(256, 2048);
    let sw = 2 * sh;
    write_f32(&dir.join("sky.f32"), sky_map(&s, sw, sh));
    let sun_dir = s.sun.travel_dir();
    let tint = SkyDome::sun_tint(&s.sky, &s.sun);
    let mut irr = s.sun.color * s.sun.intensity * tint;
    if let nephele::render::Sky::Environment(_) = &s.sky {
        // The map holds all the light for Mitsuba, a sun split off it (`sun_from_map`) too.
        irr = glam::Vec3::ZERO;
    }
    let v = |v: glam::Vec3| format!("[{}, {}, {}]", v.x, v.y, v.z);
    let envmap = match &s.sky {
        nephele::render::Sky::Environment(env) => format!(
            r#""envmap": {{"file": {:?}, "rotate_deg": {}, "intensity": {}}},"#,
            env.file, env.rotate_deg, env.intensity
        ),
        _ => String::new(),
    };
    let meta = format!(
        r#"{{{envmap}"width": {}, "height": {}, "position": {}, "look_at": {}, "up": {}, "fov_deg": {},
"sun_dir": {}, "sun_irradiance": {}, "albedo": {}, "g": {}, "back_weight": {}, "back_ratio": {},
"sky_size": [{sw}, {sh}], "grid_cells": {grid_cells},
"exposure": {}, "nephele_seconds_ss": {}, "nephele_seconds_ms": {}}}"#,
        s.width,
        s.height,
        v(s.camera.position),
        v(s.camera.look_at),
        v(s.camera.up),
        s.camera.fov_deg,
        v(sun_dir),
        v(irr),
        s.cloud.albedo,
        s.cloud.phase_g,
        BACK_LOBE_WEIGHT,
        BACK_LOBE_RATIO,
        s.exposure,
        times[0],
        times[1],
    );
    std::fs::write(dir.join("meta.json"), meta).unwrap();
    (times[0], times[1])
}

/// `NEPHELE_MITSUBA_REFERENCE=spp` (and `NEPHELE_MITSUBA_REFERENCE_DEPTH`, default 64): the
/// Reference render [`write_inputs`] adds, `(spp, max_depth)`.
fn reference_from_env() -> Option<(u32, u32)> {
    let spp = std::env::var("NEPHELE_MITSUBA_REFERENCE")
        .ok()?
        .parse()
        .ok()?;
    // NEPHELE_MITSUBA_REFERENCE_DEPTH=2: single scattering, against Mitsuba's `max_depth` 2.
    let max_depth = std::env::var("NEPHELE_MITSUBA_REFERENCE_DEPTH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64);
    Some((spp, max_depth))
}

/// Nephele's `quality: Reference` of the frame (the path tracer, `max_depth`, `spp` paths a
/// pixel), composited over the sky as the other frames: through the blobs' own density
/// (`nephele_ref.f32`, a second path seed `nephele_ref2.f32`) and through the exported grid
/// Mitsuba renders (`nephele_grid_ref.f32`, `nephele_grid_ref2.f32`: the light transport
/// alone); the seconds and the work of the first in `reference.json`.
fn write_reference(
    s: &RenderSettings,
    blobs: &[nephele::blobby::Blob],
    dense: &grid_medium::DenseGrid,
    spp: u32,
    max_depth: u32,
    dir: &Path,
) {
    let mut s = s.clone();
    s.cloud.multiple_scattering = true;
    let medium = BlobMedium::new(&s, blobs);
    let mut record = format!(r#"{{"max_depth": {max_depth}, "#);
    for (name, seed) in [("ref", 0), ("ref2", 1)] {
        s.quality.reference = Some(PathTracing {
            samples: spp,
            max_depth,
            seed,
        });
        let start = Instant::now();
        let (f, stats) = render_path_traced(&s, &medium, &Film::default());
        let seconds = start.elapsed().as_secs_f64();
        write_f32(&dir.join(format!("nephele_{name}.f32")), composite(&s, &f));
        let (g, _) = render_path_traced(&s, dense, &Film::default());
        write_f32(
            &dir.join(format!("nephele_grid_{name}.f32")),
            composite(&s, &g),
        );
        if seed == 0 {
            record += &format!(
                r#""spp": {spp}, "seconds": {seconds:.2}, "paths": {}, "collisions": {}, "rays": {}, "evaluations": {}"#,
                stats.paths, stats.collisions, stats.rays, stats.evaluations
            );
            eprintln!("nephele Reference at {spp} spp: {seconds:.1} s, {stats:?}");
        }
    }
    record += "}";
    std::fs::write(dir.join("reference.json"), record).unwrap();
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Run the comparison script; returns its stdout (JSON).
fn compare(py: &str, dir: &Path, spp: u32, picture: Option<&Path>, reuse: bool) -> String {
    compare_with(py, dir, spp, picture, reuse, false)
}

/// [`compare`], with Mitsuba's full transport left out when `only_ss`.
fn compare_with(
    py: &str,
    dir: &Path,
    spp: u32,
    picture: Option<&Path>,
    reuse: bool,
    only_ss: bool,
) -> String {
    let mut cmd = Command::new(py);
    cmd.arg(repo().join("tools/mitsuba_compare.py"))
        .arg(dir)
        .args(["--spp", &spp.to_string()]);
    if let Some(p) = picture {
        cmd.arg("--picture").arg(p);
    }
    if reuse {
        cmd.arg("--reuse");
    }
    if only_ss || std::env::var("NEPHELE_MITSUBA_ONLY_SS").is_ok() {
        cmd.arg("--only-ss");
    }
    // Mitsuba's own `blendphase` (biased under MIS in 3.6.4: the module doc), to reproduce
    // figures measured before the script's `TwoLobe`.
    if std::env::var("NEPHELE_MITSUBA_BLENDPHASE").is_ok() {
        cmd.arg("--blendphase");
    }
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "mitsuba_compare.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn number(json: &str, key: &str) -> f64 {
    let at = json
        .find(&format!("\"{key}\""))
        .unwrap_or_else(|| panic!("{key} in {json}"));
    let rest = &json[at + key.len() + 3..];
    let end = rest.find([',', '}']).unwrap();
    rest[..end].trim().parse().unwrap()
}

#[test]
fn single_scattering_matches_mitsuba() {
    let Some(py) = python() else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("nephele-mitsuba-{}", std::process::id()));
    write_inputs(
        &repo().join("scenes/duck-diffusion.ron"),
        None,
        (160, 90),
        96,
        &dir,
    );
    let json = compare(&py, &dir, 64, None, false);
    eprintln!("{json}");
    // A small run (160×90, a 96-cell grid, 64 spp; the full one, docs/MEASUREMENTS.md, gives
    // the quoted figures). On the billowy density, against Mitsuba with the script's
    // `TwoLobe` phase function, it measures end to end 0.110, same grid 0.044, mean ratio
    // 0.995 (full image 0.105 per pixel, mean 1.006; Mitsuba 3.6.4) with the sky depths shifted
    // one light-grid cell (at two: 0.120, 0.054, 1.047, the sky term a few per cent bright);
    // 0.113, 0.043, 0.981 (full image 0.105, 1.004) with them stored as cube roots, unshifted.
    // Against the biased `blendphase` it had read 0.106, 0.018, 1.024. At 160×90 one ray a pixel
    // point-samples billows Mitsuba's box filter averages, most of the end-to-end figure. The
    // bars leave room for the reference's noise and catch a regression of the light model
    // (before the sky cells this run measured 0.205).
    let rmse = number(&json, "ss_rel_rmse");
    assert!(
        rmse < 0.15,
        "single scattering differs from Mitsuba by {rmse}"
    );
    let same = number(&json, "ss_same_grid_rel_rmse");
    assert!(same < 0.07, "same-grid single scattering differs by {same}");
    let ratio = number(&json, "ss_mean_ratio");
    assert!(
        (ratio - 1.0).abs() < 0.07,
        "single scattering mean ratio {ratio}"
    );
    let (ms, full) = (
        number(&json, "mean_lum_nephele_ms"),
        number(&json, "mean_lum_mitsuba_full"),
    );
    assert!(
        (ms / full - 1.0).abs() < 0.10,
        "MS mean luminance {ms} vs {full}"
    );
    let (bt, bt_full) = (
        number(&json, "base_top_nephele_ms"),
        number(&json, "base_top_mitsuba_full"),
    );
    assert!((bt - bt_full).abs() < 0.1, "base/top {bt} vs {bt_full}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The phase function Mitsuba renders with (`tools/mitsuba_compare.py --check-phase`): single
/// scattering of a semi-infinite slab under a constant sky, `volpath` at `max_depth` 2, against
/// the closed form at 0°, 45° and 70° from its normal. Measured 0.988, 0.992, 0.998 with the
/// script's `TwoLobe`; Mitsuba 3.6.4's own `blendphase` 1.393, 1.316, 1.200 (its MIS bias; the
/// reason for `TwoLobe`). Every comparison in this file is only as good as this.
#[test]
fn mitsuba_phase_function_matches_the_closed_form() {
    let Some(py) = python() else {
        return;
    };
    let out = Command::new(&py)
        .arg(repo().join("tools/mitsuba_compare.py"))
        .arg("--check-phase")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "mitsuba_compare.py --check-phase failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json = String::from_utf8_lossy(&out.stdout).into_owned();
    eprintln!("{json}");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    for (k, r) in v["twolobe"].as_array().unwrap().iter().enumerate() {
        let r = r.as_f64().unwrap();
        assert!(
            (r - 1.0).abs() < 0.03,
            "view {}: Mitsuba's single scattering over the closed form {r}",
            v["views_deg"][k]
        );
    }
}

/// The plate's light: a non-uniform lat-long EXR written by the test (a gradient sky over a
/// dark ground with a bright patch 20° high), turned by 60° about +Y, lights the duck alone
/// (its bright patch split off as the sun, `sun_from_map`); Mitsuba's `envmap` reads the same
/// file with `to_world = rotate(+Y, 60°)`, no sun. Single scattering on the same density.
#[test]
fn environment_single_scattering_matches_mitsuba() {
    let Some(py) = python() else {
        return;
    };
    // NEPHELE_MITSUBA_ENV_DIR: a fixed folder (under the temp dir) whose Mitsuba renders are
    // reused by the next run with the same one (experiments on nephele's side alone).
    let fixed = std::env::var("NEPHELE_MITSUBA_ENV_DIR").ok();
    let dir = std::env::temp_dir().join(
        fixed
            .clone()
            .unwrap_or_else(|| format!("nephele-mitsuba-env-{}", std::process::id())),
    );
    std::fs::create_dir_all(&dir).unwrap();
    let exr = dir.join("plate.exr");
    // Texel (x, y) at u = (x + ½)/W and θ = π·y/(H − 1), as Mitsuba evaluates the map.
    let (w, h) = (256, 128);
    // NEPHELE_MITSUBA_ENV_PATCH: the patch's brightness (default 6; 0: the gradient alone).
    let patch = std::env::var("NEPHELE_MITSUBA_ENV_PATCH")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(6.0);
    crate::environment::write_exr(&exr, w, h, |x, y| {
        let (u, v) = ((x as f32 + 0.5) / w as f32, y as f32 / (h - 1) as f32);
        crate::environment::test_map_with(u, v, patch)
    });
    // The bright patch as the sun (`sun_from_map`), or (NEPHELE_MITSUBA_ENV_CELLS) in the
    // sky cells with the rest of the map.
    let split = std::env::var("NEPHELE_MITSUBA_ENV_CELLS").is_err();
    let env = nephele::render::Environment::open(&exr, 60.0, 1.5, split).unwrap();
    let smooth = std::env::var("NEPHELE_MITSUBA_BILLOWS").is_err();
    // NEPHELE_MITSUBA_ENV_SIZE=640: the comparison at 640×360 on a 384-cell grid (minutes).
    let (size, cells) = match std::env::var("NEPHELE_MITSUBA_ENV_SIZE").as_deref() {
        Ok("640") => ((640, 360), 384),
        _ => ((160, 90), 96),
    };
    write_inputs_with(
        &repo().join("scenes/duck-diffusion.ron"),
        None,
        size,
        cells,
        &dir,
        // nephele's Reference at max depth 2 as well, the independent check of the set-up
        // (64 paths a pixel, or NEPHELE_MITSUBA_REFERENCE's).
        Some((reference_from_env().map_or(64, |(spp, _)| spp), 2)),
        &|s| {
            s.sky = nephele::render::Sky::Environment(env.clone());
            // Diagnosis: the same light from an analytic sky (through sky.f32 for Mitsuba).
            if std::env::var("NEPHELE_MITSUBA_ENV_ANALYTIC").is_ok() {
                s.sky = nephele::render::Sky::Gradient {
                    zenith: glam::Vec3::new(0.12, 0.25, 0.6) * 1.5,
                    horizon: glam::Vec3::new(0.55, 0.65, 0.8) * 1.5,
                };
            }
            s.sun = env.map_sun().unwrap_or(nephele::render::Sun {
                intensity: 0.0,
                ..s.sun
            });
            // Smooth blobs: at 160×90 one ray a pixel point-samples billows that Mitsuba's box
            // filter averages (most of the duck's end-to-end figure, `single_scattering_…`).
            if smooth {
                s.cloud.noise.octaves = 0;
            }
        },
    );
    let json = compare_with(&py, &dir, 256, None, fixed.is_some(), true);
    eprintln!("{json}\n(inputs in {})", dir.display());
    // Measured (docs/MEASUREMENTS.md, "The plate's light"), against Mitsuba with the
    // script's `TwoLobe` (the `blendphase` it used before over-counted the sky by 12–16 % on
    // this shot): nephele's Reference at max depth 2 — its own estimator of the same light, the
    // map sampled uniformly with MIS — same grid 0.994 in the mean, within both noises per
    // pixel (0.000; 0.14 and 0.09 noise), through the blobs 0.983 and 3.7 %. These check the
    // set-up (map convention, rotation, intensity, the sun split off it, the grid) tightly
    // (the map turned the other way for Mitsuba had moved the march's mean by 0.78×).
    let ref_same = number(&json, "ref_same_grid_rel_rmse");
    assert!(
        ref_same < 0.05,
        "Reference, same grid, per pixel {ref_same}"
    );
    let ref_same_ratio = number(&json, "ref_same_grid_mean_ratio");
    assert!(
        (ref_same_ratio - 1.0).abs() < 0.04,
        "Reference, same grid, mean ratio {ref_same_ratio}"
    );
    let ref_ratio = number(&json, "ref_mean_ratio");
    assert!(
        (ref_ratio - 1.0).abs() < 0.05,
        "Reference through the blobs, mean ratio {ref_ratio}"
    );
    // The march (`Final`) against it (the goal is 5 % per pixel): same grid 0.058 (mean 1.005),
    // end to end 0.124 (mean 0.966) at 160×90 with the sky depths stored as cube roots (0.071
    // and 0.145, means 1.040 and 1.007, shifted one light-grid cell as before; 0.132 and 0.275
    // at two cells; with the depths marched exactly the same grid reads 0.056: the 26 cells'
    // floor at this size, docs/MEASUREMENTS.md). The bars hold those figures × 1.2–1.25 and the
    // background: the shift of one cell back fails the same grid's.
    let same = number(&json, "ss_same_grid_rel_rmse");
    assert!(same < 0.07, "same-grid single scattering differs by {same}");
    let rmse = number(&json, "ss_rel_rmse");
    assert!(
        rmse < 0.155,
        "single scattering differs from Mitsuba by {rmse}"
    );
    let ratio = number(&json, "ss_mean_ratio");
    assert!((ratio - 1.0).abs() < 0.06, "mean ratio {ratio}");
    let bg = number(&json, "background_rel_error");
    assert!(bg < 0.01, "the background differs by {bg}");
    // NEPHELE_MITSUBA_KEEP: leave the folder for `tools/mitsuba_compare.py --reuse`.
    if std::env::var("NEPHELE_MITSUBA_KEEP").is_err() && fixed.is_none() {
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
#[ignore = "full comparison (minutes), see the module doc"]
fn mitsuba_full_comparison() {
    let Some(py) = python() else {
        return;
    };
    let scene = std::env::var("NEPHELE_MITSUBA_SCENE")
        .unwrap_or_else(|_| "scenes/duck-diffusion.ron".into());
    let frame = std::env::var("NEPHELE_MITSUBA_FRAME")
        .ok()
        .and_then(|v| v.parse().ok());
    let spp = std::env::var("NEPHELE_MITSUBA_SPP")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(256);
    let dir = std::env::temp_dir().join(
        std::env::var("NEPHELE_MITSUBA_DIR").unwrap_or_else(|_| "nephele-mitsuba-full".into()),
    );
    let grid_res = std::env::var("NEPHELE_MITSUBA_GRID")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1024);
    let (ss, ms) = write_inputs(&repo().join(&scene), frame, (640, 360), grid_res, &dir);
    eprintln!("nephele: single scattering {ss:.3} s, with the MS approximation {ms:.3} s");
    // The pictures of docs/MEASUREMENTS.md: renders/mitsuba-<scene>.png (the default scene's is
    // renders/mitsuba-comparison.png).
    let stem = Path::new(&scene)
        .file_stem()
        .map_or("scene".into(), |s| s.to_string_lossy().into_owned());
    let picture = repo().join(if stem == "duck-diffusion" {
        "renders/mitsuba-comparison.png".to_string()
    } else {
        format!("renders/mitsuba-{stem}.png")
    });
    let json = compare(
        &py,
        &dir,
        spp,
        Some(&picture),
        std::env::var("NEPHELE_MITSUBA_REUSE").is_ok(),
    );
    println!("{json}");
}
