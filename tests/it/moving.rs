//! Issue 51, items 2 and 6: a target whose `transform` is keyed over the shot (the cloud follows
//! it; `vel`, the shutter and the motion vectors include the motion) and a diffusion the artist
//! steers (`start`, `order`). Models are built in code; the VDB is read back by OpenVDB
//! (`tools/vdb_dump.py`, skipped with a message when absent, see `readers_support`).

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DMat3, DQuat, DVec3};
use nephele::animate::{self, Animation, DiffusionConfig, Timeline, VelocityField};
use nephele::blobby::{Blob, BlobModel, save_model};
use nephele::scene::{self, RenderOptions, SceneError, Shot};

use crate::export::openvdb_grid;
use crate::temp_support::{self, TempDir};

/// A small cloud of twelve overlapping ellipsoids about (1, 0.5, 0), largest first.
fn cloud() -> Vec<Blob> {
    (0..12)
        .map(|i| {
            let a = i as f64 * 0.7;
            Blob {
                center: DVec3::new(
                    1.0 + 0.5 * a.cos(),
                    0.5 + 0.3 * (2.0 * a).sin(),
                    0.4 * a.sin(),
                ),
                rotation: DQuat::from_euler(glam::EulerRot::XYZ, a, 0.5 * a, 0.2),
                semi_axes: DVec3::new(0.35, 0.25, 0.3) * (1.0 - 0.02 * i as f64),
                a: 1.0,
                b: 2.0,
            }
        })
        .collect()
}

/// A folder with `model.ron` (the test cloud) and `shot.ron`: 24 fps, one second, 48×30.
fn cloud_scene(test: &str, fields: &str) -> (TempDir, PathBuf) {
    let dir = temp_support::temp_dir(&format!("moving-{test}"));
    let model = BlobModel::from_blobs("test:cloud", 1.0, 1, cloud());
    save_model(&dir.join("model.ron"), &model).unwrap();
    let path = dir.join("shot.ron");
    std::fs::write(
        &path,
        format!(
            "Scene(\n  target: Model(\"model.ron\"),\n  shot: (width: 48, height: 30, fps: 24, \
             seconds: 1.0),\n  seed: 3,\n  {fields}\n)"
        ),
    )
    .unwrap();
    (dir, path)
}

fn open(path: &Path) -> Shot {
    let s = scene::load_scene(path).unwrap();
    Shot::open(s, &RenderOptions::default()).unwrap()
}

/// Two keys over the shot's second: translate, yaw and scale each at a constant rate.
const KEYS: &str = "transform: (keys: [(time: 0.0), (time: 1.0, translate: (0.6, 0.2, -0.1), \
                    rotate_deg: (0.0, 40.0, 0.0), scale: 1.3)])";

/// The keyed motion of [`KEYS`] at `t` and `x`: `Ṫ + ω × (x − T) + (ṡ/s)(x − T)`.
fn keyed_velocity(t: f64, x: DVec3) -> DVec3 {
    let rate = DVec3::new(0.6, 0.2, -0.1);
    let origin = rate * t;
    let (s, s_dot) = (1.0 + 0.3 * t, 0.3);
    let omega = DVec3::new(0.0, 40f64.to_radians(), 0.0);
    rate + omega.cross(x - origin) + (s_dot / s) * (x - origin)
}

/// A point inside blob `b`, off its centre.
fn inside(b: &Blob) -> DVec3 {
    b.center + DMat3::from_quat(b.rotation) * (b.semi_axes * DVec3::new(0.5, -0.3, 0.2))
}

