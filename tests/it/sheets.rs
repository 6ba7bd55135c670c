//! Picture sheets of every builtin scene (docs/MEASUREMENTS.md, "The cloud look"; the README
//! shows some): an early, a middle and the final frame side by side in
//! `renders/sheet-<scene>.png`, and the golden-hour backlit frame `renders/duck-golden-hour.png`.
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
