//! Export: the density grid read back by OpenVDB itself (`tools/vdb_dump.py` under the system
//! python with Debian's `python3-openvdb`), the USD stage read by usd-core (`tools/usd_project.py`
//! in `target/usd-venv`), the Mitsuba `.vol` layout, and the grid against the renderer's density.
//! A check whose reader is missing skips with a message, or fails under
//! `NEPHELE_REQUIRE_READERS=1` (`readers_support`).

use crate::exr_support;
use crate::readers_support::skip_or_fail;
use crate::temp_support;

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::{DQuat, DVec3, Vec3, Vec3A};
use nephele::blobby::Blob;
use nephele::export::{self, DensityGrid, Leaf};
use nephele::render::Frustum;
use nephele::render::{
    BlobMedium, Camera, CloudMaterial, Medium, Quality, RenderSettings, Sky, Sun,
};
use temp_support::TempDir;

/// A fresh temporary folder for one test.
fn temp_dir(name: &str) -> TempDir {
    temp_support::temp_dir(&format!("export-{name}"))
}

/// A small cloud away from the origin (so the translation matters): a body and a head of
/// overlapping ellipsoids.
fn cloud() -> Vec<Blob> {
    let mut blobs = Vec::new();
    for i in 0..12 {
        let a = i as f64 * 0.7;
        let c = DVec3::new(
            3.0 + 0.5 * a.cos(),
            -1.0 + 0.3 * (2.0 * a).sin(),
            2.0 + 0.4 * a.sin(),
        );
        blobs.push(Blob {
            center: c,
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, a, 0.5 * a, 0.2),
            semi_axes: DVec3::new(0.35, 0.25, 0.3),
            a: 1.0,
            b: 2.0,
        });
    }
    blobs
}

fn settings() -> RenderSettings {
    RenderSettings {
        width: 32,
        height: 18,
        camera: Camera {
            position: Vec3::new(3.0, 0.0, 6.0),
            look_at: Vec3::new(3.0, -1.0, 2.0),
            up: Vec3::Y,
            fov_deg: 35.0,
            shift: glam::Vec2::ZERO,
        },
        sun: Sun::default(),
        sky: Sky::default(),
        cloud: CloudMaterial::default(),
        exposure: 0.0,
        length_scale: 2.0,
        seed: 9,
        time: 0.0,
        quality: Quality::final_frame(),
        base: None,
        surfaces: None,
    }
}

/// The renderer's extinction at world point `p`, through the `Medium` contract: a ray starting
/// at `p` (so `t = 0` is the point itself) under a frustum that keeps every blob.
fn density_at(m: &BlobMedium, s: &mut <BlobMedium as Medium>::Scratch, p: Vec3A) -> f32 {
    let everything = Frustum {
        apex: p,
        forward: Vec3A::ZERO,
        planes: [Vec3A::ZERO; 4],
    };
    m.begin_tile(&everything, s);
    export::grid::point_extinction(m, s, p)
}

/// What OpenVDB read: the JSON header and the active voxels `(ijk, world centre, value)`.
struct Dump {
    header: serde_json::Value,
    voxels: Vec<([i32; 3], [f64; 3], f32)>,
}

/// Run `tools/vdb_dump.py` on `path` for the `density` grid; `None` (after saying why) when
/// OpenVDB's python module is not installed.
fn openvdb_read(path: &Path) -> Option<Dump> {
    let (header, voxels) = openvdb_grid(path, "density")?;
    let voxels = voxels
        .into_iter()
        .map(|(ijk, p, v)| (ijk, p, v[0]))
        .collect();
    Some(Dump { header, voxels })
}

/// Active voxels as OpenVDB reads them: `(ijk, world centre, value components)`.
pub(crate) type Voxels = Vec<([i32; 3], [f64; 3], Vec<f32>)>;

