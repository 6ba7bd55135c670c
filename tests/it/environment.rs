//! The plate's light, `sky: Environment((file: "plate.exr", …))`: a lat-long EXR read at load
//! (located errors naming it), a constant map rendering as the equal uniform sky, and an
//! edited map re-rendering the frames. Its single scattering against Mitsuba's `envmap` is in
//! `mitsuba.rs`.

use std::path::Path;
use std::process::Command;

use glam::Vec3;
use nephele::scene;

use crate::temp_support::{self, TempDir};

fn temp_dir(name: &str) -> TempDir {
    temp_support::temp_dir(&format!("env-{name}"))
}

fn nephele() -> Command {
    Command::new(env!("CARGO_BIN_EXE_nephele"))
}

/// Write a `w × h` RGB float EXR whose texel `(x, y)` (row 0 at the top) is `f(x, y)`.
pub fn write_exr(path: &Path, w: usize, h: usize, f: impl Fn(usize, usize) -> Vec3 + Sync) {
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        let c = f(x, y);
        (c.x, c.y, c.z)
    })
    .unwrap();
}

/// A non-uniform test map (`w × w/2`, Mitsuba's `envmap` convention): a blue-to-white sky
/// above a dark warm ground, and a bright patch (a low sun's glow) 20° high toward +X
/// (`u = ¼`) — a cell's worth of light from one side.
pub fn test_map(u: f32, v: f32) -> Vec3 {
    test_map_with(u, v, 6.0)
}

/// [`test_map`] with the patch `patch` times as bright as its colour (0: the gradient alone).
pub fn test_map_with(u: f32, v: f32, patch: f32) -> Vec3 {
    let theta = std::f32::consts::PI * v;
    let y = theta.cos();
    let base = if y >= 0.0 {
        Vec3::new(0.55, 0.65, 0.8).lerp(Vec3::new(0.12, 0.25, 0.6), y.sqrt())
    } else {
        Vec3::new(0.12, 0.1, 0.08)
    };
    // Angular distance from the patch's centre (u = ¼, 20° above the horizon).
    let d = |u: f32, v: f32| {
        let (t, p) = (std::f32::consts::PI * v, 2.0 * std::f32::consts::PI * u);
        Vec3::new(t.sin() * p.sin(), t.cos(), -t.sin() * p.cos())
    };
    let c = d(0.25, 70.0 / 180.0);
    let angle = d(u, v).dot(c).clamp(-1.0, 1.0).acos().to_degrees();
    let patch = if angle < 12.0 { patch } else { 0.0 };
    base + Vec3::new(1.0, 0.85, 0.6) * patch
}

const SCENE: &str = "Scene(target: Model(\"builtin:cumulus\"),\n  shot: (width: 160, height: 90, fps: 4, \
                     seconds: 0.5),\n  sky: SKY,\n  output: (dir: \"out\", name: \"e\", formats: [Exr, Png]))";

fn scene_with(dir: &Path, sky: &str) -> std::path::PathBuf {
    let path = dir.join("e.ron");
    std::fs::write(&path, SCENE.replace("SKY", sky)).unwrap();
    path
}

/// The frame and the settings of frame index 0 of the scene at `path`.
fn render(path: &Path) -> (nephele::render::Frame, nephele::render::RenderSettings) {
    let dir = path.parent().unwrap().join("cache");
    let opts = scene::RenderOptions {
        output: Some(dir),
        ..scene::RenderOptions::default()
    };
    let shot = scene::Shot::open(scene::load_scene(path).unwrap(), &opts).unwrap();
    (shot.render_frame(0).unwrap(), shot.settings(0).unwrap())
}

/// A missing map, a map that is not lat-long, and non-finite or negative texels are errors at
/// `sky.file` naming the EXR; a half-float map with alpha reads.
#[test]
fn bad_maps_are_located_errors_naming_the_exr() {
    let dir = temp_dir("bad");
    let path = scene_with(&dir, "Environment((file: \"plate.exr\"))");
    let at = format!("{}:3:21: sky.file: ", path.display());
    let err = || scene::load_scene(&path).unwrap_err().to_string();
    let e = err();
    assert!(e.starts_with(&at), "{e}");
    assert!(e.contains("plate.exr: does not exist"), "{e}");
    let exr = dir.join("plate.exr");
    write_exr(&exr, 30, 20, |_, _| Vec3::ONE);
    let e = err();
    assert!(
        e.starts_with(&at) && e.contains("plate.exr: is 30 × 20 texels"),
        "{e}"
    );
    write_exr(&exr, 8, 4, |x, y| {
        if (x, y) == (3, 2) {
            Vec3::new(1.0, -0.5, 1.0)
        } else {
            Vec3::ONE
        }
    });
    let e = err();
    assert!(
        e.contains("texel (x 3, y 2)") && e.contains("not negative"),
        "{e}"
    );
    write_exr(&exr, 8, 4, |x, _| {
        Vec3::splat(if x == 5 { f32::INFINITY } else { 1.0 })
    });
    assert!(err().contains("finite"), "{}", err());
    std::fs::write(&exr, b"not an exr").unwrap();
    let e = err();
    assert!(
        e.starts_with(&at) && e.contains("plate.exr: is not a readable EXR"),
        "{e}"
    );
    // Half floats with an alpha channel: read, alpha ignored.
    use exr::prelude::f16;
    exr::prelude::write_rgba_file(&exr, 8, 4, |x, _| {
        let v = f16::from_f32(x as f32);
        (v, v, v, f16::from_f32(0.5))
    })
    .unwrap();
    let s = scene::load_scene(&path).unwrap();
    let nephele::render::Sky::Environment(env) = &s.file.sky else {
        panic!("an environment")
    };
    let map = env.map.as_ref().unwrap();
    assert_eq!((map.width(), map.height()), (8, 4));
    assert_eq!(map.texels()[5], Vec3::splat(5.0));
    // Out-of-range settings are located at their field.
    let path = scene_with(&dir, "Environment((file: \"plate.exr\", intensity: -1.0))");
    let e = scene::load_scene(&path).unwrap_err().to_string();
    assert!(e.contains("sky.intensity: must be ≥ 0"), "{e}");
}

