//! Motion blur against references: a blurred frame against the mean of many unblurred sub-frame
//! renders, a still cloud through an open shutter, a frame that holds in one part and moves in
//! another, and bad shutters in a scene file (moved here from the integration tests: they build
//! their shutters with [`strata`], which is the renderer's own).

use glam::{DQuat, DVec3, Vec3};

use super::*;
use crate::render::{
    Camera, CloudMaterial, FrameOptions, FrameRenderer, Quality, Sky, Sun, render_frame,
};

#[test]
fn strata_cover_the_shutter_centred_on_the_frame() {
    let (c, s) = strata(0.5, 4, 24.0);
    assert!((s - 0.5 / 24.0 / 4.0).abs() < 1e-15);
    assert!((c[0] + 0.25 / 24.0 - 0.5 * s).abs() < 1e-15);
    assert!((c.iter().sum::<f64>()).abs() < 1e-15);
}

/// `blobs` rendered through `shutter` (the frame renderer with an open shutter).
fn render_frame_blurred(
    settings: &RenderSettings,
    blobs: &[Blob],
    shutter: &Shutter,
) -> (Frame, BlurReport) {
    let options = FrameOptions {
        shutter: Some(shutter),
        ..FrameOptions::default()
    };
    let (frame, report) = FrameRenderer::render_once(settings, blobs, &options);
    (frame, report.blur.expect("the cloud moves: blurred"))
}

/// A small cloud of overlapping ellipsoids about 1.2 units across around `at`.
fn cloud(at: DVec3) -> Vec<Blob> {
    (0..10)
        .map(|i| {
            let a = i as f64 * 0.9;
            Blob {
                center: at + DVec3::new(0.35 * a.cos(), 0.2 * (1.7 * a).sin(), 0.3 * a.sin()),
                rotation: DQuat::from_euler(glam::EulerRot::XYZ, a, 0.4 * a, 0.1),
                semi_axes: DVec3::new(0.3, 0.22, 0.26),
                a: 1.0,
                b: 2.0,
            }
        })
        .collect()
}

fn settings(time_samples: u32) -> RenderSettings {
    RenderSettings {
        width: 96,
        height: 54,
        camera: Camera {
            position: Vec3::new(0.0, 0.3, 4.5),
            look_at: Vec3::ZERO,
            up: Vec3::Y,
            fov_deg: 40.0,
            shift: glam::Vec2::ZERO,
        },
        sun: Sun::default(),
        sky: Sky::default(),
        cloud: CloudMaterial::default(),
        exposure: 0.0,
        length_scale: 1.5,
        seed: 11,
        time: 1.0,
        // A coarser light grid than Final's 224 cells keeps the 48 sub-frame renders quick (96:
        // the sky's grid a third of it, 32 cells);
        // no pixel floor on its cells (0), so every render of this 96×54 frame has 96 whatever
        // its cloud's bounds (the floor would give the strata and the sub-frames different,
        // far coarser lattices: this test is about the light's motion, not its resolution).
        quality: Quality {
            time_samples,
            shadow_grid: 96,
            shadow_cell_pixels: 0.0,
            ..Quality::final_frame()
        },
        base: None,
        surfaces: None,
    }
}

/// `blobs` moved by `v·t`.
fn moved(blobs: &[Blob], v: DVec3, t: f64) -> Vec<Blob> {
    blobs
        .iter()
        .map(|b| Blob {
            center: b.center + v * t,
            ..*b
        })
        .collect()
}

/// The shutter of a cloud whose blobs `moving` travel at `v` (the others hold), `shutter`
/// frames long at 24 fps with `n` strata.
fn shutter_of(blobs: &[Blob], moving: &[bool], v: DVec3, shutter: f64, n: u32) -> Shutter {
    let (centres, stratum) = strata(shutter, n, 24.0);
    let at = |t: f64| -> Vec<Blob> {
        blobs
            .iter()
            .zip(moving)
            .map(|(b, &m)| if m { moved(&[*b], v, t)[0] } else { *b })
            .collect()
    };
    Shutter {
        samples: centres
            .into_iter()
            .map(|offset| TimeSample {
                offset,
                blobs: at(offset),
                velocity: moving
                    .iter()
                    .map(|&m| if m { v } else { DVec3::ZERO })
                    .collect(),
            })
            .collect(),
        stratum,
    }
}