/// Run `tools/vdb_dump.py` on grid `name` of `path`: its JSON header and active voxels;
/// `None` (after saying why) when OpenVDB's python module is not installed.
pub(crate) fn openvdb_grid(path: &Path, name: &str) -> Option<(serde_json::Value, Voxels)> {
    let out = path.with_extension(format!("{name}.dump.txt"));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/vdb_dump.py");
    let run = Command::new("/usr/bin/python3")
        .arg(&script)
        .arg(path)
        .arg(name)
        .arg(&out)
        .output();
    let run = match run {
        Ok(r) => r,
        Err(e) => {
            skip_or_fail(
                "OpenVDB",
                &format!("/usr/bin/python3 cannot run ({e}); install Debian's python3-openvdb"),
            );
            return None;
        }
    };
    if run.status.code() == Some(3) {
        skip_or_fail(
            "OpenVDB",
            &format!(
                "{} (install Debian's python3-openvdb)",
                String::from_utf8_lossy(&run.stderr).trim()
            ),
        );
        return None;
    }
    assert!(
        run.status.success(),
        "OpenVDB could not read {}: {}",
        path.display(),
        String::from_utf8_lossy(&run.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: serde_json::Value = serde_json::from_str(lines.next().unwrap()).unwrap();
    let voxels = lines
        .map(|l| {
            let w: Vec<&str> = l.split(' ').collect();
            let i = |k: usize| w[k].parse::<i32>().unwrap();
            let f = |k: usize| w[k].parse::<f64>().unwrap();
            let values = (6..w.len()).map(|k| f(k) as f32).collect();
            ([i(0), i(1), i(2)], [f(3), f(4), f(5)], values)
        })
        .collect();
    Some((header, voxels))
}

#[test]
fn openvdb_reads_back_the_renderer_density() {
    let (settings, blobs) = (settings(), cloud());
    let medium = BlobMedium::new(&settings, &blobs);
    let (lo, hi) = medium.bounds().unwrap();
    // Small enough that the cloud spans several Internal-4 nodes (128 voxels each).
    let voxel = 0.015;
    let grid = export::frame_grid(&settings, &blobs, voxel).unwrap();
    let active = grid.active_count();
    assert!(active > 10_000, "{active} active voxels");
    let dir = temp_dir("roundtrip");
    let path = dir.join("cloud_0001.vdb");
    export::write_vdb(&path, &grid, export::GRID_NAME, 1).unwrap();
    let Some(dump) = openvdb_read(&path) else {
        return;
    };
    let h = &dump.header;
    assert_eq!(h["grids"], serde_json::json!(["density"]));
    assert_eq!(h["name"], "density");
    assert_eq!(h["class"], "fog volume");
    assert_eq!(h["background"], 0.0);
    for a in 0..3 {
        assert!((h["voxel_size"][a].as_f64().unwrap() - voxel).abs() < 1e-12);
    }
    assert_eq!(h["active"].as_u64().unwrap() as usize, active);
    assert_eq!(dump.voxels.len(), active);
    // The world box of the active voxels lies inside the blobs' supports' box, and fills it to
    // within the soft edge (the density ends before the support does).
    let wb = &h["world_bbox"];
    for a in 0..3 {
        let (min, max) = (wb[0][a].as_f64().unwrap(), wb[1][a].as_f64().unwrap());
        assert!(
            min >= lo[a] as f64 - 1e-9 && max <= hi[a] as f64 + 1e-9,
            "axis {a}"
        );
        assert!(
            max - min > 0.5 * (hi[a] - lo[a]) as f64,
            "axis {a}: {min}..{max}"
        );
    }
    // Every active voxel: finite, positive, and the renderer's density at its centre (as
    // OpenVDB's transform places it).
    let peak = grid.max_value();
    let mut scratch = medium.scratch();
    let mut worst = 0.0f32;
    for (ijk, p, v) in &dump.voxels {
        assert!(v.is_finite() && *v > 0.0, "{ijk:?}: {v}");
        let p = Vec3A::new(p[0] as f32, p[1] as f32, p[2] as f32);
        worst = worst.max((density_at(&medium, &mut scratch, p) - v).abs());
    }
    eprintln!("{active} active voxels, peak {peak}, max |OpenVDB − renderer| = {worst:e}");
    assert!(worst <= 1e-6 * peak, "max error {worst} vs peak {peak}");
}

/// Leaves scattered over several Internal-5 nodes (negative coordinates, beyond 4096) and
/// Internal-4 slots: OpenVDB reads every value at its index.
/// A half-float VDB (`Precision::Half`: Houdini's "Write 16-bit Floats") read by OpenVDB:
/// both grids flagged `is_saved_as_half_float`, the same active voxels, every value within half
/// precision of the 32-bit grid's, and the file about half the size.
#[test]
fn openvdb_reads_half_float_grids_within_half_precision() {
    let (settings, blobs) = (settings(), cloud());
    let grid = export::frame_grid(&settings, &blobs, 0.015).unwrap();
    let field = nephele::animate::VelocityField::new(
        &blobs
            .iter()
            .map(|b| Blob {
                center: b.center - DVec3::new(0.1, 0.0, 0.05),
                ..*b
            })
            .collect::<Vec<_>>(),
        &blobs,
        &blobs
            .iter()
            .map(|b| Blob {
                center: b.center + DVec3::new(0.1, 0.0, 0.05),
                ..*b
            })
            .collect::<Vec<_>>(),
        0.25,
    );
    let vel = export::sample_velocity(&grid, &field);
    let dir = temp_dir("half");
    let [full, half] = [export::Precision::Full, export::Precision::Half].map(|p| {
        let path = dir.join(format!("cloud_{p:?}.vdb"));
        let grids = [
            export::VdbGrid::fog(export::GRID_NAME, &grid).with_precision(p),
            export::velocity_vdb_grid(&vel, 24.0).with_precision(p),
        ];
        export::write_vdb_grids(&path, &grids, 1).unwrap();
        path
    });
    let size = |p: &Path| std::fs::metadata(p).unwrap().len() as f64;
    let ratio = size(&half) / size(&full);
    eprintln!(
        "{} active voxels: full {:.2} MB, half {:.2} MB ({ratio:.3})",
        grid.active_count(),
        size(&full) / 1e6,
        size(&half) / 1e6
    );
    assert!((0.45..0.56).contains(&ratio), "half/full size {ratio}");
    let Some((dh, density)) = openvdb_grid(&half, "density") else {
        return;
    };
    let (vh, vel_read) = openvdb_grid(&half, "vel").expect("OpenVDB read the density");
    for h in [&dh, &vh] {
        assert_eq!(h["half"], true, "{h}");
        assert_eq!(h["metadata"]["is_saved_as_half_float"], true, "{h}");
    }
    assert_eq!(dh["class"], "fog volume");
    assert_eq!(vh["type"], "Vec3SGrid");
    let (fh, _) = openvdb_grid(&full, "density").unwrap();
    assert_eq!(fh["half"], false);
    for key in ["voxel_size", "index_bbox", "world_bbox", "active"] {
        assert_eq!(dh[key], fh[key], "{key}");
    }
    // Half precision: 11 significant bits (relative 2^-11 after rounding), subnormals below
    // 2^-14 in steps of 2^-24.
    let close = |got: f32, want: f32| (got - want).abs() <= want.abs() * 4.9e-4 + 3.0e-8;
    let exact: std::collections::HashMap<[i32; 3], f32> = grid
        .leaves
        .iter()
        .flat_map(|l| l.active().collect::<Vec<_>>())
        .collect();
    assert_eq!(density.len(), exact.len());
    for (ijk, _, v) in &density {
        let want = exact[ijk];
        assert!(close(v[0], want), "{ijk:?}: {} vs {want}", v[0]);
    }
    let mut exact_vel = std::collections::HashMap::new();
    for l in &vel.leaves {
        for i in 0..512 {
            if l.is_active(i) {
                let o = Leaf::offset(i);
                exact_vel.insert(std::array::from_fn(|a| l.origin[a] + o[a]), l.values[i]);
            }
        }
    }
    assert_eq!(vel_read.len(), exact_vel.len());
    for (ijk, _, v) in &vel_read {
        let want: [f32; 3] = exact_vel[ijk];
        for a in 0..3 {
            assert!(close(v[a], want[a]), "{ijk:?}: {v:?} vs {want:?}");
        }
    }
}

#[test]
fn openvdb_reads_scattered_leaves_at_their_index() {
    let origins = [
        [-4104, 0, 8],
        [-8, -8, -8],
        [0, 0, 0],
        [0, 0, 128],
        [0, 8, 0],
        [0, 136, 0],
        [128, 0, 0],
        [4096, 8, 16],
        [8192, -4096, 40],
    ];
    let leaves = origins
        .iter()
        .enumerate()
        .map(|(n, &origin)| {
            let mut values = Box::new([0.0f32; 512]);
            for (i, v) in values.iter_mut().enumerate() {
                if (i * 7 + n) % 5 != 0 {
                    *v = (n * 512 + i) as f32 * 0.25 + 1.0;
                }
            }
            Leaf { origin, values }
        })
        .collect();
    let grid = DensityGrid {
        voxel: 0.5,
        translation: [-1.5, 2.0, 0.5],
        leaves,
    };
    let dir = temp_dir("scattered");
    let path = dir.join("scattered.vdb");
    export::write_vdb(&path, &grid, export::GRID_NAME, 7).unwrap();
    let Some(dump) = openvdb_read(&path) else {
        return;
    };
    assert_eq!(dump.voxels.len(), grid.active_count());
    for (ijk, p, v) in &dump.voxels {
        assert_eq!(*v, grid.value(*ijk), "{ijk:?}");
        let w = grid.world(*ijk);
        assert!(
            (0..3).all(|a| (w[a] - p[a]).abs() < 1e-9),
            "{ijk:?}: {p:?} vs {w:?}"
        );
    }
}

#[test]
fn empty_frame_is_a_valid_empty_grid() {
    let grid = export::frame_grid(&settings(), &[], 0.05).unwrap();
    assert!(grid.leaves.is_empty());
    let dir = temp_dir("empty");
    let path = dir.join("empty_0001.vdb");
    export::write_vdb(&path, &grid, export::GRID_NAME, 1).unwrap();
    export::write_vol(&dir.join("empty_0001.vol"), &grid).unwrap();
    let Some(dump) = openvdb_read(&path) else {
        return;
    };
    assert_eq!(dump.header["active"], 0);
    assert!(dump.voxels.is_empty());
}

#[test]
fn vol_holds_the_grid_densely() {
    let grid = export::frame_grid(&settings(), &cloud(), 0.04).unwrap();
    let bytes = export::vol::encode_vol(&grid).unwrap();
    let i32_at = |at: usize| i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let f32_at = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    let (lo, hi) = grid.active_index_bounds().unwrap();
    let dims: [usize; 3] = std::array::from_fn(|a| (hi[a] - lo[a] + 1) as usize);
    assert_eq!([i32_at(8), i32_at(12), i32_at(16)], dims.map(|d| d as i32));
    assert_eq!(bytes.len(), 48 + 4 * dims.iter().product::<usize>());
    // Every value at its place; the sum of the dense data is the sum of the grid.
    let mut sum = 0.0f64;
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                let v = f32_at(48 + 4 * ((z * dims[1] + y) * dims[0] + x));
                let ijk = [lo[0] + x as i32, lo[1] + y as i32, lo[2] + z as i32];
                assert_eq!(v, grid.value(ijk));
                sum += v as f64;
            }
        }
    }
    let total: f64 = grid
        .leaves
        .iter()
        .flat_map(|l| l.values.iter())
        .map(|&v| v as f64)
        .sum();
    assert!((sum - total).abs() <= 1e-9 * total);
    // The box's minimum corner is half a voxel below the first centre.
    let first = grid.world(lo);
    assert!((f32_at(24) as f64 - (first[0] - 0.02)).abs() < 1e-5);
}

