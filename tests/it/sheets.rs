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

/// Frames `frames` (1-based) of `scene`, tone-mapped as the PNG frames are.
fn frames(scene: &Path, frames: &dyn Fn(u32) -> Vec<u32>) -> Option<Vec<image::RgbImage>> {
    let scene = load_scene(scene)
        .map_err(|e| eprintln!("skipping: {e}"))
        .ok()?;
    let opts = RenderOptions {
        output: Some(std::env::temp_dir().join("nephele-sheets")),
        ..RenderOptions::default()
    };
    let shot = Shot::open(scene, &opts).ok()?;
    shot.prepared()
        .map_err(|e| eprintln!("skipping: {e}"))
        .ok()?;
    Some(
        frames(shot.total())
            .into_iter()
            .map(|f| {
                let k = shot.index(f);
                let s = shot.settings(k).unwrap();
                output::tonemapped(&shot.render_frame(k).unwrap(), &s)
            })
            .collect(),
    )
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
        let pick = |n: u32| vec![(n / 5).max(1), (n * 11 / 20).max(1), n];
        let Some(images) = frames(&builtin_scenes::path(name), &pick) else {
            continue;
        };
        let (w, h) = images[0].dimensions();
        let mut sheet = image::RgbImage::new(w * images.len() as u32, h);
        for (i, img) in images.iter().enumerate() {
            image::imageops::replace(&mut sheet, img, (i as u32 * w) as i64, 0);
        }
        let path = repo.join(format!("renders/sheet-{name}.png"));
        sheet.save(&path).unwrap();
        println!("{}", path.display());
    }
    if only.is_some() {
        return;
    }
    let golden = frames(&repo.join("scenes/duck-golden-hour.ron"), &|n| vec![n]).unwrap();
    let path = repo.join("renders/duck-golden-hour.png");
    golden[0].save(&path).unwrap();
    println!("{}", path.display());
}

/// The last frame of each of `scenes`, rendered twice: with the octaves (`quality.ms_photons`
/// 0, what `Preview` uses) in the top row and as the scene asks (the fluence grid at `Final`
/// and `Production`) in the bottom row.
#[test]
#[ignore = "writes renders/sheet-multiple-scattering.png: see the module doc"]
fn multiple_scattering_sheet() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes = ["duck-diffusion", "duck-golden-hour", "cumulus-to-duck"];
    let mut rows: [Vec<image::RgbImage>; 2] = [Vec::new(), Vec::new()];
    for name in scenes {
        let scene = load_scene(&repo.join(format!("scenes/{name}.ron"))).unwrap();
        let opts = RenderOptions {
            output: Some(std::env::temp_dir().join("nephele-sheets")),
            ..RenderOptions::default()
        };
        let shot = Shot::open(scene, &opts).unwrap();
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
    let (w, h) = rows[0][0].dimensions();
    let mut sheet = image::RgbImage::new(w * scenes.len() as u32, 2 * h);
    for (r, row) in rows.iter().enumerate() {
        for (i, img) in row.iter().enumerate() {
            image::imageops::replace(
                &mut sheet,
                img,
                (i as u32 * w) as i64,
                (r as u32 * h) as i64,
            );
        }
    }
    let path = repo.join("renders/sheet-multiple-scattering.png");
    sheet.save(&path).unwrap();
    println!("{}", path.display());
}

/// A row per directing scene (a story of targets, a target that drifts, one that bends): an
/// early, a middle and the last frame at 160×90, as the scene renders them otherwise.
#[test]
#[ignore = "writes renders/sheet-directing.png: see the module doc"]
fn directing_sheet() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scenes = ["cumulus-duck-torus-knot", "duck-drift", "waving-tube"];
    let (w, h) = (160u32, 90u32);
    let mut sheet = image::RgbImage::new(3 * w, scenes.len() as u32 * h);
    for (row, name) in scenes.iter().enumerate() {
        let mut scene = load_scene(&repo.join(format!("scenes/{name}.ron"))).unwrap();
        (scene.file.shot.width, scene.file.shot.height) = (w, h);
        let opts = RenderOptions {
            output: Some(std::env::temp_dir().join("nephele-sheets-directing")),
            ..RenderOptions::default()
        };
        let shot = Shot::open(scene, &opts).unwrap();
        let n = shot.total();
        for (col, f) in [(n / 5).max(1), (n * 11 / 20).max(1), n]
            .into_iter()
            .enumerate()
        {
            let k = shot.index(f);
            let s = shot.settings(k).unwrap();
            let img = output::tonemapped(&shot.render_frame(k).unwrap(), &s);
            image::imageops::replace(
                &mut sheet,
                &img,
                (col as u32 * w) as i64,
                (row as u32 * h) as i64,
            );
        }
    }
    let path = repo.join("renders/sheet-directing.png");
    sheet.save(&path).unwrap();
    println!("{}", path.display());
}
