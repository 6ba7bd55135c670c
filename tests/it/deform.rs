//! Targets that bend (issue 51, item 3): a cloud fitted once on a deforming mesh's rest frame
//! and carried by its surface (`src/animate/deform/`), on the builtin deforming shape
//! `builtin:waving-tube` (48 frames, made in code) of `scenes/waving-tube.ron`, and the scene
//! file's sequences (`walk_####.obj`, a time-sampled USD mesh) with their located errors.
//!
//! The measures, printed (`cargo test --release --test it -- deform:: --nocapture`):
//! the silhouette IoU of the formed cloud with the mesh's own silhouette on each of the 48
//! frames, the per-frame update's cost against the frame's render, the billows' drift against
//! the surface's motion, and `vel` against the mesh's own vertex velocities.

use std::time::Instant;

use glam::{DMat3, DVec3};
use nephele::animate::deform::RefitConfig;
use nephele::animate::{Deformation, Ease, Timing, TimingKey};
use nephele::mesh::sequence::MeshSequence;
use nephele::render::render_frame;
use nephele::scene::{RenderOptions, Scene, SceneError, Shot, load_scene, scene_from_str};

use crate::look_support::{Mask, iou, project_mesh};
use crate::temp_support::temp_dir;

/// [`formed_tube`] at preview size, fitted once for all the tests of this file (its fit
/// cached in the system's temporary folder, as the look tests' are).
fn formed_tube_preview() -> &'static Shot {
    static SHOT: std::sync::OnceLock<Shot> = std::sync::OnceLock::new();
    SHOT.get_or_init(|| formed_tube(&std::env::temp_dir().join("nephele-deform-tube"), true))
}

/// `scenes/waving-tube.ron` with the cloud formed throughout (a retime that holds the scheme
/// at progress 1), so every frame shows the whole target on the waving mesh; output in `dir`.
fn formed_tube(dir: &std::path::Path, preview: bool) -> Shot {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/waving-tube.ron");
    let mut scene: Scene = load_scene(&path).unwrap();
    let key = |time| TimingKey {
        time,
        progress: 1.0,
        ease: Ease::Linear,
    };
    scene.file.timing = Some(Timing::try_from(vec![key(0.0), key(10.0)]).unwrap());
    let opts = RenderOptions {
        output: Some(dir.to_path_buf()),
        preview,
        ..RenderOptions::default()
    };
    let shot = Shot::open(scene, &opts).unwrap();
    shot.prepared().unwrap();
    shot
}