/// A scene folder holding `model.ron` (the test cloud) and `shot.ron` with `extra` fields.
fn cloud_scene(test: &str, extra: &str) -> (TempDir, PathBuf) {
    cloud_scene_with(test, "Diffusion(())", 8, extra)
}

/// [`cloud_scene`] with the given `animation` at `fps` frames per second.
fn cloud_scene_with(test: &str, animation: &str, fps: u32, extra: &str) -> (TempDir, PathBuf) {
    use nephele::blobby::{BlobModel, save_model};
    let dir = temp_dir(test);
    let blobs = cloud();
    let model = BlobModel::from_blobs("test:cloud", 1.0, 1, blobs);
    save_model(&dir.join("model.ron"), &model).unwrap();
    let path = dir.join("shot.ron");
    std::fs::write(
        &path,
        format!(
            "Scene(target: Model(\"model.ron\"), animation: {animation}, \
             camera: Auto((azimuth_deg: 40.0, elevation_deg: 20.0, orbit_deg: 60.0)), \
             shot: (width: 48, height: 30, fps: {fps}, seconds: 1.0), seed: 3, {extra})"
        ),
    )
    .unwrap();
    (dir, path)
}

/// `p·M` for a row-major 4×4 `M` (row vectors), before the homogeneous divide.
fn row_times(p: [f64; 3], m: &[f32; 16]) -> [f64; 4] {
    std::array::from_fn(|c| {
        (0..3).map(|r| p[r] * m[r * 4 + c] as f64).sum::<f64>() + m[12 + c] as f64
    })
}

