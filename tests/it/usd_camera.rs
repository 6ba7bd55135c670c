//! `camera: Usd((file, prim))`: a shot's tracked camera read from a USD stage — by frame number,
//! through its parents' transforms, with its lens fitted to the image; located errors naming
//! the USD file; per-frame provenance; the stage `nephele usd` writes read back to the same
//! frame; and the projection against usd-core's own (`tools/usd_camera.py`, skipped without
//! usd-core unless `NEPHELE_REQUIRE_READERS=1`). Also the `.chan` camera against the matching
//! keyframed one.

use crate::readers_support::skip_or_fail;
use crate::temp_support;

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DVec3, Vec3};
use nephele::render::output::CameraFrame;
use nephele::render::{Camera, CameraRays};
use nephele::scene;
use temp_support::TempDir;

fn temp_dir(name: &str) -> TempDir {
    temp_support::temp_dir(&format!("usdcam-{name}"))
}

fn nephele() -> Command {
    Command::new(env!("CARGO_BIN_EXE_nephele"))
}

/// A camera under a translated parent: moving along +X and panning left to 90° over frames
/// 1001..1004, the focal length from 24 to 48 over the same frames, a 3:2 film back.
const STAGE: &str = r#"#usda 1.0
(
    startTimeCode = 1001
    endTimeCode = 1004
    timeCodesPerSecond = 4
    upAxis = "Y"
)

def Xform "World"
{
    double3 xformOp:translate = (0, 1, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]

    def Camera "cam"
    {
        float focalLength.timeSamples = {
            1001: 24,
            1004: 48,
        }
        float horizontalAperture = 36
        float verticalAperture = 24
        float2 clippingRange = (0.1, 1000)
        double3 xformOp:translate.timeSamples = {
            1001: (0, 0, 4),
            1003: (1, 0, 4),
        }
        float3 xformOp:rotateXYZ.timeSamples = {
            1001: (0, 0, 0),
            1004: (0, 90, 0),
        }
        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]
    }
}
"#;

/// A scene of four frames 1001..1004 at 4 fps, `width × height`, with `camera`.
fn scene_text(camera: &str, width: u32, height: u32) -> String {
    format!(
        "Scene(target: Model(\"builtin:cumulus\"),\n  shot: (width: {width}, height: {height}, \
         fps: 4, seconds: 1.0, start_frame: 1001),\n  camera: {camera},\n  \
         output: (dir: \"out\", name: \"c\", formats: [Png]))"
    )
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-4
}

#[test]
fn a_usd_camera_drives_the_shot_by_frame_number() {
    let dir = temp_dir("frames");
    std::fs::write(dir.join("cam.usda"), STAGE).unwrap();
    let path = dir.join("c.ron");
    let camera = "Usd((file: \"cam.usda\", prim: \"/World/cam\"))";
    std::fs::write(&path, scene_text(camera, 32, 18)).unwrap();
    let scene = scene::load_scene(&path).unwrap();
    let shot = scene::Shot::open(scene, &scene::RenderOptions::default()).unwrap();
    let cam = |k: u32| shot.settings(k).unwrap().camera;
    let view = |c: &Camera| (c.look_at - c.position).normalize();
    // The parent lifts it by 1; time codes are frame numbers; linear between samples.
    assert!(close(cam(0).position, Vec3::new(0.0, 1.0, 4.0)));
    assert!(close(view(&cam(0)), Vec3::NEG_Z));
    assert!(close(cam(1).position, Vec3::new(0.5, 1.0, 4.0)));
    assert!(close(cam(3).position, Vec3::new(1.0, 1.0, 4.0)), "held");
    // 30° of pan a frame: at 1002 the view is 30° left of −Z.
    let a = 30f32.to_radians();
    assert!(close(view(&cam(1)), Vec3::new(-a.sin(), 0.0, -a.cos())));
    assert!(close(view(&cam(3)), Vec3::NEG_X));
    // A 3:2 back on a 16:9 image keeps its 24 height: fov = 2·atan(12 / focal).
    for (k, focal) in [(0, 24.0f32), (1, 32.0), (3, 48.0)] {
        let want = 2.0 * (12.0 / focal).atan().to_degrees();
        assert!((cam(k).fov_deg - want).abs() < 1e-4, "frame {k}");
    }
    assert_eq!(cam(0).shift, glam::Vec2::ZERO);
}