/// Render frame number `frame` of `path` as a VDB into `out`.
fn render_vdb(path: &Path, out: &Path, frames: &str) {
    let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
        .arg("render")
        .arg(path)
        .args(["--frames", frames, "-o"])
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The cloud follows the keyed transform (each blob moved by `P(t)·P₀⁻¹`), the automatic camera
/// frames the whole path, and `vel` — from the API and in the VDB read by OpenVDB — equals the
/// keyed motion within 1 % where the density is > 0 (the plan still: the whole shot held).
#[test]
fn a_keyed_target_carries_the_cloud_and_vel_is_the_keyed_motion() {
    let (dir, path) = cloud_scene(
        "vel",
        &format!(
            "animation: Aggregation((hold_seconds: 2.0)),\n  {KEYS},\n  \
             output: (formats: [Vdb], voxel: 0.03)"
        ),
    );
    let shot = open(&path);
    let prep = shot.prepared().unwrap();
    let plan = prep.plan.frame(12);
    let moved = shot.blobs(12).unwrap();
    // At t = 0.5: translate (0.3, 0.1, −0.05), 20° about +Y, scale 1.15 (P₀ is the identity).
    let (t, s) = (0.5, 1.15);
    let r = DQuat::from_rotation_y(20f64.to_radians());
    for (p, m) in plan.iter().zip(&moved) {
        let want = DVec3::new(0.3, 0.1, -0.05) + s * (r * p.center);
        assert!((m.center - want).length() < 1e-9, "{} vs {want}", m.center);
        assert!((m.semi_axes - p.semi_axes * s).length() < 1e-9);
        assert!(m.rotation.angle_between(r * p.rotation) < 1e-6);
    }
    // The automatic camera frames every frame's cloud, not only the first.
    for k in [0, 23] {
        let b = animate::blob_bounds(&shot.blobs(k).unwrap());
        assert!(
            prep.framing.expanded(1e-9).contains(b.min)
                && prep.framing.expanded(1e-9).contains(b.max),
            "frame {k}"
        );
    }
    assert!(prep.framing.size().x > prep.bounds.size().x + 0.5);
    let field = prep.direction.velocity(&prep.plan, t);
    let mut worst = 0.0f64;
    for b in &moved {
        let x = inside(b);
        let want = keyed_velocity(t, x);
        worst = worst.max((field.velocity(x) - want).length() / want.length());
    }
    assert!(
        worst < 1e-5,
        "API vel differs from the keyed motion by {worst}"
    );
    // The shutter (motion blur) carries the motion too: each time sample's blobs are the cloud
    // at that time, their centres moving at the keyed motion.
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(
        &path,
        text.replace("seconds: 1.0)", "seconds: 1.0, shutter: 0.5)"),
    )
    .unwrap();
    let blurred = open(&path);
    let shutter = blurred
        .shutter(12, 4)
        .unwrap()
        .expect("a moving cloud is blurred");
    assert_eq!(shutter.samples.len(), 4);
    for sample in &shutter.samples {
        let bp = blurred.prepared().unwrap();
        let at = bp.direction.at(&bp.plan, t + sample.offset);
        assert_eq!(sample.blobs, at);
        for (b, v) in sample.blobs.iter().zip(&sample.velocity) {
            let want = keyed_velocity(t + sample.offset, b.center);
            assert!((*v - want).length() < 1e-6 * want.length(), "{v} vs {want}");
        }
    }
    std::fs::write(&path, text).unwrap();
    // The VDB, read by OpenVDB: every active voxel.
    let out = dir.join("out");
    render_vdb(&path, &out, "13");
    let Some((_, vel)) = openvdb_grid(&out.join("shot_0013.vdb"), "vel") else {
        return;
    };
    assert!(vel.len() > 1000, "{} voxels", vel.len());
    let (mut worst, mut sum) = (0.0f64, 0.0f64);
    for (_, p, v) in &vel {
        let want = keyed_velocity(t, DVec3::from(*p));
        let got = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        let e = (got - want).length() / want.length();
        worst = worst.max(e);
        sum += e;
    }
    eprintln!(
        "keyed target vel: {} voxels, worst relative error {worst:.2e}, mean {:.2e}",
        vel.len(),
        sum / vel.len() as f64
    );
    assert!(worst < 0.01, "vel differs from the keyed motion by {worst}");
}

/// In a diffusion whose target moves, the velocity is the keyed motion plus the diffusion's own
/// (carried along): it differs from the keyed motion wherever a blob grows or moves out — in
/// every phase (blob I growing, II moving out, III growing and the strengths rising) — and
/// equals it where nothing changes; every active voxel of the VDB moves, in each phase.
#[test]
fn a_moving_diffusion_has_its_own_velocity_in_every_phase() {
    let (dir, path) = cloud_scene(
        "diffusion",
        &format!(
            "animation: Diffusion((grow_seconds: 0.2, final_grow_seconds: 0.3, category_ii: 0.4, \
             hold_seconds: 0.2)),\n  {KEYS},\n  output: (formats: [Vdb], voxel: 0.03)"
        ),
    );
    let shot = open(&path);
    let prep = shot.prepared().unwrap();
    let (plan, tl) = (&prep.plan, prep.plan.timeline());
    let h = 1e-3 / tl.fps;
    let (mut changing_frames, mut still_frames) = (0, 0);
    for k in 0..tl.frames {
        let t = tl.time(k);
        let (before, now, after) = (
            plan.at((t - h).max(0.0)),
            plan.at(t),
            plan.at((t + h).min(tl.end())),
        );
        let carried = shot.blobs(k as u32).unwrap();
        let field = prep.direction.velocity(plan, t);
        let own = VelocityField::of_plan(plan, t);
        let mut changed = 0;
        for i in 0..now.len() {
            if !now[i].is_live() {
                continue;
            }
            let x = inside(&carried[i]);
            let relative = field.velocity(x) - keyed_velocity(t, x);
            if before[i] == now[i] && now[i] == after[i] {
                if own.velocity(inside(&now[i])) == DVec3::ZERO {
                    // A centred difference; one-sided (first order) at the shot's ends.
                    assert!(
                        relative.length() < 1e-4,
                        "frame {k}: blob {i} is still in the plan but moves by {relative}"
                    );
                }
                continue;
            }
            changed += 1;
            assert!(
                relative.length() > 1e-6,
                "frame {k}: blob {i} changes but its velocity is only the keyed motion"
            );
        }
        if changed > 0 {
            changing_frames += 1;
        } else {
            still_frames += 1;
        }
    }
    eprintln!("moving diffusion: {changing_frames} frames changing, {still_frames} held");
    assert!(changing_frames >= 15 && still_frames >= 3);
    // The VDB at a frame of category II, of the blend and of the hold: all active voxels move.
    let out = dir.join("out");
    render_vdb(&path, &out, "4,15,24");
    for frame in [4, 15, 24] {
        let Some((_, vel)) = openvdb_grid(&out.join(format!("shot_{frame:04}.vdb")), "vel") else {
            return;
        };
        assert!(!vel.is_empty());
        let slowest = vel
            .iter()
            .map(|(_, _, v)| DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64).length())
            .fold(f64::INFINITY, f64::min);
        eprintln!(
            "frame {frame}: {} voxels, slowest {slowest:.3} units/s",
            vel.len()
        );
        assert!(slowest > 0.1, "frame {frame}: a voxel with speed {slowest}");
    }
}