#[test]
fn exr_carries_the_camera_and_reprojects_a_point() {
    use nephele::scene::{self, RenderOptions};
    let (dir, path) = cloud_scene("exr", "output: (formats: [Exr, Vdb], voxel: 0.03)");
    let s = scene::load_scene(&path).unwrap();
    let out = dir.join("out");
    let opts = RenderOptions {
        frames: Some(nephele::scene::frames::FrameSelection::range(6, 6)),
        output: Some(out.clone()),
        ..RenderOptions::default()
    };
    scene::render_shot(&s, &opts, &mut |_| {}).unwrap();
    assert!(out.join("shot_0006.vdb").is_file());
    let attrs = exr_support::read_first_layer(&out.join("shot_0006.exr")).attributes;
    let text = |k: &str| match attrs
        .other
        .get(&exr::meta::attribute::Text::new_or_panic(k))
    {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
        other => panic!("{k}: {other:?}"),
    };
    assert_eq!(text("nephele/scene"), "shot.ron");
    assert_eq!(text("nephele/frame"), "6");
    assert_eq!(text("nephele/seed"), "3");
    assert_eq!(text("nephele/version"), env!("CARGO_PKG_VERSION"));
    let to_cam = attrs.world_to_camera.expect("worldToCamera");
    let to_ndc = attrs.world_to_normalized_device.expect("worldToNDC");
    // The renderer's camera of that frame (the orbit makes it differ from frame 1's).
    let shot = scene::Shot::open(s.clone(), &opts).unwrap();
    let settings = shot.settings(5).unwrap();
    let rays = nephele::render::CameraRays::new(&settings.camera, 48, 30);
    let (pixels, points) = known_points(&settings.camera);
    for (want, p) in pixels.iter().zip(points) {
        let n = row_times(p, &to_ndc);
        let got = [n[0] / n[3] * 48.0, n[1] / n[3] * 30.0];
        let off = (got[0] - want[0]).hypot(got[1] - want[1]);
        assert!(
            off < 1e-3,
            "{p:?}: worldToNDC gives pixel {got:?}, renderer {want:?}"
        );
        // Camera space: +z is the distance along the view direction.
        let c = row_times(p, &to_cam);
        let to_p = glam::DVec3::from(p) - settings.camera.position.as_dvec3();
        assert!((c[2] - to_p.dot(rays.forward.as_dvec3())).abs() < 1e-4);
        assert!(c[0] * (want[0] - 24.0) > 0.0 && c[1] * (want[1] - 15.0) < 0.0);
    }
}

/// Pixels near the corners and the centre of a 48×30 image, and world points on the renderer's
/// rays through them (at different distances).
fn known_points(camera: &Camera) -> (Vec<[f64; 2]>, Vec<[f64; 3]>) {
    let rays = nephele::render::CameraRays::new(camera, 48, 30);
    let pixels = vec![[3.25, 2.5], [44.5, 27.75], [40.0, 4.0], [20.5, 16.25]];
    let points = pixels
        .iter()
        .enumerate()
        .map(|(n, px)| {
            let d = rays.dir(px[0] as f32, px[1] as f32).as_dvec3();
            (camera.position.as_dvec3() + d * (2.0 + n as f64)).to_array()
        })
        .collect();
    (pixels, points)
}

#[test]
fn exr_bytes_are_identical_across_encodings() {
    use nephele::render::output::{FrameMetadata, encode_exr_with};
    let frame = nephele::render::Frame {
        width: 4,
        height: 2,
        rgb: vec![[0.5, 0.25, 0.125]; 8],
        alpha: vec![0.75; 8],
        depth: vec![3.0; 8],
        passes: None,
        mattes: None,
        motion: None,
        holdout: None,
        shadow: None,
        shadow_total: None,
        region: None,
    };
    let strings = ["scene", "frame", "seed", "version"]
        .iter()
        .map(|k| (k.to_string(), format!("value of {k}")))
        .collect();
    let meta = FrameMetadata::new(&settings().camera, 4, 2, strings);
    let first = encode_exr_with(&frame, Some(&meta)).unwrap();
    // Every encoding builds fresh hash maps (new random orders); the bytes must not change.
    for _ in 0..8 {
        assert_eq!(encode_exr_with(&frame, Some(&meta)).unwrap(), first);
    }
}

/// The python with Pixar's `pxr`: `$NEPHELE_USD_PYTHON`, else the venv `.ci/run` makes in
/// `target/usd-venv`; `None` (after saying why) when neither exists.
fn usd_python() -> Option<PathBuf> {
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/usd-venv/bin/python");
    let python = std::env::var_os("NEPHELE_USD_PYTHON")
        .map(PathBuf::from)
        .unwrap_or(venv);
    if python.is_file() {
        Some(python)
    } else {
        skip_or_fail(
            "usd-core",
            &format!(
                "{} not found (`python3 -m venv target/usd-venv && \
                 target/usd-venv/bin/pip install usd-core`, as .ci/run does)",
                python.display()
            ),
        );
        None
    }
}