/// Every one of the 48 frames: the formed cloud's silhouette (rendered alpha > 0.5, preview)
/// against the mesh frame's own silhouette through the same camera has IoU ≥ 0.8; and the
/// per-frame update (carrying the blobs) costs at most 10 % of the frame's render. Measured
/// beside: the local refit of `A`, `B` where the surface leaves the blobs
/// (`Deformation::with_refit`, which the shot does not use): its IoU on every frame, its cost,
/// and that it is deterministic and stays within 0.03 of the carried cloud's IoU.
#[test]
fn the_cloud_follows_the_waving_tube_on_every_frame() {
    let shot = formed_tube_preview();
    let seq = MeshSequence::builtin("waving-tube").unwrap();
    assert_eq!(shot.total() as usize, seq.frames.len(), "a 48-frame shot");
    let prep = shot.prepared().unwrap();
    let deform = prep.direction.deform.clone().expect("the target deforms");
    assert!(!deform.is_refitted(), "the shot carries the blobs only");
    // The refit, solved as a shot would when prepared (timed), and again (deterministic).
    let formed = prep.plan.frame(prep.plan.timeline().frames - 1);
    let times: Vec<f64> = (0..seq.frames.len())
        .map(|k| prep.plan.timeline().time(k))
        .collect();
    let started = Instant::now();
    let refit = Deformation::with_refit(&formed, &seq.frames, &times, &RefitConfig::default());
    let refit_seconds = started.elapsed().as_secs_f64();
    let again = Deformation::with_refit(&formed, &seq.frames, &times, &RefitConfig::default());
    assert_eq!(refit, again, "the refit is deterministic");
    assert_eq!(
        refit.carried_only(),
        deform.carried_only(),
        "the same carry"
    );
    // The shape refit (the anchors' spread mapped where they leave the affine map), timed: what
    // the shot made; its frames are measured against the carry alone.
    let started = Instant::now();
    let shaped =
        Deformation::with_shape_refit(&formed, &seq.frames, &times, &RefitConfig::default());
    let shape_seconds = started.elapsed().as_secs_f64();
    assert_eq!(shaped, *deform, "the shot's deformation is the shape refit");
    let carry = deform.carried_only();
    let (mut worst_shape, mut sum_shape, mut shape_update) = (f64::INFINITY, 0.0, 0.0f64);
    let (mut worst_refit, mut sum_refit, mut worst_loss) = (f64::INFINITY, 0.0, 0.0f64);
    let mut refit_update = 0.0f64;
    // The baseline: the formed cloud left in the rest pose (not carried), against each frame.
    let still = {
        let s = shot.settings(0).unwrap();
        let formed = prep.plan.at(prep.plan.timeline().end());
        let frame = render_frame(&s, &formed);
        Mask::from_alpha(&frame.alpha, s.width as usize, s.height as usize)
    };
    let mut still_worst = f64::INFINITY;
    let (mut worst, mut sum) = (f64::INFINITY, 0.0);
    let (mut update, mut render) = (0.0f64, 0.0f64);
    for k in 0..shot.total() {
        let s = shot.settings(k).unwrap();
        let blobs = shot.blobs(k).unwrap();
        let started = Instant::now();
        let frame = render_frame(&s, &blobs);
        render += started.elapsed().as_secs_f64();
        // The update alone: the plan's blobs carried to the frame's time (fastest of 5).
        let t = prep.plan.timeline().time(k as usize);
        let plan_blobs = prep.plan.at(prep.direction.scheme_time(t));
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            let mut b = plan_blobs.clone();
            let started = Instant::now();
            deform.apply(&mut b, t);
            best = best.min(started.elapsed().as_secs_f64());
            assert_eq!(
                b, blobs,
                "frame {k}: the shot's blobs are the carried plan's"
            );
        }
        update += best;
        let cloud = Mask::from_alpha(&frame.alpha, s.width as usize, s.height as usize);
        let mesh = project_mesh(&s, &seq.frame(k as usize));
        let score = iou(&cloud, &mesh);
        let left = iou(&still, &mesh);
        still_worst = still_worst.min(left);
        let mut refit_best = f64::INFINITY;
        for _ in 0..5 {
            let mut b = plan_blobs.clone();
            let started = Instant::now();
            refit.apply(&mut b, t);
            refit_best = refit_best.min(started.elapsed().as_secs_f64());
        }
        refit_update += refit_best;
        let mut refitted = plan_blobs.clone();
        refit.apply(&mut refitted, t);
        let refitted = render_frame(&s, &refitted);
        let refitted = iou(
            &Mask::from_alpha(&refitted.alpha, s.width as usize, s.height as usize),
            &mesh,
        );
        worst_refit = worst_refit.min(refitted);
        sum_refit += refitted;
        let mut shape_best = f64::INFINITY;
        for _ in 0..5 {
            let mut b = plan_blobs.clone();
            let started = Instant::now();
            shaped.apply(&mut b, t);
            shape_best = shape_best.min(started.elapsed().as_secs_f64());
        }
        shape_update += shape_best;
        let mut carried = plan_blobs.clone();
        carry.apply(&mut carried, t);
        let carried = render_frame(&s, &carried);
        let carried = iou(
            &Mask::from_alpha(&carried.alpha, s.width as usize, s.height as usize),
            &mesh,
        );
        worst_shape = worst_shape.min(carried);
        sum_shape += carried;
        worst_loss = worst_loss.max(carried - refitted);
        println!(
            "frame {:2}: IoU {score:.3} (carried only: {carried:.3}, A, B refitted: \
             {refitted:.3}, not carried: {left:.3})",
            k + 1
        );
        worst = worst.min(score);
        sum += score;
    }
    let n = shot.total() as f64;
    let summary = refit.refit_summary();
    println!(
        "waving tube, {} blobs, preview {}×{}: IoU min {worst:.3}, mean {:.3} (refitted: \
         min {:.3}, mean {:.3}); update {:.1} µs a frame, {:.4} % of the frame's render ({:.3} \
         s a frame); a cloud left in the rest pose: IoU min {still_worst:.3}; refitted {} of \
         {} (blob, frame) pairs, A × {:.3}–{:.3}, B × {:.3}–{:.3}, solved in {:.1} ms at \
         preparation ({:.2} ms a frame of the sequence), its update {:.1} µs a frame",
        prep.model.blobs.len(),
        shot.size().0,
        shot.size().1,
        sum / n,
        worst_refit,
        sum_refit / n,
        update / n * 1e6,
        100.0 * update / render,
        render / n,
        summary.refitted,
        summary.considered,
        summary.a_range[0],
        summary.a_range[1],
        summary.b_range[0],
        summary.b_range[1],
        refit_seconds * 1e3,
        refit_seconds * 1e3 / seq.frames.len() as f64,
        refit_update / n * 1e6,
    );
    println!(
        "waving tube, carried only: IoU min {worst_shape:.3}, mean {:.3}; the shot's shape \
         refit: {} (blob, frame) pairs corrected, made in {:.1} ms at preparation; the carry's \
         update alone {:.1} µs a frame ({:.4} % of the frame's render)",
        sum_shape / n,
        shaped.shape_refitted(),
        shape_seconds * 1e3,
        shape_update / n * 1e6,
        100.0 * shape_update / render,
    );
    assert!(
        summary.refitted > 0,
        "the tube leaves some blobs: {summary:?}"
    );
    assert!(
        shaped.shape_refitted() > 0,
        "the tube's shape refit corrects some blobs"
    );
    // Measured: the shot (shape refit) min 0.822, mean 0.844 against the carry's 0.820, 0.843
    // (the A, B refit lost 0.011 of the min); a shape refit that loses more than 0.005 of
    // either against the carry alone is a regression.
    assert!(
        worst >= worst_shape - 0.005 && sum >= sum_shape - 0.005 * n,
        "the shape refit loses IoU: min {worst:.3} vs the carry's {worst_shape:.3}"
    );
    assert!(shape_update <= 0.1 * render, "the shape refit's update");
    assert!(
        worst_loss <= 0.03,
        "the refit loses {worst_loss:.3} of IoU on some frame"
    );
    assert!(worst >= 0.8, "IoU {worst:.3} < 0.8 on some frame");
    assert!(
        update <= 0.1 * render,
        "update {update} s vs render {render} s"
    );
}