/// A shell of blobs around a large one (the model's selection order: largest first).
fn shell(n: usize) -> BlobModel {
    let mut blobs = vec![Blob {
        center: DVec3::ZERO,
        rotation: DQuat::IDENTITY,
        semi_axes: DVec3::new(1.4, 1.0, 0.8),
        a: 1.0,
        b: 2.0,
    }];
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    for i in 1..n {
        let t = i as f64;
        let y = 1.0 - 2.0 * (t - 0.5) / (n - 1) as f64;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let dir = DVec3::new(r * (golden * t).cos(), y, r * (golden * t).sin());
        let size = 0.45 - 0.2 * t / n as f64;
        blobs.push(Blob {
            center: dir * DVec3::new(1.9, 1.4, 1.1),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, t * 0.7, t * 1.3, t * 0.2),
            semi_axes: DVec3::new(size * 1.3, size, size * 0.8),
            a: 0.8,
            b: 2.2,
        });
    }
    BlobModel::from_blobs("test:shell", 1.0, 1, blobs)
}

fn timeline() -> Timeline {
    Timeline {
        frames: 48,
        fps: 24.0,
        hold_seconds: 0.25,
    }
}

/// The blob nearest `p` by its own ellipsoidal radius, computed here from the blobs' frames.
fn nearest(blobs: &[Blob], p: DVec3) -> usize {
    let rho = |b: &Blob| {
        let local = b.rotation.inverse() * (p - b.center) / b.semi_axes;
        local.length_squared()
    };
    (0..blobs.len())
        .filter(|&i| blobs[i].is_live())
        .min_by(|&a, &b| rho(&blobs[a]).total_cmp(&rho(&blobs[b])))
        .unwrap()
}