#[test]
fn usd_camera_errors_are_located_and_name_the_usd_file() {
    let dir = temp_dir("errors");
    let path = dir.join("c.ron");
    let usd = dir.join("cam.usda");
    let load = |stage: Option<&str>, prim: &str| {
        match stage {
            Some(text) => std::fs::write(&usd, text).unwrap(),
            None => {
                let _ = std::fs::remove_file(&usd);
            }
        }
        let camera = format!("Usd((file: \"cam.usda\",\n    prim: \"{prim}\"))");
        std::fs::write(&path, scene_text(&camera, 32, 18)).unwrap();
        scene::load_scene(&path).unwrap_err().to_string()
    };
    let at_file = format!("{}:3:16: camera.file: {}", path.display(), usd.display());
    let at_prim = format!("{}:4:5: camera.prim: {}", path.display(), usd.display());
    let e = load(None, "/World/cam");
    assert!(e.starts_with(&at_file) && e.contains("no such file"), "{e}");
    let e = load(
        Some("#usda 1.0\ndef Camera \"cam\" {\n  float focalLength = \n"),
        "/cam",
    );
    assert!(
        e.starts_with(&at_file) && e.contains("not a USD stage"),
        "{e}"
    );
    let e = load(Some(STAGE), "/World/camera");
    assert!(
        e.starts_with(&at_prim) && e.contains("no prim at /World/camera") && e.contains("/World"),
        "{e}"
    );
    let e = load(Some(STAGE), "/World");
    assert!(
        e.starts_with(&at_prim) && e.contains("/World is a Xform, not a Camera"),
        "{e}"
    );
    let e = load(Some(&STAGE.replace("1001: 24", "1001: -24")), "/World/cam");
    assert!(
        e.starts_with(&at_prim)
            && e.contains("/World/cam.focalLength at time code 1001 is -24")
            && e.contains("positive finite"),
        "{e}"
    );
    let e = load(
        Some(&STAGE.replace("verticalAperture = 24", "verticalAperture = 0")),
        "/World/cam",
    );
    assert!(e.contains("verticalAperture at time code 1001 is 0"), "{e}");
    let e = load(
        Some(&STAGE.replace("horizontalAperture = 36", "horizontalAperture = inf")),
        "/World/cam",
    );
    assert!(
        e.starts_with(&at_prim) && e.contains("horizontalAperture"),
        "{e}"
    );
    let e = load(
        Some(&STAGE.replace(
            "\"xformOp:rotateXYZ\"]",
            "\"xformOp:rotateXYZ\", \"xformOp:shear\"]",
        )),
        "/World/cam",
    );
    assert!(
        e.starts_with(&at_prim) && e.contains("xformOp:shear"),
        "{e}"
    );
    // A binary layer that is not one: an error naming it, not a panic.
    std::fs::write(
        &path,
        scene_text("Usd((file: \"cam.usdc\", prim: \"/c\"))", 32, 18),
    )
    .unwrap();
    let mut bytes = b"PXR-USDC".to_vec();
    bytes.extend((0..4000u32).map(|i| (i.wrapping_mul(2654435761) >> 13) as u8));
    std::fs::write(dir.join("cam.usdc"), bytes).unwrap();
    let e = scene::load_scene(&path).unwrap_err().to_string();
    assert!(
        e.contains("camera.file: ") && e.contains("cam.usdc: not a USD stage"),
        "{e}"
    );
    // A prim path that is not absolute is refused before the file is read.
    let e = load(Some(STAGE), "World/cam");
    assert!(
        e.contains("camera.prim") && e.contains("absolute path"),
        "{e}"
    );
}

#[test]
fn an_edited_usd_sample_re_renders_only_its_frame() {
    let dir = temp_dir("provenance");
    let keyed = |pan: &str| {
        STAGE.replace(
            "            1001: (0, 0, 0),\n            1004: (0, 90, 0),",
            &format!(
                "            1001: (0, 0, 0),\n            1002: (0, 2, 0),\n            \
                 1003: (0, {pan}, 0),\n            1004: (0, 4, 0),"
            ),
        )
    };
    std::fs::write(dir.join("cam.usda"), keyed("3")).unwrap();
    let camera = "Usd((file: \"cam.usda\", prim: \"/World/cam\"))";
    std::fs::write(dir.join("c.ron"), scene_text(camera, 32, 18)).unwrap();
    let render = || {
        let out = nephele()
            .current_dir(&*dir)
            .args(["render", "c.ron"])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(out.status.success(), "{text}");
        text
    };
    render();
    std::fs::write(dir.join("cam.usda"), keyed("3.5")).unwrap();
    let t = render();
    assert!(t.contains("1 frames rendered, 3 already done"), "{t}");
    assert!(t.contains("changed: camera"), "{t}");
}

/// 4×4-pixel block means of an 8-bit RGBA image, per channel.
fn block_means(img: &image::RgbaImage) -> Vec<f64> {
    let (w, h) = img.dimensions();
    let mut out = Vec::new();
    for by in 0..h / 4 {
        for bx in 0..w / 4 {
            for c in 0..4 {
                let mut sum = 0.0;
                for y in 0..4 {
                    for x in 0..4 {
                        sum += img.get_pixel(bx * 4 + x, by * 4 + y)[c] as f64;
                    }
                }
                out.push(sum / 16.0);
            }
        }
    }
    out
}