/// The billows ride with the surface: each rest vertex's noise lookup position in its dominant
/// blob's frame (`Rᵀ(x − c)`, world units, as the renderer anchors octaves) drifts by a small
/// fraction of how far the vertex moves; a texture fixed in the world would drift by all of it.
#[test]
fn billows_move_with_the_surface() {
    let shot = formed_tube_preview();
    let prep = shot.prepared().unwrap();
    let seq = MeshSequence::builtin("waving-tube").unwrap();
    let deform = prep.direction.deform.clone().unwrap();
    let formed = prep.plan.at(prep.plan.timeline().end());
    let rest = &seq.frames[0];
    let dominant: Vec<usize> = rest
        .iter()
        .map(|&p| {
            (0..formed.len())
                .max_by(|&a, &b| formed[a].value(p).total_cmp(&formed[b].value(p)))
                .unwrap()
        })
        .collect();
    let local = |b: &nephele::blobby::Blob, x: DVec3| {
        DMat3::from_quat(b.rotation).transpose() * (x - b.center)
    };
    let diagonal = prep.bounds.diagonal();
    let mut ratios = Vec::new();
    let mut drifts = Vec::new();
    for k in 1..seq.frames.len() {
        let t = prep.plan.timeline().time(k);
        let mut moved = formed.clone();
        deform.apply(&mut moved, t);
        for (v, &i) in dominant.iter().enumerate() {
            let (p, q) = (rest[v], seq.frames[k][v]);
            let travel = (q - p).length();
            if travel < 0.02 * diagonal {
                continue;
            }
            let drift = (local(&moved[i], q) - local(&formed[i], p)).length();
            ratios.push(drift / travel);
            drifts.push(drift / diagonal);
        }
    }
    let pct = |v: &mut Vec<f64>, q: f64| {
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * q) as usize]
    };
    let (median, p95) = (pct(&mut ratios, 0.5), pct(&mut ratios, 0.95));
    let (d50, d95) = (pct(&mut drifts, 0.5), pct(&mut drifts, 0.95));
    println!(
        "billow drift / surface travel over {} (vertex, frame) pairs: median {median:.3}, 95th \
         percentile {p95:.3}; drift median {:.2} %, 95th percentile {:.2} % of the diagonal",
        ratios.len(),
        100.0 * d50,
        100.0 * d95
    );
    // Where the surface leaves what a blob can follow: its anchors' distance from their
    // affine map, against the blob's smallest semi-axis (the refit was not needed below it).
    let mut leave = Vec::new();
    for k in 0..seq.frames.len() {
        let t = prep.plan.timeline().time(k);
        for (i, b) in formed.iter().enumerate() {
            leave.push(deform.residual(i, t) / b.semi_axes.min_element());
        }
    }
    let (l50, lmax) = (pct(&mut leave, 0.5), pct(&mut leave, 1.0));
    println!(
        "anchors off their affine map: median {:.2} %, max {:.2} % of the blob's smallest \
         semi-axis",
        100.0 * l50,
        100.0 * lmax
    );
    assert!(
        median <= 0.1,
        "median billow drift {median} of the surface's travel"
    );
    assert!(
        p95 <= 0.35,
        "95th percentile billow drift {p95} of the surface's travel"
    );
}

