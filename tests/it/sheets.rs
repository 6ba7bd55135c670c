//! Picture sheets of every builtin scene (docs/MEASUREMENTS.md, "The cloud look"; the README
//! shows some): an early, a middle and the final frame side by side in
//! `renders/sheet-<scene>.png`, and the golden-hour backlit frame `renders/duck-golden-hour.png`;
//! and the README's multiple-scattering sheet, `renders/sheet-multiple-scattering.png` (the
//! finished duck, golden hour and cumulus-to-duck: the octaves above, the fluence grid below)
//! and the directing sheet, `renders/sheet-directing.png` (a story, a drifting target, a bending
//! one: a row each, at 160×90).
//! Scenes whose target is unavailable (bunny and horse need `../shared/models`) are skipped with
//! a message. Re-run after changing the look or the animation:
//!
//! `cargo test --release --test it -- --ignored --nocapture sheets::` (`NEPHELE_SHEETS=a,b`: only those scenes)

use crate::builtin_scenes;

use std::path::Path;

use nephele::render::output;
use nephele::scene::{RenderOptions, Shot, load_scene};

/// The shot of `scene` (at `size`, or its own), or `None` with a message when its target is
/// unavailable.
fn open(scene: &Path, size: Option<(u32, u32)>) -> Option<Shot> {
    let mut scene = load_scene(scene)
        .map_err(|e| eprintln!("skipping: {e}"))
        .ok()?;
    if let Some(size) = size {
        (scene.file.shot.width, scene.file.shot.height) = size;
    }
    let opts = RenderOptions {
        output: Some(std::env::temp_dir().join("nephele-sheets")),
        ..RenderOptions::default()
    };
    let shot = Shot::open(scene, &opts).ok()?;
    shot.prepared()
        .map_err(|e| eprintln!("skipping: {e}"))
        .ok()?;
    Some(shot)
}

/// Frames `frames` (1-based, of the shot's total) of `shot`, tone-mapped as the PNG frames are.
fn frames(shot: &Shot, frames: &dyn Fn(u32) -> Vec<u32>) -> Vec<image::RgbImage> {
    frames(shot.total())
        .into_iter()
        .map(|f| {
            let k = shot.index(f);
            let s = shot.settings(k).unwrap();
            output::tonemapped(&shot.render_frame(k).unwrap(), &s)
        })
        .collect()
}

/// An early, a middle and the last frame of a shot of `n` frames.
fn early_middle_last(n: u32) -> Vec<u32> {
    vec![(n / 5).max(1), (n * 11 / 20).max(1), n]
}

/// `rows` of equal-sized pictures pasted into one sheet.
pub(crate) fn sheet(rows: &[Vec<image::RgbImage>]) -> image::RgbImage {
    let (w, h) = rows[0][0].dimensions();
    let cols = rows.iter().map(Vec::len).max().unwrap_or(0) as u32;
    let mut sheet = image::RgbImage::new(w * cols, h * rows.len() as u32);
    for (r, row) in rows.iter().enumerate() {
        for (c, img) in row.iter().enumerate() {
            let (x, y) = (c as u32 * w, r as u32 * h);
            image::imageops::replace(&mut sheet, img, x as i64, y as i64);
        }
    }
    sheet
}

/// [`sheet`] of `rows`, saved as `renders/<name>`.
fn save_sheet(name: &str, rows: &[Vec<image::RgbImage>]) {
    let sheet = sheet(rows);
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("renders")
        .join(name);
    sheet.save(&path).unwrap();
    println!("{}", path.display());
}

#[test]
#[ignore = "writes the picture sheets into renders/: see the module doc"]
fn sheets() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    // NEPHELE_SHEETS=a,b re-makes only those scenes' sheets (and not the golden-hour picture).
    let only = std::env::var("NEPHELE_SHEETS").ok();
    for name in builtin_scenes::NAMES {
        if only
            .as_ref()
            .is_some_and(|o| !o.split(',').any(|s| s == name))
        {
            continue;
        }
        let Some(shot) = open(&builtin_scenes::path(name), None) else {
            continue;
        };
        save_sheet(
            &format!("sheet-{name}.png"),
            &[frames(&shot, &early_middle_last)],
        );
    }
    if only.is_some() {
        return;
    }
    let golden = open(&repo.join("scenes/duck-golden-hour.ron"), None).unwrap();
    save_sheet("duck-golden-hour.png", &[frames(&golden, &|n| vec![n])]);
}

/// The last frame of each of `scenes`, rendered twice: with the octaves (`quality.ms_photons`
/// 0, what `Preview` uses) in the top row and as the scene asks (the fluence grid at `Final`
/// and `Production`) in the bottom row.
#[test]
#[ignore = "writes renders/sheet-multiple-scattering.png: see the module doc"]
fn multiple_scattering_sheet() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut rows: [Vec<image::RgbImage>; 2] = [Vec::new(), Vec::new()];
    for name in ["duck-diffusion", "duck-golden-hour", "cumulus-to-duck"] {
        let shot = open(&repo.join(format!("scenes/{name}.ron")), None).unwrap();
        let k = shot.index(shot.total());
        let blobs = shot.blobs(k).unwrap();
        let settings = shot.settings(k).unwrap();
        let mut octaves = settings.clone();
        octaves.quality.ms_photons = 0;
        for (row, s) in rows.iter_mut().zip([&octaves, &settings]) {
            row.push(output::tonemapped(
                &nephele::render::render_frame(s, &blobs),
                s,
            ));
        }
    }
    save_sheet("sheet-multiple-scattering.png", &rows);
}

/// A row per directing scene (a story of targets, a target that drifts, one that bends): an
/// early, a middle and the last frame at 160×90, as the scene renders them otherwise.
#[test]
#[ignore = "writes renders/sheet-directing.png: see the module doc"]
fn directing_sheet() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let rows: Vec<_> = ["cumulus-duck-torus-knot", "duck-drift", "waving-tube"]
        .iter()
        .map(|name| {
            let path = repo.join(format!("scenes/{name}.ron"));
            frames(&open(&path, Some((160, 90))).unwrap(), &early_middle_last)
        })
        .collect();
    save_sheet("sheet-directing.png", &rows);
}