#[test]
fn the_stage_nephele_writes_reads_back_to_the_same_frame() {
    let dir = temp_dir("roundtrip");
    let orbit = "Auto((azimuth_deg: 40.0, elevation_deg: 20.0, orbit_deg: 60.0))";
    std::fs::write(dir.join("a.ron"), scene_text(orbit, 64, 36)).unwrap();
    let run = |args: &[&str]| {
        let out = nephele().current_dir(&*dir).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    run(&["usd", "a.ron", "-o", "shot.usda"]);
    let from_usd = "Usd((file: \"shot.usda\", prim: \"/shot/camera\"))";
    std::fs::write(
        dir.join("b.ron"),
        scene_text(from_usd, 64, 36).replace("name: \"c\"", "name: \"u\""),
    )
    .unwrap();
    for scene in ["a.ron", "b.ron"] {
        run(&["render", scene, "--frames", "1003"]);
    }
    let a = image::open(dir.join("out/c_1003.png")).unwrap().to_rgba8();
    let b = image::open(dir.join("out/u_1003.png")).unwrap().to_rgba8();
    let means = block_means(&a);
    let spread =
        means.iter().fold(0.0f64, |m, v| m.max(*v)) - means.iter().fold(255.0f64, |m, v| m.min(*v));
    assert!(spread > 10.0, "the frame shows the cloud ({spread})");
    let worst = means
        .iter()
        .zip(block_means(&b))
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    eprintln!("round trip: largest 4×4 block mean difference {worst:.3}/255");
    assert!(worst <= 2.0, "{worst}/255");
}

/// The pixel (x right, y down) where `camera` puts world point `p` in a `w × h` image, by the
/// frame's EXR `worldToNDC`; checked against the renderer's own ray through that pixel.
fn project(camera: &Camera, w: u32, h: u32, p: DVec3) -> [f64; 2] {
    let (_, ndc) = CameraFrame::new(camera, w, h).exr_matrices();
    let v: [f64; 4] =
        std::array::from_fn(|c| (0..3).map(|r| p[r] * ndc[r * 4 + c]).sum::<f64>() + ndc[12 + c]);
    let px = [v[0] / v[3] * w as f64, v[1] / v[3] * h as f64];
    let ray = CameraRays::new(camera, w, h).dir(px[0] as f32, px[1] as f32);
    let to_p = (p - camera.position.as_dvec3()).normalize();
    assert!(
        ray.as_dvec3().normalize().dot(to_p) > 1.0 - 1e-9,
        "the ray through {px:?} misses {p}"
    );
    px
}

#[test]
fn a_shifted_lens_projects_where_its_rays_go() {
    // The EXR's worldToNDC of an off-axis camera puts each point on the pixel whose ray the
    // renderer casts through it (`project` checks), and the shift moves the image as stated.
    let mut camera = Camera {
        position: Vec3::new(0.5, 0.25, 6.0),
        look_at: Vec3::new(0.0, 0.0, 0.0),
        up: Vec3::Y,
        fov_deg: 38.0,
        shift: glam::Vec2::new(0.3, -0.2),
    };
    let shifted: Vec<[f64; 2]> = corners()
        .into_iter()
        .map(|p| project(&camera, 1920, 1080, p))
        .collect();
    camera.shift = glam::Vec2::ZERO;
    for (p, s) in corners().into_iter().zip(shifted) {
        let c = project(&camera, 1920, 1080, p);
        // A window shifted right by 0.3 half heights and down by 0.2 moves the image left by
        // 0.3·540 px and up by 0.2·540.
        assert!((c[0] - s[0] - 0.3 * 540.0).abs() < 1e-3, "{c:?} {s:?}");
        assert!((c[1] - s[1] - 0.2 * 540.0).abs() < 1e-3, "{c:?} {s:?}");
    }
}

/// The corners of the box the projections are compared on.
fn corners() -> Vec<DVec3> {
    (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { -1.5 } else { 1.0 },
                if i & 2 == 0 { -0.5 } else { 1.5 },
                if i & 4 == 0 { -2.0 } else { 0.5 },
            )
        })
        .collect()
}