/// `vel` holds the deformation: at the surface of the formed cloud, between two frames, the
/// density's velocity matches the mesh's own vertex velocity there.
#[test]
fn velocity_includes_the_deformation() {
    let shot = formed_tube_preview();
    let prep = shot.prepared().unwrap();
    let seq = MeshSequence::builtin("waving-tube").unwrap();
    let fps = prep.plan.timeline().fps;
    let (mut err, mut speed, mut n) = (0.0, 0.0, 0usize);
    for k in [5usize, 17, 30, 41] {
        let t = (k as f64 + 0.5) / fps;
        let field = prep.direction.velocity(&prep.plan, t);
        for v in (0..seq.frames[k].len()).step_by(7) {
            let x = (seq.frames[k][v] + seq.frames[k + 1][v]) * 0.5;
            let want = (seq.frames[k + 1][v] - seq.frames[k][v]) * fps;
            let got = field.velocity(x);
            err += (got - want).length();
            speed += want.length();
            n += 1;
        }
    }
    // The motion blur holds it too: the formed cloud's open shutter (the scene's 0.5) is not
    // still, its samples' blobs differ across the shutter.
    let blur = shot
        .shutter(17, 4)
        .unwrap()
        .expect("an open shutter on a bending cloud");
    assert_ne!(blur.samples[0].blobs, blur.samples[3].blobs);
    let rel = err / speed;
    println!(
        "vel against the mesh's vertex velocity at {n} surface points: mean error {:.1} % of \
         the mean speed ({:.3} units/s)",
        100.0 * rel,
        speed / n as f64
    );
    assert!(rel < 0.1, "vel error {rel} of the surface speed");
}

/// A tiny tetrahedron OBJ, its apex at `apex`.
fn tetra_obj(apex: DVec3, extra_vertex: bool) -> String {
    let mut s = format!(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv {} {} {}\n",
        apex.x, apex.y, apex.z
    );
    s.push_str("f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    if extra_vertex {
        // A fin on one face: one more vertex and face (another topology).
        s.push_str("v 1 1 1\nf 2 3 5\n");
    }
    s
}

