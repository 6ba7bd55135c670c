//! Look at the renderer by eye: a few frames of the renderer tests' 400-blob cloud (or the
//! fitted builtin duck) written as PNG, with the luminance of their opaque pixels printed.
//! Nothing is checked: the tests in `tests/it/render.rs` do that; this is for a person.
//!
//! ```text
//! cargo run --release --example render_look -- WHAT [OUT_DIR]
//! ```
//!
//! `OUT_DIR` defaults to `/tmp/nephele-look`. `WHAT` is one of
//!
//! - `cloud`: the cloud at 640×360 lit from the upper left (`front.png`), seen toward the sun
//!   (`against_sun.png`: the silver lining), and a 256×256 preview (`preview.png`);
//! - `duck`: `builtin:duck` fitted with 300 blobs (cached as `duck.ron` in `OUT_DIR`) at 480×320,
//!   from the front (`duck.png`, with the render time) and the back (`duck_back.png`);
//! - `debug`: the lighting's parts — one round blob lit from the side by the sun alone with
//!   single scattering (`sphere.png`), the cloud by the sky alone (`amb.png`), by the sun alone
//!   (`sun.png`), by the sun alone with single scattering (`sun1.png`), and with 2 and 3
//!   multiple-scattering octaves (`oct2.png`, `oct3.png`);
//! - `light`: no picture: the light grid's optical depths along the cloud's x axis, printed.
//!
//! The cloud and its settings are the renderer tests' own (`src/render/fixture.rs`, included
//! by path as the tests include it): the same blobs for the same `n` and seed.

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use glam::{DQuat, DVec3, Vec3, Vec3A};
use nephele::blobby::Blob;
use nephele::render::{
    BlobMedium, Camera, CloudMaterial, Frame, LightGrid, Quality, RenderSettings, ShadowDepths,
    Sky, Sun, output, render_frame,
};

// The renderer tests' cloud and the settings that frame it, the very file the tests include.
#[allow(dead_code)]
#[path = "../src/render/fixture.rs"]
mod fixture;
use fixture::{settings, test_cloud};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: render_look cloud|duck|debug|light [OUT_DIR]";
    let (what, dir) = match args.as_slice() {
        [what] => (what.as_str(), PathBuf::from("/tmp/nephele-look")),
        [what, dir] => (what.as_str(), PathBuf::from(dir)),
        _ => bail!("{usage}"),
    };
    match what {
        "cloud" => cloud(&dir),
        "duck" => duck(&dir),
        "debug" => debug(&dir),
        "light" => light(),
        _ => bail!("{usage}"),
    }
}

/// Writes `frame` as `dir/name` (tone-mapped with `s`) and says so.
fn save(dir: &Path, name: &str, frame: &Frame, s: &RenderSettings) -> anyhow::Result<()> {
    let path = dir.join(name);
    output::write_png(&path, frame, s).with_context(|| format!("writing {}", path.display()))?;
    eprintln!("{}", path.display());
    Ok(())
}

/// The cloud from the front, toward the sun, and as a preview.
fn cloud(dir: &Path) -> anyhow::Result<()> {
    let blobs = test_cloud(400, 11);
    let mut s = settings(640, 360, Quality::final_frame());
    // Sun from the upper left, a little in front of the cloud.
    s.sun.direction = Vec3::new(0.75, -0.6, 0.05);
    let f = render_frame(&s, &blobs);
    save(dir, "front.png", &f, &s)?;
    println!("front {}", lum_stats(&f));
    // Looking toward the sun: silver lining.
    let mut back = s.clone();
    back.camera.position = Vec3::new(-2.2, 1.4, -3.4);
    let f = render_frame(&back, &blobs);
    save(dir, "against_sun.png", &f, &back)?;
    let mut p = settings(256, 256, Quality::preview());
    p.sun = s.sun;
    let f = render_frame(&p, &blobs);
    save(dir, "preview.png", &f, &p)
}