/// Steered from several start points: the first visible blob is the one nearest `start`, the
/// visible cloud is one piece at every frame and its volume never falls; an `order` shows its
/// blobs first, in its order.
#[test]
fn a_steered_diffusion_starts_at_the_start_and_keeps_its_bars() {
    use nephele::animate::stats::{Lattice, visible_volume};
    let model = shell(60);
    let b = animate::blob_bounds(&model.blobs);
    let lattice = Lattice::for_target(&b, 0.02);
    let appear = |plan: &animate::Plan, i: usize| {
        (0..timeline().frames)
            .find(|&k| plan.frame(k)[i].is_live() && plan.frame(k)[i].semi_axes.min_element() > 0.0)
    };
    for f in [
        DVec3::new(0.5, 0.5, 0.5),
        DVec3::new(0.95, 0.5, 0.5),
        DVec3::new(0.1, 0.9, 0.2),
        DVec3::new(0.5, 0.02, 0.9),
    ] {
        let start = b.min + b.size() * f;
        let anim: Animation = Animation::Diffusion(DiffusionConfig {
            start: Some(start),
            ..DiffusionConfig::default()
        });
        let plan = animate::plan(&anim, &model, timeline(), 1).unwrap();
        let first = plan.frame(0);
        let shown: Vec<usize> = (0..first.len()).filter(|&i| first[i].is_live()).collect();
        assert_eq!(shown, vec![nearest(&model.blobs, start)], "start {start}");
        let mut last = 0usize;
        for k in 0..timeline().frames {
            let v = visible_volume(&plan.frame(k), model.threshold, lattice);
            assert!(
                v.largest_share() >= 0.95,
                "start {start}, frame {k}: largest piece {:.3}",
                v.largest_share()
            );
            assert!(
                v.voxels >= last,
                "start {start}, frame {k}: the volume fell"
            );
            last = v.voxels;
        }
        assert_eq!(plan.frame(timeline().frames - 1), model.blobs);
    }
    // An explicit order: its blobs first, in its order, before any other.
    let order = vec![17, 3, 40];
    let anim: Animation = Animation::Diffusion(DiffusionConfig {
        order: order.clone(),
        ..DiffusionConfig::default()
    });
    let plan = animate::plan(&anim, &model, timeline(), 1).unwrap();
    assert_eq!(&plan.diffusion().unwrap().order()[..3], &order[..]);
    let first = plan.frame(0);
    assert!(first[17].is_live() && first.iter().filter(|b| b.is_live()).count() == 1);
    let (a, b3, c) = (appear(&plan, 17), appear(&plan, 3), appear(&plan, 40));
    assert!(a <= b3 && b3 <= c, "{a:?} {b3:?} {c:?}");
    for i in (0..60).filter(|i| !order.contains(i)) {
        assert!(appear(&plan, i) >= c, "blob {i} before the listed ones");
    }
}

/// The scene's errors for the new inputs, each at its `file:line:column`.
#[test]
fn bad_keys_starts_and_orders_are_located_errors() {
    let located = |e: &SceneError, line: usize, needle: &str| {
        let text = e.to_string();
        assert!(
            text.contains(&format!("shot.ron:{line}:")) && text.contains(needle),
            "expected line {line} and {needle:?}: {text}"
        );
    };
    // Parse errors: one key, times not increasing.
    for (keys, needle) in [
        ("transform: (keys: [(time: 0.0)])", "at least two"),
        (
            "transform: (keys: [(time: 1.0), (time: 1.0, scale: 2.0)])",
            "times must increase",
        ),
    ] {
        let (_d, path) = cloud_scene("bad-keys", keys);
        located(&scene::load_scene(&path).unwrap_err(), 5, needle);
    }
    // A holdout's transform is not keyed.
    let (d, path) = cloud_scene(
        "holdout-keys",
        "holdouts: [(mesh: \"h.obj\", transform: (keys: [(time: 0.0), (time: 1.0)]))]",
    );
    std::fs::write(d.join("h.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    located(&scene::load_scene(&path).unwrap_err(), 5, "only the target");
    // Checked against the target when the shot is planned.
    let plan_err = |test: &str, anim: &str| {
        let (_d, path) = cloud_scene(test, &format!("animation: Diffusion(({anim}))"));
        let shot = open(&path);
        shot.prepared().unwrap_err()
    };
    located(
        &plan_err("start-out", "start: (9.0, 0.5, 0.0)"),
        5,
        "outside the target's box",
    );
    located(
        &plan_err("order-range", "order: [2, 12]"),
        5,
        "the target has 12 blobs",
    );
    let (_d, path) = cloud_scene("order-twice", "animation: Diffusion((order: [2, 5, 2]))");
    located(&scene::load_scene(&path).unwrap_err(), 5, "listed twice");
    // A start inside the box plans, and its blob shows first.
    let (_d, path) = cloud_scene(
        "start-in",
        "animation: Diffusion((grow_seconds: 0.2, final_grow_seconds: 0.3, hold_seconds: 0.2, \
         start: (1.4, 0.5, 0.3)))",
    );
    let shot = open(&path);
    let blobs = shot.blobs(0).unwrap();
    let live: Vec<usize> = (0..blobs.len()).filter(|&i| blobs[i].is_live()).collect();
    assert_eq!(live, vec![nearest(&cloud(), DVec3::new(1.4, 0.5, 0.3))]);
}