/// The scene's error for a target `mesh`, with files `files` written beside it.
fn error_for(dir: &std::path::Path, mesh: &str, files: &[(&str, String)]) -> String {
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let text = format!("Scene(\n    target: Fit(mesh: \"{mesh}\", blobs: 8),\n)\n");
    let path = dir.join("scene.ron");
    match scene_from_str(&path, &text) {
        Ok(_) => panic!("{mesh}: loaded"),
        Err(e) => {
            assert!(
                matches!(e, SceneError::InvalidAt { line: 2, .. }),
                "{mesh}: not located at target.mesh: {e:?}"
            );
            e.to_string()
        }
    }
}

#[test]
fn sequence_errors_are_located_and_name_the_file() {
    let dir = temp_dir("deform-errors");
    let frame = |z: f64, extra| tetra_obj(DVec3::new(0.0, 0.0, z), extra);
    // A gap.
    let e = error_for(
        &dir,
        "gap_####.obj",
        &[
            ("gap_0001.obj", frame(1.0, false)),
            ("gap_0002.obj", frame(1.1, false)),
            ("gap_0004.obj", frame(1.3, false)),
        ],
    );
    assert!(
        e.contains("target.mesh") && e.contains("gap_0003.obj"),
        "{e}"
    );
    // One frame.
    let e = error_for(&dir, "one_####.obj", &[("one_0001.obj", frame(1.0, false))]);
    assert!(
        e.contains("at least two frames") && e.contains("one_0001.obj"),
        "{e}"
    );
    // None at all.
    let e = error_for(&dir, "none_####.obj", &[]);
    assert!(e.contains("no file matches"), "{e}");
    // Another topology: the frame and both vertex counts named.
    let e = error_for(
        &dir,
        "topo_##.obj",
        &[
            ("topo_07.obj", frame(1.0, false)),
            ("topo_08.obj", frame(1.2, true)),
        ],
    );
    assert!(
        e.contains("topo_08.obj") && e.contains("5 vertices") && e.contains("has 4"),
        "{e}"
    );
    // A USD mesh with a single time sample.
    let usda = |samples: &str| {
        format!(
            "#usda 1.0\n\ndef Mesh \"m\"\n{{\n    int[] faceVertexCounts = [3, 3, 3, 3]\n    \
             int[] faceVertexIndices = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]\n    \
             point3f[] points.timeSamples = {{\n{samples}\n    }}\n}}\n"
        )
    };
    let e = error_for(
        &dir,
        "still.usda",
        &[(
            "still.usda",
            usda("        1: [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)],"),
        )],
    );
    assert!(e.contains("still.usda") && e.contains("found 1"), "{e}");
}