/// The mean of `n` unblurred renders at the centres of `n` strata of the shutter (each with its
/// own light grid, at its own time).
fn sub_frame_mean(base: &RenderSettings, blobs: &[Blob], v: DVec3, shutter: f64, n: u32) -> Frame {
    let (centres, _) = strata(shutter, n, 24.0);
    let mut mean = Frame {
        width: base.width,
        height: base.height,
        rgb: vec![[0.0; 3]; (base.width * base.height) as usize],
        alpha: vec![0.0; (base.width * base.height) as usize],
        depth: Vec::new(),
        passes: None,
        mattes: None,
        motion: None,
        holdout: None,
        shadow: None,
        shadow_total: None,
        region: None,
    };
    for offset in &centres {
        let mut s = base.clone();
        s.time = (base.time as f64 + offset) as f32;
        let f = render_frame(&s, &moved(blobs, v, *offset));
        for i in 0..mean.rgb.len() {
            for c in 0..3 {
                mean.rgb[i][c] += f.rgb[i][c] / n as f32;
            }
            mean.alpha[i] += f.alpha[i] / n as f32;
        }
    }
    mean
}

/// `‖a − b‖ / ‖b‖` over the premultiplied RGB and alpha of every pixel.
fn relative_rmse(a: &Frame, b: &Frame) -> f64 {
    let (mut d2, mut n2) = (0.0f64, 0.0f64);
    for i in 0..b.rgb.len() {
        for c in 0..3 {
            d2 += ((a.rgb[i][c] - b.rgb[i][c]) as f64).powi(2);
            n2 += (b.rgb[i][c] as f64).powi(2);
        }
        d2 += ((a.alpha[i] - b.alpha[i]) as f64).powi(2);
        n2 += (b.alpha[i] as f64).powi(2);
    }
    (d2 / n2).sqrt()
}

/// A cloud moving at a known speed, blurred, against the mean of 48 sub-frame renders: slow
/// enough for the one light grid of the frame (under `MAX_LIGHT_SHIFT` cells), and fast
/// (a grid per stratum).
#[test]
fn blurred_frame_equals_the_mean_of_sub_frame_renders() {
    let blobs = cloud(DVec3::ZERO);
    let moving = vec![true; blobs.len()];
    // Units per second at 24 fps with a half-frame shutter: the shutter spans v/48 units.
    for (v, grids, samples) in [
        (DVec3::new(1.0, 0.25, 0.0), 1, 8),
        (DVec3::new(9.6, -2.4, 1.2), 16, 16),
    ] {
        let base = settings(samples);
        let shutter = shutter_of(&blobs, &moving, v, 0.5, samples);
        let (blurred, report) = render_frame_blurred(&base, &blobs, &shutter);
        assert_eq!(report.light_grids, grids, "{report:?}");
        let reference = sub_frame_mean(&base, &blobs, v, 0.5, 48);
        let still = render_frame(&base, &blobs);
        let (err, unblurred) = (
            relative_rmse(&blurred, &reference),
            relative_rmse(&still, &reference),
        );
        eprintln!(
            "v = {v}: travel {:.2} light cells, blurred {:.4}, unblurred {:.4} (relative RMSE)",
            report.shift_cells, err, unblurred
        );
        assert!(err <= 0.02, "blurred frame {err} from the sub-frame mean");
        assert!(
            unblurred > 2.0 * err,
            "the blur must matter here: unblurred {unblurred}, blurred {err}"
        );
    }
}

/// Two clouds, one still and one flying: the blurred frame equals the unblurred one (to float
/// rounding of the mean of identical rays) wherever only the still cloud is seen, and differs
/// where the other moves.
#[test]
fn blur_changes_the_frame_where_the_cloud_moves_and_not_where_it_holds() {
    let mut blobs = cloud(DVec3::new(-1.0, 0.0, 0.0));
    let still_count = blobs.len();
    blobs.extend(cloud(DVec3::new(1.1, 0.0, 0.0)));
    let moving: Vec<bool> = (0..blobs.len()).map(|i| i >= still_count).collect();
    let base = settings(4);
    // Slow enough for the frame's one light grid, which lights what holds exactly as unblurred
    // (per-stratum grids sit on a lattice over the whole shutter, which re-samples it).
    let shutter = shutter_of(&blobs, &moving, DVec3::new(0.0, 2.5, 0.0), 0.5, 4);
    let (blurred, report) = render_frame_blurred(&base, &blobs, &shutter);
    assert_eq!(report.light_grids, 1, "{report:?}");
    let sharp = render_frame(&base, &blobs);
    // Columns left of the middle see only the still cloud; right of it, the moving one.
    let (w, h) = (base.width as usize, base.height as usize);
    let (mut left, mut right) = (0.0f32, 0.0f32);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let d = (0..3)
                .map(|c| (blurred.rgb[i][c] - sharp.rgb[i][c]).abs())
                .fold((blurred.alpha[i] - sharp.alpha[i]).abs(), f32::max);
            if x < w / 2 - 4 {
                left = left.max(d / sharp.rgb[i][0].abs().max(sharp.alpha[i]).max(1e-3));
            } else if x > w / 2 + 4 {
                right = right.max(d);
            }
        }
    }
    assert!(left < 1e-5, "the still cloud changed by {left} (relative)");
    eprintln!("largest change: still part {left:e} (relative), moving part {right}");
    assert!(right > 0.02, "the moving cloud did not blur ({right})");
}