/// A constant map renders as the uniform sky of its colour: its cells hold the same light
/// (solid-angle sums), and the background is the colour. PNG within 1/255, EXR within 0.5 %.
#[test]
fn a_constant_map_renders_as_the_equal_uniform_sky() {
    let dir = temp_dir("constant");
    let c = Vec3::new(0.3, 0.42, 0.65);
    // Half the colour at intensity 2: the intensity scales the map.
    write_exr(&dir.join("flat.exr"), 16, 8, |_, _| c * 0.5);
    let (fe, se) = render(&scene_with(
        &dir,
        "Environment((file: \"flat.exr\", rotate_deg: 33.0, intensity: 2.0))",
    ));
    let (fu, su) = render(&scene_with(&dir, "Uniform(color: (0.3, 0.42, 0.65))"));
    assert!(
        fu.alpha.iter().any(|&a| a > 0.5),
        "the cloud is in the frame"
    );
    let (pe, pu) = (
        nephele::render::output::tonemapped(&fe, &se),
        nephele::render::output::tonemapped(&fu, &su),
    );
    let max_png = pe
        .as_raw()
        .iter()
        .zip(pu.as_raw())
        .map(|(a, b)| a.abs_diff(*b))
        .max()
        .unwrap();
    let mut max_rel = 0.0f32;
    for (a, b) in fe.rgb.iter().zip(&fu.rgb) {
        for k in 0..3 {
            max_rel = max_rel.max((a[k] - b[k]).abs() / b[k].max(0.05));
        }
    }
    eprintln!("constant map vs uniform sky: PNG max |Δ| {max_png}/255, EXR max rel {max_rel:.5}");
    assert!(max_png <= 1, "PNG differs by {max_png}/255");
    assert!(max_rel < 0.005, "EXR differs by {max_rel}");
}

/// The map's content is part of the frame's light: an edited HDRI re-renders the frames (and
/// says it was the sun and sky), an untouched one does not.
#[test]
fn an_edited_map_rerenders_the_frames() {
    let dir = temp_dir("edit");
    let exr = dir.join("plate.exr");
    write_exr(&exr, 32, 16, |x, y| {
        test_map(x as f32 / 32.0, y as f32 / 16.0)
    });
    scene_with(&dir, "Environment((file: \"plate.exr\"))");
    let run = || {
        let out = nephele()
            .current_dir(&*dir)
            .args(["render", "e.ron"])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{text}");
        text
    };
    run();
    let t = run();
    assert!(t.contains("0 frames rendered, 2 already done"), "{t}");
    // One texel brighter.
    write_exr(&exr, 32, 16, |x, y| {
        test_map(x as f32 / 32.0, y as f32 / 16.0)
            + Vec3::splat(if (x, y) == (3, 3) { 1.0 } else { 0.0 })
    });
    let t = run();
    assert!(t.contains("2 frames rendered, 0 already done"), "{t}");
    assert!(t.contains("changed: sun and sky"), "{t}");
}

/// `sun_from_map: true`: the scene's sun is the map's bright patch (toward it, turned with the
/// map), and the map it leaves lights the cells; a map without a bright region has no sun.
#[test]
fn sun_from_map_replaces_the_scene_sun_with_the_maps() {
    let dir = temp_dir("sun");
    let (w, h) = (128, 64);
    write_exr(&dir.join("plate.exr"), w, h, |x, y| {
        test_map((x as f32 + 0.5) / w as f32, y as f32 / (h - 1) as f32)
    });
    let path = scene_with(
        &dir,
        "Environment((file: \"plate.exr\", rotate_deg: 90.0, intensity: 2.0, sun_from_map: true))",
    );
    let s = scene::load_scene(&path).unwrap();
    // The patch is 20° high toward +X in the file; turned by 90° it is toward −Z.
    let (el, az) = (20f32.to_radians(), 0f32);
    let toward = Vec3::new(az.sin() * el.cos(), el.sin(), -el.cos());
    let to_sun = -s.file.sun.travel_dir();
    assert!(to_sun.dot(toward) > 0.995, "{to_sun} vs {toward}");
    // Its irradiance: the patch's excess over the sky around it × solid angle × intensity
    // (a 12° cap: 2π(1 − cos 12°) = 0.137 sr, 6 × (1, 0.85, 0.6) over the sky).
    let e = s.file.sun.color * s.file.sun.intensity;
    let expect = Vec3::new(1.0, 0.85, 0.6) * 6.0 * 0.137 * 2.0;
    assert!(
        ((e - expect) / expect).abs().max_element() < 0.15,
        "{e} vs {expect}"
    );
    // No bright region: no sun.
    write_exr(&dir.join("plate.exr"), 16, 8, |_, _| Vec3::splat(0.4));
    let s = scene::load_scene(&path).unwrap();
    assert_eq!(s.file.sun.intensity, 0.0);
}