/// A frame-numbered OBJ sequence and a time-sampled USD mesh of the same motion load as the
/// same sequence (their numbers the shot's frames), fitted on the first frame.
#[test]
fn obj_and_usd_sequences_read_the_same_frames() {
    let dir = temp_dir("deform-read");
    let apex = |k: u32| DVec3::new(0.1 * k as f64, 0.0, 1.0);
    let mut samples = String::new();
    for k in 1..=3u32 {
        std::fs::write(
            dir.join(format!("walk_{k:04}.obj")),
            tetra_obj(apex(k), false),
        )
        .unwrap();
        let a = apex(k);
        samples.push_str(&format!(
            "        {}: [(0, 0, 0), (1, 0, 0), (0, 1, 0), ({}, {}, {})],\n",
            2 * k,
            a.x,
            a.y,
            a.z
        ));
    }
    // Time codes at twice the frame rate: code 2k is frame k.
    let usda = format!(
        "#usda 1.0\n(\n    timeCodesPerSecond = 48\n)\n\ndef Mesh \"m\"\n{{\n    \
         int[] faceVertexCounts = [3, 3, 3, 3]\n    \
         int[] faceVertexIndices = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3]\n    \
         point3f[] points.timeSamples = {{\n{samples}    }}\n}}\n"
    );
    std::fs::write(dir.join("walk.usda"), usda).unwrap();
    let load = |mesh: &str| {
        let text = format!("Scene(target: Fit(mesh: \"{mesh}\"), shot: (fps: 24))");
        let scene = scene_from_str(&dir.join("scene.ron"), &text).unwrap();
        scene.deforming.clone().expect("a deforming target")
    };
    let (obj, usd) = (load("walk_####.obj"), load("walk.usda"));
    assert_eq!(obj.numbers, vec![1.0, 2.0, 3.0]);
    assert_eq!(usd.numbers, obj.numbers);
    assert_eq!(usd.frames.len(), 3);
    for (a, b) in obj.frames.iter().zip(&usd.frames) {
        for (p, q) in a.iter().zip(b) {
            assert!((*p - *q).length() < 1e-6, "{p} vs {q}");
        }
    }
    // A still target is not a sequence.
    std::fs::write(dir.join("still.obj"), tetra_obj(apex(1), false)).unwrap();
    let scene = scene_from_str(
        &dir.join("scene.ron"),
        "Scene(target: Fit(mesh: \"still.obj\"))",
    )
    .unwrap();
    assert!(scene.deforming.is_none());
}

/// Frames of a harder deformation, made in code from the waving tube's rest frame: the tube
/// stretched along its length by up to 1.6× while it bends by up to 120° about a bend line at
/// its base (so the outer side stretches more than the inner), over `n` frames.
fn bend_and_stretch(rest: &[DVec3], n: usize) -> Vec<Vec<DVec3>> {
    let base = rest.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    let length = rest.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max) - base;
    (0..n)
        .map(|k| {
            let tau = k as f64 / (n - 1) as f64;
            let stretch = 1.0 + 0.6 * tau;
            let angle = 120f64.to_radians() * tau;
            rest.iter()
                .map(|&p| {
                    let s = (p.y - base) * stretch;
                    if angle == 0.0 {
                        return DVec3::new(p.x, base + s, p.z);
                    }
                    // The centre line an arc of radius R through the base, bending toward −x.
                    let r = length * stretch / angle;
                    let phi = s / r;
                    let centre = DVec3::new(-r * (1.0 - phi.cos()), base + r * phi.sin(), 0.0);
                    let across = DVec3::new(phi.cos(), phi.sin(), 0.0);
                    centre + across * p.x + DVec3::Z * p.z
                })
                .collect()
        })
        .collect()
}

/// A mesh sequence written as OBJ files `NAME_####.obj` (frame numbers from 1) into `dir`.
fn write_obj_sequence(dir: &std::path::Path, name: &str, frames: &[Vec<DVec3>], tris: &[[u32; 3]]) {
    for (k, frame) in frames.iter().enumerate() {
        let mut text = String::new();
        for p in frame {
            text.push_str(&format!("v {:.9} {:.9} {:.9}\n", p.x, p.y, p.z));
        }
        for t in tris {
            text.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
        }
        std::fs::write(dir.join(format!("{name}_{:04}.obj", k + 1)), text).unwrap();
    }
}