#[test]
fn usd_stage_camera_projects_like_the_renderer() {
    use nephele::scene::{self, RenderOptions};
    let (dir, path) = cloud_scene("usd", "output: (formats: [Vdb], voxel: 0.03)");
    // A 180° shutter: the stage's camera carries it.
    let text = std::fs::read_to_string(&path).unwrap();
    std::fs::write(
        &path,
        text.replace("seconds: 1.0)", "seconds: 1.0, shutter: 0.5)"),
    )
    .unwrap();
    let stage_path = dir.join("stage/shot.usda");
    let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
        .arg("usd")
        .arg(&path)
        .arg("--frames-dir")
        .arg(dir.join("out"))
        .arg("-o")
        .arg(&stage_path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let Some(python) = usd_python() else {
        return;
    };
    let s = scene::load_scene(&path).unwrap();
    let opts = RenderOptions {
        output: Some(dir.join("out")),
        ..RenderOptions::default()
    };
    let shot = scene::Shot::open(s.clone(), &opts).unwrap();
    let first = RenderOptions {
        frames: Some(nephele::scene::frames::FrameSelection::range(1, 1)),
        ..opts.clone()
    };
    scene::render_shot(&s, &first, &mut |_| {}).unwrap();
    for frame in [1u32, 5, 8] {
        let settings = shot.settings(shot.index(frame)).unwrap();
        let (pixels, points) = known_points(&settings.camera);
        let mut cmd = Command::new(&python);
        cmd.arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/usd_project.py"))
            .arg(&stage_path)
            .args(["48", "30", &frame.to_string()]);
        points.iter().flatten().for_each(|c| {
            cmd.arg(c.to_string());
        });
        let run = cmd.output().unwrap();
        if run.status.code() == Some(3) {
            skip_or_fail("usd-core", String::from_utf8_lossy(&run.stderr).trim());
            return;
        }
        assert!(
            run.status.success(),
            "{}",
            String::from_utf8_lossy(&run.stderr)
        );
        let j: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(
            (j["start"].as_f64(), j["end"].as_f64()),
            (Some(1.0), Some(8.0))
        );
        assert_eq!(
            (j["fps"].as_f64(), j["tcps"].as_f64()),
            (Some(8.0), Some(8.0))
        );
        assert_eq!(j["up_axis"], "Y");
        assert_eq!(
            (j["sun"].as_str(), j["sky"].as_str()),
            (Some("DistantLight"), Some("DomeLight"))
        );
        assert_eq!(j["field_name"], "density");
        assert_eq!(j["shutter"], serde_json::json!([-0.25, 0.25]));
        // The velocity beside it, in the same frame files.
        let vel = &j["fields"]["vel"];
        assert_eq!(vel["field_name"], "vel");
        assert_eq!(vel["data_type"], "float3");
        assert_eq!(vel["vdb"], format!("../out/shot_{frame:04}.vdb"));
        assert_eq!(j["vdb"], format!("../out/shot_{frame:04}.vdb"));
        // USD resolves the path of the frame rendered (only existing files resolve).
        let resolved = j["vdb_resolved"].as_str().unwrap();
        if frame == 1 {
            assert_eq!(
                std::fs::canonicalize(resolved).unwrap(),
                std::fs::canonicalize(dir.join("out/shot_0001.vdb")).unwrap()
            );
        }
        // The stage's camera puts each point on the pixel whose ray the renderer cast at it.
        for (want, got) in pixels.iter().zip(j["pixels"].as_array().unwrap()) {
            let got = [got[0].as_f64().unwrap(), got[1].as_f64().unwrap()];
            let off = (got[0] - want[0]).hypot(got[1] - want[1]);
            assert!(
                off < 1e-3,
                "frame {frame}: pixel {got:?}, renderer {want:?}"
            );
        }
    }
}

/// Frame VDBs in a folder whose name holds `@` (and `@@@`) resolve through usd-core to the very
/// files; a scene file name with a newline (in the stage's `doc`) still gives a stage usd-core
/// opens; a frame name with a newline is refused with a clear error and no stage.
#[test]
fn usd_stage_asset_paths_resolve_with_at_signs_and_odd_names() {
    let (dir, path) = cloud_scene("usd-names", "output: (formats: [Vdb], voxel: 0.03)");
    let nephele = |args: &[&std::ffi::OsStr]| {
        Command::new(env!("CARGO_BIN_EXE_nephele"))
            .args(args)
            .current_dir(&*dir)
            .output()
            .unwrap()
    };
    // Written by the scene file itself: output.name keeps the frame names plain.
    let odd = dir.join("odd\nscene.ron");
    std::fs::write(
        &odd,
        std::fs::read_to_string(&path)
            .unwrap()
            .replace("voxel: 0.03)", "voxel: 0.03, name: \"shot\")"),
    )
    .unwrap();
    for folder in ["out@v2", "a@b@@@c@"] {
        let frames = dir.join(folder);
        let o = nephele(&[
            "render".as_ref(),
            odd.as_os_str(),
            "--frames".as_ref(),
            "1".as_ref(),
            "--output".as_ref(),
            frames.as_os_str(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stage = dir.join("stage").join(format!("{folder}.usda"));
        let o = nephele(&[
            "usd".as_ref(),
            odd.as_os_str(),
            "--frames-dir".as_ref(),
            frames.as_os_str(),
            "-o".as_ref(),
            stage.as_os_str(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let text = std::fs::read_to_string(&stage).unwrap();
        assert!(!text.contains("%40"), "{text}");
        let Some(python) = usd_python() else {
            return;
        };
        let run = Command::new(&python)
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("tools/usd_project.py"))
            .arg(&stage)
            .args(["48", "30", "1", "0", "0", "0"])
            .output()
            .unwrap();
        if run.status.code() == Some(3) {
            skip_or_fail("usd-core", String::from_utf8_lossy(&run.stderr).trim());
            return;
        }
        assert!(
            run.status.success(),
            "{folder}: usd-core cannot open the stage:\n{}\n{text}",
            String::from_utf8_lossy(&run.stderr)
        );
        let j: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        assert_eq!(j["vdb"], format!("../{folder}/shot_0001.vdb"));
        assert_eq!(j["fields"]["vel"]["vdb"], j["vdb"]);
        let resolved = j["vdb_resolved"].as_str().unwrap();
        assert!(!resolved.is_empty(), "{folder}: the VDB does not resolve");
        assert_eq!(
            std::fs::canonicalize(resolved).unwrap(),
            std::fs::canonicalize(frames.join("shot_0001.vdb")).unwrap()
        );
    }
    // A newline in the frame names (the default output.name is the scene file's name) cannot be
    // in a USD asset path: refused, naming the scene and the fix, and no stage is written.
    let bad = dir.join("bad\nname.ron");
    std::fs::copy(&path, &bad).unwrap();
    let stage = dir.join("stage/bad.usda");
    let o = nephele(&[
        "usd".as_ref(),
        bad.as_os_str(),
        "-o".as_ref(),
        stage.as_os_str(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("bad\nname.ron") && err.contains("newline") && err.contains("output.name"),
        "{err}"
    );
    assert!(!stage.exists());
}

#[test]
fn bad_voxel_sizes_are_clear_errors_before_any_frame() {
    use nephele::scene::{self, RenderOptions, SceneError};
    for bad in ["0.0", "-0.5", "inf"] {
        let (_dir, path) = cloud_scene(
            "voxel-bad",
            &format!("output: (formats: [Vdb], voxel: {bad})"),
        );
        let err = scene::load_scene(&path).unwrap_err();
        assert!(
            matches!(&err, SceneError::InvalidAt { field, .. } if field == "output.voxel"),
            "{bad}: {err}"
        );
    }
    // Absurdly small: more than 2^31 voxels over the target's box. Nothing is written.
    let (dir, path) = cloud_scene("voxel-tiny", "output: (formats: [Exr, Vdb], voxel: 0.0001)");
    let s = scene::load_scene(&path).unwrap();
    let out = dir.join("out");
    let opts = RenderOptions {
        output: Some(out.clone()),
        ..RenderOptions::default()
    };
    let err = scene::render_shot(&s, &opts, &mut |_| {}).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("output.voxel") && text.contains("larger voxel"),
        "{text}"
    );
    let frames: Vec<_> = std::fs::read_dir(&out)
        .map(|d| d.map(|e| e.unwrap().file_name()).collect())
        .unwrap_or_default();
    assert!(
        frames
            .iter()
            .all(|n| n.to_string_lossy().starts_with("target")),
        "{frames:?}"
    );
    // The command line says so and exits non-zero; an unknown --formats entry too.
    let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
        .arg("render")
        .arg(&path)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("output.voxel"));
    let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
        .arg("render")
        .arg(&path)
        .args(["--formats", "exr,obj"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("'obj' is not a format"));
}

/// `output.voxel_pixels` and `output.vdb_precision`: checked with located errors, and a shot
/// written with them has the voxel of the pixel footprint at the target's centre from its
/// nearest camera (read back by OpenVDB, half floats flagged).
#[test]
fn voxel_from_the_pixel_footprint_and_half_floats_through_a_scene() {
    use nephele::scene::{self, RenderOptions, SceneError};
    for (bad, says) in [
        ("voxel_pixels: 0.0", "positive number of pixels"),
        ("voxel_pixels: -1.0", "positive number of pixels"),
        ("voxel_pixels: inf", "positive number of pixels"),
        ("voxel_pixels: 1.0, voxel: 0.02", "not both"),
    ] {
        let (_dir, path) = cloud_scene("voxel-pixels-bad", &format!("output: ({bad})"));
        let err = scene::load_scene(&path).unwrap_err();
        assert!(
            matches!(&err, SceneError::InvalidAt { field, message, .. }
                if field == "output.voxel_pixels" && message.contains(says)),
            "{bad}: {err}"
        );
    }
    let (_dir, path) = cloud_scene("precision-bad", "output: (vdb_precision: Quarter)");
    let err = scene::load_scene(&path).unwrap_err().to_string();
    assert!(err.contains("Quarter"), "{err}");
    let (dir, path) = cloud_scene(
        "voxel-pixels",
        "output: (formats: [Vdb], voxel_pixels: 2.0, vdb_precision: Half)",
    );
    let out = dir.join("out");
    let opts = RenderOptions {
        output: Some(out.clone()),
        ..RenderOptions::default()
    };
    let s = scene::load_scene(&path).unwrap();
    let shot = scene::Shot::open(s, &opts).unwrap();
    // Two pixels' footprint, 2·d·tan(fov/2)/height, at the target's centre, from the nearest
    // of the shot's cameras (this one orbits at a fixed distance).
    let bounds = shot.prepared().unwrap().bounds;
    let centre = 0.5 * (bounds.min + bounds.max);
    let want = (0..shot.total())
        .map(|k| {
            let c = shot.settings(k).unwrap().camera;
            let d = (centre - c.position.as_dvec3()).length();
            2.0 * 2.0 * d * (f64::from(c.fov_deg) / 2.0).to_radians().tan() / 30.0
        })
        .fold(f64::INFINITY, f64::min);
    let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
        .arg("render")
        .arg(&path)
        .args(["--frames", "8", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let vdb = out.join("shot_0008.vdb");
    let Some((h, voxels)) = openvdb_grid(&vdb, "density") else {
        return;
    };
    let got = h["voxel_size"][0].as_f64().unwrap();
    assert!((got - want).abs() < 1e-9 * want, "voxel {got} vs {want}");
    assert_eq!(h["half"], true);
    assert!(!voxels.is_empty());
    let (vh, _) = openvdb_grid(&vdb, "vel").unwrap();
    assert_eq!(vh["half"], true);
    eprintln!(
        "48×30 at 2 px a voxel: voxel {got:.5} (the default D/512 would be {:.5}), {} voxels",
        export::voxel_size(None, &bounds),
        voxels.len()
    );
}

#[test]
fn render_formats_flag_writes_the_grids() {
    let (dir, path) = cloud_scene("formats", "output: (voxel: 0.03)");
    let out = dir.join("out");
    let render = |formats: &str, threads: &str| {
        let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
            .arg("render")
            .arg(&path)
            .args(["--frames", "8", "--force", "--formats", formats])
            .arg("-o")
            .arg(&out)
            .env("RAYON_NUM_THREADS", threads)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    render("exr,vdb,VOL", "2");
    let vdb = out.join("shot_0008.vdb");
    assert!(vdb.is_file() && out.join("shot_0008.vol").is_file());
    assert!(!out.join("shot_0008.png").exists());
    // Same frame, same bytes, in another process at another thread count (the VDB's UUID comes
    // from the seed and frame; the EXR's attributes are sorted).
    let first = [
        std::fs::read(&vdb).unwrap(),
        std::fs::read(out.join("shot_0008.exr")).unwrap(),
    ];
    render("exr,vdb", "1");
    let again = [
        std::fs::read(&vdb).unwrap(),
        std::fs::read(out.join("shot_0008.exr")).unwrap(),
    ];
    assert!(first == again, "frame files differ between runs");
    // The last frame is the target: OpenVDB's world box of the active voxels against the
    // target's box (the soft edge and the noise reach a little beyond the iso-surface).
    let Some(dump) = openvdb_read(&vdb) else {
        return;
    };
    let target = nephele::animate::blob_bounds(&cloud());
    let diag = target.diagonal();
    let wb = &dump.header["world_bbox"];
    for a in 0..3 {
        let (min, max) = (wb[0][a].as_f64().unwrap(), wb[1][a].as_f64().unwrap());
        let (tmin, tmax) = (target.min[a], target.max[a]);
        assert!(
            (min - tmin).abs() < 0.08 * diag && (max - tmax).abs() < 0.08 * diag,
            "axis {a}: active {min}..{max}, target {tmin}..{tmax}"
        );
    }
    let [lo, hi] = [
        &dump.header["value_range"][0],
        &dump.header["value_range"][1],
    ];
    assert!(lo.as_f64().unwrap() > 0.0 && hi.as_f64().unwrap().is_finite());
}

/// Benchmark (ignored): per-frame density grid, VDB encoding and atomic write at the default
/// voxel size (target diagonal / 256) on the shipped duck scenes.
/// `cargo test --release --test it -- --ignored --nocapture export::bench`
#[test]
#[ignore]
fn bench_duck_vdb_frames() {
    use nephele::scene::{self, RenderOptions};
    use std::time::Instant;
    let cache = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/bench-export");
    for (file, frames) in [
        ("duck-diffusion.ron", [1u32, 48, 96]),
        ("duck-aggregation.ron", [1, 60, 120]),
    ] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(file);
        let s = scene::load_scene(&path).unwrap();
        let opts = RenderOptions {
            output: Some(cache.clone()),
            ..RenderOptions::default()
        };
        let shot = scene::Shot::open(s, &opts).unwrap();
        let voxel = export::voxel_size(None, &shot.prepared().unwrap().bounds);
        for frame in frames {
            let settings = shot.settings(shot.index(frame)).unwrap();
            let blobs = shot.blobs(shot.index(frame)).unwrap();
            let t0 = Instant::now();
            let grid = export::frame_grid(&settings, &blobs, voxel).unwrap();
            let t1 = Instant::now();
            let bytes = export::vdb::encode_vdb(&grid, export::GRID_NAME, 1);
            let t2 = Instant::now();
            let out = cache.join(format!("bench_{frame:04}.vdb"));
            nephele::atomic::write_bytes_atomically(&out, &bytes).unwrap();
            let t3 = Instant::now();
            eprintln!(
                "{file} frame {frame:>3}: voxel {voxel:.5}, {} active voxels in {} leaves, \
                 {:.2} MB; sample {:.3} s, encode {:.3} s, write {:.3} s",
                grid.active_count(),
                grid.leaves.len(),
                bytes.len() as f64 / 1e6,
                (t1 - t0).as_secs_f64(),
                (t2 - t1).as_secs_f64(),
                (t3 - t2).as_secs_f64()
            );
        }
    }
}

/// The `vel` grid of a frame in flight, read by OpenVDB: beside `density`, with its lattice and
/// active voxels, its metadata, and values that match the blobs' own motion as the dumps of
/// the neighbouring frames give it.
#[test]
fn openvdb_reads_vel_beside_density_and_it_matches_the_blobs_motion() {
    let (dir, path) = cloud_scene_with(
        "vel",
        "Aggregation((hold_seconds: 0.25))",
        48,
        "output: (formats: [Vdb], voxel: 0.03)",
    );
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
        .arg("render")
        .arg(&path)
        .args(["--frames", "11..13", "--dump-blobs", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let vdb = out.join("shot_0012.vdb");
    let Some((dh, density)) = openvdb_grid(&vdb, "density") else {
        return;
    };
    let (vh, vel) = openvdb_grid(&vdb, "vel").expect("OpenVDB read the density");
    assert_eq!(vh["grids"], serde_json::json!(["density", "vel"]));
    assert_eq!(vh["type"], "Vec3SGrid");
    assert_eq!(vh["class"], "unknown");
    assert_eq!(vh["metadata"]["fps"], 48.0);
    assert_eq!(vh["metadata"]["vector_type"], "contravariant relative");
    assert_eq!(vh["metadata"]["is_local_space"], false);
    for key in ["voxel_size", "index_bbox", "world_bbox", "active"] {
        assert_eq!(vh[key], dh[key], "{key}");
    }
    // The same active voxels at the same world centres.
    assert_eq!(vel.len(), density.len());
    let mut a: Vec<_> = density
        .iter()
        .map(|v| (v.0, v.1.map(f64::to_bits)))
        .collect();
    let mut b: Vec<_> = vel.iter().map(|v| (v.0, v.1.map(f64::to_bits))).collect();
    a.sort();
    b.sort();
    assert!(a == b, "vel's active voxels differ from density's");
    // The blobs' motion from the dumps of frames 11 and 13 (a centred difference over two
    // frames, 1/24 s) against OpenVDB's values.
    let load = |f: u32| -> Vec<Blob> {
        let text = std::fs::read_to_string(out.join(format!("shot_{f:04}.blobs.ron"))).unwrap();
        ron::from_str(&text).unwrap()
    };
    let field = nephele::animate::VelocityField::new(&load(11), &load(12), &load(13), 2.0 / 48.0);
    let (mut err2, mut norm2, mut n) = (0.0f64, 0.0f64, 0usize);
    for (_, p, v) in &vel {
        let expected = field.velocity(DVec3::from(*p));
        let got = DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64);
        err2 += (got - expected).length_squared();
        norm2 += expected.length_squared();
        n += 1;
    }
    let (rms, speed) = ((err2 / n as f64).sqrt(), (norm2 / n as f64).sqrt());
    eprintln!("vel: {n} voxels, RMS speed {speed:.4}, RMS difference {rms:.5} units/s");
    // The cloud of diagonal ~1.6 flies in over 0.625 s: a few units a second.
    assert!(speed > 0.5, "the cloud should be moving: RMS speed {speed}");
    assert!(
        rms < 0.03 * speed,
        "vel differs from the dumps' motion: {rms} vs {speed}"
    );
}

/// Issue 51, wind: a still cloud (the whole shot inside the hold) in a wind has `vel` equal to
/// the wind at every active voxel, within 1 %.
#[test]
fn wind_vel_equals_the_wind_for_a_still_cloud() {
    let wind = DVec3::new(0.3, -0.1, 0.2);
    let (dir, path) = cloud_scene_with(
        "wind-vel",
        "Aggregation((hold_seconds: 2.0))",
        24,
        &format!(
            "wind: (velocity: ({}, {}, {})), output: (formats: [Vdb], voxel: 0.03)",
            wind.x, wind.y, wind.z
        ),
    );
    // The blobs and the velocity field, without any reader.
    let s = nephele::scene::load_scene(&path).unwrap();
    let shot = nephele::scene::Shot::open(s, &nephele::scene::RenderOptions::default()).unwrap();
    let prep = shot.prepared().unwrap();
    let (b0, b12) = (shot.blobs(0).unwrap(), shot.blobs(12).unwrap());
    for (a, b) in b0.iter().zip(&b12) {
        assert!((b.center - a.center - wind * 0.5).length() < 1e-12);
    }
    let field = prep.direction.velocity(&prep.plan, 0.5);
    for b in &b12 {
        let v = field.velocity(b.center + DVec3::new(0.05, 0.02, -0.03));
        assert!((v - wind).length() < 1e-6 * wind.length(), "{v}");
    }
    // And in the VDB, read by OpenVDB.
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_nephele"))
        .arg("render")
        .arg(&path)
        .args(["--frames", "13", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let Some((_, vel)) = openvdb_grid(&out.join("shot_0013.vdb"), "vel") else {
        return;
    };
    assert!(!vel.is_empty());
    let worst = vel
        .iter()
        .map(|(_, _, v)| {
            (DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) - wind).length() / wind.length()
        })
        .fold(0.0f64, f64::max);
    eprintln!(
        "wind vel: {} voxels, worst relative error {worst:.2e}",
        vel.len()
    );
    assert!(worst < 0.01, "vel differs from the wind by {worst}");
}

/// Issue 51, wind: the frame at time `t` is the windless frame moved by `wind · t` — rendered
/// with the camera moved along, it is the windless frame; with the camera still, the alpha's
/// centroid moves by the displacement's projection.
#[test]
fn wind_moves_the_frame_by_the_drift() {
    use nephele::scene::{self, RenderOptions};
    // The camera looks down −z at the cloud (centre about (3, −1, 2)) from 4 units away.
    let camera = |d: f64| {
        format!(
            "camera: Fixed((position: ({}, -1.0, 6.0), look_at: ({}, -1.0, 2.0), fov_deg: 40.0))",
            3.0 + d,
            3.0 + d
        )
    };
    let still = "Aggregation((hold_seconds: 2.0))";
    let render = |name: &str, extra: String| {
        use nephele::blobby::{BlobModel, save_model};
        let dir = temp_dir(name);
        let model = BlobModel::from_blobs("test:cloud", 1.0, 1, cloud());
        save_model(&dir.join("model.ron"), &model).unwrap();
        let path = dir.join("shot.ron");
        std::fs::write(
            &path,
            format!(
                "Scene(target: Model(\"model.ron\"), animation: {still}, \
                 shot: (width: 48, height: 30, fps: 24, seconds: 1.0), seed: 3, \
                 quality: Preview, {extra})"
            ),
        )
        .unwrap();
        let s = scene::load_scene(&path).unwrap();
        let shot = scene::Shot::open(s, &RenderOptions::default()).unwrap();
        shot.render_frame(12).unwrap()
    };
    let (w, t) = (0.4, 0.5);
    let windless = render("wind-none", camera(0.0));
    let windy = render(
        "wind-still-camera",
        format!("{}, wind: (velocity: ({w}, 0.0, 0.0))", camera(0.0)),
    );
    let along = render(
        "wind-camera-along",
        format!("{}, wind: (velocity: ({w}, 0.0, 0.0))", camera(w * t)),
    );
    let (mut worst, mut sum) = (0.0f32, 0.0f64);
    for (a, b) in windless.alpha.iter().zip(&along.alpha) {
        worst = worst.max((a - b).abs());
        sum += (a - b).abs() as f64;
    }
    let mean = sum / windless.alpha.len() as f64;
    eprintln!("camera moved along: alpha differs by at most {worst:.2e}, mean {mean:.2e}");
    assert!(worst < 0.02 && mean < 1e-3, "{worst} {mean}");
    let centroid = |f: &nephele::render::Frame| {
        let (mut sx, mut sa) = (0.0f64, 0.0f64);
        for (i, &a) in f.alpha.iter().enumerate() {
            sx += (i % f.width as usize) as f64 * a as f64;
            sa += a as f64;
        }
        sx / sa
    };
    // 0.2 units at a depth of 4 under a 40° vertical field of view, 30 pixels high.
    let expected = w * t / (2.0 * 4.0 * (20f64).to_radians().tan()) * 30.0;
    let moved = centroid(&windy) - centroid(&windless);
    eprintln!("alpha centroid moved {moved:.3} px, projected drift {expected:.3} px");
    assert!(
        (moved - expected).abs() < 0.1 * expected,
        "{moved} vs {expected}"
    );
}

/// Issue 51, timing in a scene: the shot's frames follow the curve (a hold repeats the blobs,
/// with a still `vel`), and a scene without `timing` keeps the plan's own pace.
#[test]
fn scene_timing_drives_the_shots_frames() {
    use nephele::scene::{self, RenderOptions};
    let open = |name: &str, extra: &str| {
        let (dir, path) = cloud_scene_with(name, "Aggregation((hold_seconds: 0.25))", 24, extra);
        let s = scene::load_scene(&path).unwrap();
        (
            dir,
            scene::Shot::open(s, &RenderOptions::default()).unwrap(),
        )
    };
    let (_a, plain) = open("timing-none", "output: (formats: [Exr])");
    let (_b, timed) = open(
        "timing-hold",
        "timing: [(time: 0.0, progress: 0.0), (time: 0.25, progress: 0.5, ease: Smooth), \
         (time: 0.75, progress: 0.5), (time: 0.9, progress: 1.0)]",
    );
    let prep = plain.prepared().unwrap();
    for k in 0..24 {
        assert_eq!(plain.blobs(k).unwrap(), prep.plan.frame(k as usize));
    }
    let held = timed.blobs(6).unwrap();
    assert_ne!(held, plain.blobs(6).unwrap());
    for k in 7..=18 {
        assert_eq!(timed.blobs(k).unwrap(), held, "frame {k} is held");
    }
    let p = timed.prepared().unwrap();
    let v = p.direction.velocity(&p.plan, 12.0 / 24.0);
    assert!(v.motions().iter().all(|m| m.velocity == DVec3::ZERO));
    assert_eq!(timed.blobs(23).unwrap(), plain.blobs(23).unwrap());
}