#[test]
fn a_chan_camera_projects_as_its_keyframes() {
    // The same camera as `.chan` lines (no roll) and as RON keyframes at the frames' times.
    let dir = temp_dir("chan");
    let keys = [
        (1001, [0.0, 0.5, 6.0], [0.0, 0.0, 0.0], 40.0),
        (1002, [1.0, 1.0, 5.5], [-5.0, 10.0, 0.0], 35.0),
        (1003, [2.0, 0.5, 5.0], [3.0, 20.0, 0.0], 30.0),
        (1004, [3.0, 0.0, 4.5], [0.0, 30.0, 0.0], 30.0),
    ];
    let mut chan = String::new();
    let mut ron = Vec::new();
    for (frame, t, r, fov) in keys {
        chan += &format!(
            "{frame} {} {} {} {} {} {} {fov}\n",
            t[0], t[1], t[2], r[0], r[1], r[2]
        );
        let (rx, ry) = (f64::to_radians(r[0]), f64::to_radians(r[1]));
        // ZXY with no roll: the view −Z tilted about X, then panned about Y.
        let view = DVec3::new(-ry.sin() * rx.cos(), rx.sin(), -ry.cos() * rx.cos());
        let eye = DVec3::from(t);
        let look = eye + 3.0 * view;
        ron.push(format!(
            "(time: {}, position: ({}, {}, {}), look_at: ({}, {}, {}), fov_deg: {fov})",
            (frame - 1001) as f64 / 4.0,
            eye.x,
            eye.y,
            eye.z,
            look.x,
            look.y,
            look.z
        ));
    }
    std::fs::write(dir.join("cam.chan"), chan).unwrap();
    let shot = |camera: &str, name: &str| {
        let path = dir.join(format!("{name}.ron"));
        std::fs::write(&path, scene_text(camera, 1920, 1080)).unwrap();
        scene::Shot::open(
            scene::load_scene(&path).unwrap(),
            &scene::RenderOptions::default(),
        )
        .unwrap()
    };
    let a = shot("Chan((file: \"cam.chan\"))", "a");
    let b = shot(&format!("Keyframes([{}])", ron.join(", ")), "b");
    let mut worst = 0.0f64;
    for k in 0..4 {
        let (ca, cb) = (a.settings(k).unwrap().camera, b.settings(k).unwrap().camera);
        for p in corners() {
            let (pa, pb) = (project(&ca, 1920, 1080, p), project(&cb, 1920, 1080, p));
            worst = worst.max((pa[0] - pb[0]).hypot(pa[1] - pb[1]));
        }
    }
    eprintln!(".chan against keyframes: largest projection difference {worst:.2e} px");
    assert!(worst < 0.5, "{worst} px");
}

/// The python with Pixar's `pxr` (as `export` finds it), or `None` after skipping.
pub(crate) fn usd_python() -> Option<PathBuf> {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/usd-venv/bin/python");
    let python = std::env::var_os("NEPHELE_USD_PYTHON")
        .map(PathBuf::from)
        .unwrap_or(venv);
    if python.is_file() {
        return Some(python);
    }
    skip_or_fail(
        "usd-core",
        &format!("{} not found (as .ci/run makes it)", python.display()),
    );
    None
}

#[test]
fn a_usd_camera_projects_as_usd_core_does_from_usda_and_usdc() {
    let Some(python) = usd_python() else {
        return;
    };
    let dir = temp_dir("usdcore");
    let points: Vec<String> = corners()
        .iter()
        .flat_map(|p| p.to_array())
        .map(|c| c.to_string())
        .collect();
    let mut worst = 0.0f64;
    for ext in ["usda", "usdc"] {
        let stage = dir.join(format!("cam.{ext}"));
        let run = Command::new(&python)
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/usd_camera.py"))
            .arg(&stage)
            .args(["1920", "1080", "1001", "1024"])
            .args(&points)
            .output()
            .unwrap();
        if run.status.code() == Some(3) {
            skip_or_fail("usd-core", String::from_utf8_lossy(&run.stderr).trim());
            return;
        }
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let frames: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        let path = dir.join(format!("{ext}.ron"));
        let camera = format!("Usd((file: \"cam.{ext}\", prim: \"/World/rig/cam\"))");
        std::fs::write(
            &path,
            scene_text(&camera, 1920, 1080).replace("seconds: 1.0", "seconds: 6.0"),
        )
        .unwrap();
        let shot = scene::Shot::open(
            scene::load_scene(&path).unwrap(),
            &scene::RenderOptions::default(),
        )
        .unwrap();
        for (k, want) in frames.as_array().unwrap().iter().enumerate() {
            let camera = shot.settings(k as u32).unwrap().camera;
            for (p, want) in corners().into_iter().zip(want.as_array().unwrap()) {
                let got = project(&camera, 1920, 1080, p);
                let want = [want[0].as_f64().unwrap(), want[1].as_f64().unwrap()];
                let off = (got[0] - want[0]).hypot(got[1] - want[1]);
                assert!(
                    off < 0.5,
                    "{ext} frame {}: {p} at {got:?}, usd-core {want:?}",
                    1001 + k
                );
                worst = worst.max(off);
            }
        }
    }
    eprintln!("usd-core against nephele: largest projection difference {worst:.3e} px");
}