/// A bending that stretches (made in code, 24 frames): the formed cloud's silhouette against
/// the mesh's on every frame follows it (IoU ≥ 0.8 everywhere); measured beside, the local
/// refit of `A`, `B` (`Deformation::with_refit`), which must stay within 0.03 of it.
#[test]
fn a_bend_that_stretches_is_followed_and_the_refit_measured() {
    let dir = std::env::temp_dir().join("nephele-deform-bend");
    std::fs::create_dir_all(&dir).unwrap();
    let tube = MeshSequence::builtin("waving-tube").unwrap();
    let frames = bend_and_stretch(&tube.frames[0], 24);
    write_obj_sequence(&dir, "bend", &frames, &tube.triangles);
    let text = "Scene(\n    target: Fit(mesh: \"bend_####.obj\", blobs: 160, seed: 1),\n    \
        animation: Aggregation((keyframes: 6, speed: (0.1, 0.18), easing: EaseOut, hold_seconds: 0.8)),\n    \
        camera: Auto((azimuth_deg: 0.0, elevation_deg: 10.0, distance: 1.1)),\n    \
        sun: (direction: (-0.5, -0.7, -0.4)),\n    \
        shot: (width: 640, height: 360, fps: 24, seconds: 1.0),\n    \
        timing: [(time: 0.0, progress: 1.0), (time: 10.0, progress: 1.0)],\n    \
        seed: 5,\n)\n";
    let path = dir.join("bend.ron");
    std::fs::write(&path, text).unwrap();
    let scene = load_scene(&path).unwrap();
    let opts = RenderOptions {
        output: Some(dir.clone()),
        preview: true,
        ..RenderOptions::default()
    };
    let shot = Shot::open(scene, &opts).unwrap();
    let prep = shot.prepared().unwrap();
    let deform = prep.direction.deform.clone().expect("the target deforms");
    let seq = MeshSequence::load_pattern(&dir.join("bend_####.obj").to_string_lossy()).unwrap();
    let formed = prep.plan.frame(prep.plan.timeline().frames - 1);
    let times: Vec<f64> = (0..seq.frames.len())
        .map(|k| prep.plan.timeline().time(k))
        .collect();
    let refit = Deformation::with_refit(&formed, &seq.frames, &times, &RefitConfig::default());
    assert_eq!(
        refit.carried_only(),
        deform.carried_only(),
        "the same carry"
    );
    let shaped =
        Deformation::with_shape_refit(&formed, &seq.frames, &times, &RefitConfig::default());
    assert_eq!(shaped, *deform, "the shot's deformation is the shape refit");
    let carry = deform.carried_only();
    let (mut worst_shape, mut sum_shape) = (f64::INFINITY, 0.0);
    let (mut worst, mut worst_refit, mut sum, mut sum_refit) =
        (f64::INFINITY, f64::INFINITY, 0.0, 0.0);
    let mut worst_gain = f64::INFINITY;
    for k in 0..shot.total() {
        let s = shot.settings(k).unwrap();
        let t = prep.plan.timeline().time(k as usize);
        let plan_blobs = prep.plan.at(prep.direction.scheme_time(t));
        let mesh = project_mesh(&s, &seq.frame(k as usize));
        let score = |blobs: &[nephele::blobby::Blob]| {
            let frame = render_frame(&s, blobs);
            iou(
                &Mask::from_alpha(&frame.alpha, s.width as usize, s.height as usize),
                &mesh,
            )
        };
        let reshaped = score(&shot.blobs(k).unwrap());
        let mut refitted = plan_blobs.clone();
        refit.apply(&mut refitted, t);
        let refitted = score(&refitted);
        let mut carried = plan_blobs.clone();
        carry.apply(&mut carried, t);
        let carried = score(&carried);
        (worst_shape, sum_shape) = (worst_shape.min(reshaped), sum_shape + reshaped);
        println!(
            "bend frame {:2}: IoU {reshaped:.3} (the shot's shape refit; carried only \
             {carried:.3}, A, B refitted {refitted:.3})",
            k + 1
        );
        (worst, worst_refit) = (worst.min(carried), worst_refit.min(refitted));
        (sum, sum_refit) = (sum + carried, sum_refit + refitted);
        worst_gain = worst_gain.min(refitted - carried);
    }
    let n = shot.total() as f64;
    let summary = refit.refit_summary();
    println!(
        "bend and stretch, {} blobs, carried only: IoU min {worst:.3}, mean {:.3}; A, B refitted: min \
         {worst_refit:.3}, mean {:.3}; refitted {} of {} (blob, frame) pairs, A × {:.3}–{:.3}, \
         B × {:.3}–{:.3}",
        prep.model.blobs.len(),
        sum / n,
        sum_refit / n,
        summary.refitted,
        summary.considered,
        summary.a_range[0],
        summary.a_range[1],
        summary.b_range[0],
        summary.b_range[1],
    );
    println!(
        "bend and stretch, the shot (shape refit): IoU min {worst_shape:.3}, mean {:.3}; {} \
         (blob, frame) pairs corrected",
        sum_shape / n,
        shaped.shape_refitted(),
    );
    assert!(
        summary.refitted > 0,
        "the bend leaves some blobs: {summary:?}"
    );
    assert!(
        worst_shape >= 0.8,
        "IoU {worst_shape:.3} < 0.8 on some frame"
    );
    // Measured: the shot (shape refit) min 0.840, mean 0.860 against the carry's 0.839, 0.859.
    assert!(
        shaped.shape_refitted() > 0 && worst_shape >= worst - 0.005 && sum_shape >= sum - 0.005 * n,
        "the shape refit loses IoU: min {worst_shape:.3} vs {worst:.3}"
    );
    assert!(
        worst_gain >= -0.03,
        "the refit loses {:.3} of IoU on some frame",
        -worst_gain
    );
}