/// A scene at its hold: shutter open and closed give the same bits; a bad shutter is a located
/// error before anything renders.
#[test]
fn still_cloud_shutter_open_is_the_closed_frame_and_bad_shutters_are_errors() {
    use crate::blobby::{BlobModel, save_model};
    use crate::scene::{self, RenderOptions, SceneError, Shot};
    let dir = std::env::temp_dir().join(format!("nephele-blur-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let blobs = cloud(DVec3::ZERO);
    let model = BlobModel::from_blobs("test:cloud", 1.0, 1, blobs);
    save_model(&dir.join("model.ron"), &model).unwrap();
    let write = |name: &str, shutter: &str| {
        let path = dir.join(name);
        std::fs::write(
            &path,
            format!(
                "Scene(target: Model(\"model.ron\"), animation: Aggregation((hold_seconds: 0.5)),\n\
                 shot: (width: 48, height: 30, fps: 8, seconds: 1.0, shutter: {shutter}), seed: 3)"
            ),
        )
        .unwrap();
        path
    };
    let opts = RenderOptions {
        output: Some(dir.join("out")),
        ..RenderOptions::default()
    };
    let frame = |path: &std::path::Path, k: u32| {
        let shot = Shot::open(scene::load_scene(path).unwrap(), &opts).unwrap();
        shot.render_frame(k).unwrap()
    };
    let (open, closed) = (write("open.ron", "0.5"), write("closed.ron", "0.0"));
    // Frame 8 (k = 7) is in the hold: the same frame. Frame 2 flies: blurred.
    assert_eq!(frame(&open, 7), frame(&closed, 7));
    assert_ne!(frame(&open, 1), frame(&closed, 1));
    for bad in ["-0.1", "1.5", "NaN", "inf"] {
        let path = write("bad.ron", bad);
        let err = scene::load_scene(&path).unwrap_err();
        assert!(
            matches!(&err, SceneError::InvalidAt { field, .. } if field == "shot.shutter"),
            "{bad}: {err}"
        );
        let text = err.to_string();
        assert!(text.starts_with(&path.display().to_string()), "{text}");
        assert!(text.contains("[0, 1]"), "{text}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Motion vectors with an open shutter: the blurred beauty keeps its bits, and where the
/// blurred cloud is dense the vectors are the cloud's speed in pixels a frame (the frame's
/// velocity where each time sample's cloud lies).
#[test]
fn motion_vectors_of_a_blurred_frame_leave_its_beauty_alone() {
    use crate::render::{Film, MotionSource};
    let s = settings(4);
    let blobs = cloud(DVec3::ZERO);
    let v = DVec3::new(3.0, 0.0, 0.0);
    let shutter = shutter_of(&blobs, &vec![true; blobs.len()], v, 0.5, 4);
    let h = 1e-3;
    let field = crate::animate::VelocityField::new(
        &moved(&blobs, v, -h),
        &blobs,
        &moved(&blobs, v, h),
        2.0 * h,
    );
    let film = Film {
        motion: true,
        ..Film::default()
    };
    let options = FrameOptions {
        shutter: Some(&shutter),
        film: &film,
        motion: Some(MotionSource {
            velocity: &field,
            fps: 24.0,
        }),
    };
    let (with, _) = FrameRenderer::render_once(&s, &blobs, &options);
    let (plain, _) = render_frame_blurred(&s, &blobs, &shutter);
    assert!(with.rgb == plain.rgb && with.alpha == plain.alpha);
    // 3 units a second at 24 fps, 4.5 units from a 40° camera 54 pixels tall.
    let px = 3.0 / 24.0 * 54.0 / (2.0 * 4.5 * 20f64.to_radians().tan());
    let motion = with.motion.expect("vectors");
    let (mut n, mut worst) = (0, 0.0f64);
    for (i, m) in motion.iter().enumerate() {
        if with.alpha[i] > 0.9 {
            n += 1;
            worst = worst.max((m[0] as f64 - px).abs() / px);
        }
    }
    eprintln!("blurred: {n} pixels, {px:.3} px a frame, worst {worst:.3} relative");
    assert!(n > 100 && worst < 0.15, "{n} pixels, worst {worst}");
}