/// The fitted builtin duck from the front (timed) and the back.
fn duck(dir: &Path) -> anyhow::Result<()> {
    let cache = dir.join("duck.ron");
    let model = match nephele::blobby::load_model(&cache) {
        Ok(m) => m,
        Err(_) => {
            let mesh = nephele::mesh::load("builtin:duck")?;
            let cfg = nephele::pipeline::FitConfig {
                blobs: 300,
                ..Default::default()
            };
            let m = nephele::pipeline::fit(&cfg, &mesh)?.model;
            nephele::blobby::save_model(&cache, &m)?;
            m
        }
    };
    println!("duck: {} live blobs", model.live_count());
    let mut s = settings(480, 320, Quality::final_frame());
    s.length_scale = model.source.bounds.diagonal() as f32;
    s.camera.position = Vec3::new(2.2, 1.2, 3.6);
    s.camera.look_at = Vec3::new(0.0, 0.0, 0.0);
    s.sun.direction = Vec3::new(0.8, -0.6, -0.2);
    let t = std::time::Instant::now();
    let f = render_frame(&s, &model.blobs);
    let secs = t.elapsed().as_secs_f64();
    println!("duck final {secs:.3} s, {}", lum_stats(&f));
    save(dir, "duck.png", &f, &s)?;
    s.camera.position = Vec3::new(2.5, 0.6, -3.4);
    let f = render_frame(&s, &model.blobs);
    save(dir, "duck_back.png", &f, &s)
}

/// The lighting's parts, one at a time.
fn debug(dir: &Path) -> anyhow::Result<()> {
    let blob = Blob {
        center: DVec3::new(0.0, 0.1, 0.0),
        rotation: DQuat::IDENTITY,
        semi_axes: DVec3::splat(0.8),
        a: 1.0,
        b: 2.0,
    };
    let black = Sky::Gradient {
        zenith: Vec3::ZERO,
        horizon: Vec3::ZERO,
    };
    let mut p = settings(
        256,
        256,
        Quality {
            ms_octaves: 1,
            ..Quality::final_frame()
        },
    );
    p.sun.direction = Vec3::new(1.0, 0.0, 0.0);
    p.sky = black.clone();
    let f = render_frame(&p, &[blob]);
    println!("sphere {}", lum_stats(&f));
    save(dir, "sphere.png", &f, &p)?;
    let blobs = test_cloud(400, 11);
    let mut s = settings(320, 180, Quality::final_frame());
    s.sun.direction = Vec3::new(0.75, -0.6, 0.05);
    let mut a = s.clone();
    a.sun.intensity = 0.0;
    let f = render_frame(&a, &blobs);
    println!("ambient only {}", lum_stats(&f));
    save(dir, "amb.png", &f, &a)?;
    let mut b = s.clone();
    b.sky = black;
    let f = render_frame(&b, &blobs);
    println!("sun only {}", lum_stats(&f));
    save(dir, "sun.png", &f, &b)?;
    b.quality.ms_octaves = 1;
    let f = render_frame(&b, &blobs);
    println!("sun single {}", lum_stats(&f));
    save(dir, "sun1.png", &f, &b)?;
    for oct in [2, 3] {
        let mut c = s.clone();
        c.quality.ms_octaves = oct;
        let f = render_frame(&c, &blobs);
        println!("full {oct} octaves {}", lum_stats(&f));
        save(dir, &format!("oct{oct}.png"), &f, &c)?;
    }
    Ok(())
}

/// The light grid's optical depths through the cloud's middle.
fn light() -> anyhow::Result<()> {
    let blobs = test_cloud(400, 11);
    let mut s = settings(640, 360, Quality::final_frame());
    s.sun.direction = Vec3::new(0.75, -0.6, 0.05);
    let m = BlobMedium::new(&s, &blobs);
    let g = LightGrid::for_frame(&s, &m).context("the cloud is empty")?;
    for x in [-1.2f32, -0.9, -0.6, -0.3, 0.0, 0.3, 0.6, 0.9] {
        println!("x {x}: {:?}", g.depths(Vec3A::new(x, 0.0, 0.0)));
    }
    Ok(())
}

/// The 5th, 50th and 95th percentiles of the luminance of the opaque pixels (alpha > 0.99).
fn lum_stats(f: &Frame) -> String {
    let mut lum: Vec<f32> = (0..f.alpha.len())
        .filter(|&i| f.alpha[i] > 0.99)
        .map(|i| 0.2126 * f.rgb[i][0] + 0.7152 * f.rgb[i][1] + 0.0722 * f.rgb[i][2])
        .collect();
    if lum.is_empty() {
        return "no opaque pixels".into();
    }
    lum.sort_by(f32::total_cmp);
    let q = |p: f32| lum[((lum.len() - 1) as f32 * p) as usize];
    format!(
        "opaque luminance p5 {:.3} p50 {:.3} p95 {:.3}",
        q(0.05),
        q(0.5),
        q(0.95)
    )
}