/// A deforming target with a keyed transform: the keys win, as for a still target — on every
/// frame the cloud is the unplaced target's cloud on that frame of the sequence, placed where
/// the keys put the target at that time (`P(t)`), whatever the transform's own fields say.
#[test]
fn a_deforming_target_with_keys_is_placed_by_the_keys() {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(repo.join("scenes/waving-tube.ron")).unwrap();
    let dir = temp_dir("deform-keys");
    let shot_of = |name: &str, transform: &str| {
        let edited = text.replace(
            "    seed: 5,\n",
            &format!(
                "    seed: 5,\n    timing: [(time: 0.0, progress: 1.0), (time: 10.0, progress: \
                 1.0)],\n{transform}"
            ),
        );
        assert_ne!(edited, text, "the scene was edited");
        let path = dir.join(format!("{name}.ron"));
        std::fs::write(&path, edited).unwrap();
        let opts = RenderOptions {
            // The fit is shared with the other tests of this file (one cache folder).
            output: Some(std::env::temp_dir().join("nephele-deform-tube")),
            preview: true,
            ..RenderOptions::default()
        };
        let shot = Shot::open(load_scene(&path).unwrap(), &opts).unwrap();
        shot.prepared().unwrap();
        shot
    };
    let keyed = shot_of(
        "keyed",
        "    transform: (translate: (5.0, 0.0, 0.0), scale: 2.0, rotate_deg: (0.0, 40.0, 0.0), \
         keys: [\n        (time: 0.0, translate: (1.0, 0.0, 0.0), rotate_deg: (0.0, 0.0, 10.0), \
         scale: 1.2),\n        (time: 2.0, translate: (1.0, 1.5, -0.5), rotate_deg: (0.0, 30.0, \
         -20.0), scale: 0.9),\n    ]),\n",
    );
    let plain = shot_of("plain", "");
    let motion = keyed.scene().file.transform.motion().expect("keyed");
    let prep = keyed.prepared().unwrap();
    let diagonal = prep.bounds.diagonal();
    let mut worst = 0.0f64;
    for k in 0..keyed.total() {
        let t = prep.plan.timeline().time(k as usize);
        let mut want = plain.blobs(k).unwrap();
        motion.placement(t).apply(&mut want);
        let got = keyed.blobs(k).unwrap();
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            worst = worst.max((g.center - w.center).length() / diagonal);
            assert!(
                (g.semi_axes - w.semi_axes).abs().max_element() < 1e-6 * diagonal,
                "frame {k}: semi-axes {} vs {}",
                g.semi_axes,
                w.semi_axes
            );
            assert!(g.rotation.dot(w.rotation).abs() > 1.0 - 1e-9, "frame {k}");
            assert!((g.a - w.a).abs() < 1e-9 && (g.b - w.b).abs() < 1e-9);
        }
    }
    println!("keyed deforming target: centres within {worst:.2e} of the diagonal of P(t)·cloud");
    assert!(worst < 1e-6, "centres off by {worst} of the diagonal");
}
