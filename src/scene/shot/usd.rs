//! The shot as a USD ASCII stage (`.usda`): the camera animated per frame, the sun as a
//! `DistantLight`, the sky as a `DomeLight` colour, and the cloud as a `Volume` whose
//! `OpenVDBAsset` fields `density` and `vel` (the velocity grid, so Karma and other Hydra
//! renderers motion-blur it without set-up) point at the frame VDBs (time-sampled `filePath`).
//!
//! Conventions: the time code of a frame is its frame number (from `shot.start_frame`, 1 by
//! default), `timeCodesPerSecond` = `framesPerSecond` = the shot's fps; `upAxis` Y, `metersPerUnit` 1 (the scene's units are the model's; scale the
//! stage on import if they are not metres). Matrices are USD's row-vector `matrix4d` (the last
//! row is the translation). The camera looks down its local −Z with +Y up, as nephele's does;
//! its lens uses the schema's tenths-of-a-unit convention with a 24-unit vertical aperture:
//! `focalLength = 12 / tan(fov_v/2)`, `horizontalAperture = 2·focalLength·tan(fov_h/2)`, both
//! half-angles read off the renderer's own rays; a shifted lens adds the aperture offsets
//! `focalLength·c` of its image centre `c` on the plane at distance 1. A `DistantLight` shines
//! down its local −Z, so the sun's rotation takes −Z to the direction sunlight travels.

use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use glam::DVec3;

use crate::render::output::CameraFrame;
use crate::render::{Sky, Sun};
use crate::scene::{SceneError, Shot};

/// Vertical aperture of the stage's camera (tenths of a unit, the schema's convention).
pub const VERTICAL_APERTURE: f64 = 24.0;

/// Everything a shot's stage holds.
#[derive(Clone, Debug)]
pub struct Stage {
    /// Frames per second.
    pub fps: f64,
    /// Frame number (and time code) of the first frame.
    pub start_frame: u32,
    /// The camera of frames `start_frame..start_frame + cameras.len()`.
    pub cameras: Vec<CameraFrame>,
    /// Near and far clipping distances.
    pub clipping: [f64; 2],
    /// Open shutter as a fraction of a frame, centred on it (`shot.shutter`; 0 = closed).
    pub shutter: f64,
    /// The sun.
    pub sun: Sun,
    /// The sky.
    pub sky: Sky,
    /// The VDB file of each frame, as written into the stage (relative to the stage's folder);
    /// [`stage_text`] refuses one that cannot be a USD asset path ([`asset_ref`]).
    pub vdb_paths: Vec<String>,
    /// A line of documentation for the stage.
    pub doc: String,
}

/// The stage of `shot`'s whole shot (every frame, whatever its frame range), for a stage file
/// in `stage_dir`: the cameras of every frame as rendered, the lights, and the frame VDBs of
/// the shot's folder (written by `nephele render --formats vdb`), relative to `stage_dir`
/// where possible. A VDB path that cannot be a USD asset path (a control character such as a
/// newline in the output folder or `output.name`, or a name that is not UTF-8) is an error
/// naming the scene file, the path and how to fix it.
pub fn shot_stage(shot: &Shot, stage_dir: &Path) -> Result<Stage, SceneError> {
    let scene = shot.scene();
    let (width, height) = shot.size();
    let vdb_paths = (0..shot.total())
        .map(|k| {
            let vdb = frame_vdb(shot, shot.number(k));
            let bad = |reason: String| SceneError::Invalid {
                path: scene.path.clone(),
                field: "output".into(),
                message: format!(
                    "the frame VDB path {vdb:?} {reason}, so the USD stage cannot refer to it; \
                     rename the output folder (`output.dir`, or --frames-dir) or set \
                     `output.name` (by default the scene file's name)"
                ),
            };
            let rel = relative_to(&vdb, stage_dir);
            let rel = rel.to_str().ok_or_else(|| bad("is not UTF-8".into()))?;
            // USD's separator is `/`; elsewhere a backslash is part of a name.
            let rel = if cfg!(windows) {
                rel.replace('\\', "/")
            } else {
                rel.to_string()
            };
            asset_ref(&rel).map_err(|e| bad(e.reason))?;
            Ok(rel)
        })
        .collect::<Result<_, SceneError>>()?;
    // After the paths: a name the stage cannot hold is refused before the target is fitted.
    let cameras = (0..shot.total())
        .map(|k| Ok(CameraFrame::new(&shot.settings(k)?.camera, width, height)))
        .collect::<Result<_, SceneError>>()?;
    let length = shot.prepared()?.bounds.diagonal().max(1e-12);
    Ok(Stage {
        fps: scene.file.shot.fps,
        start_frame: shot.number(0),
        cameras,
        clipping: [1e-3 * length, 1e3 * length],
        shutter: scene.file.shot.shutter,
        sun: scene.file.sun,
        sky: scene.file.sky.clone(),
        vdb_paths,
        doc: format!(
            "nephele {} shot of {}",
            env!("CARGO_PKG_VERSION"),
            scene
                .path
                .file_name()
                .map(|n| n.to_string_lossy())
                .unwrap_or_default()
        ),
    })
}

/// The VDB file of frame number `frame`, as `nephele render --formats vdb` names it.
pub fn frame_vdb(shot: &Shot, frame: u32) -> PathBuf {
    shot.dir().join(format!(
        "{}.vdb",
        crate::scene::resume::frame_names::frame_stem(shot, frame)
    ))
}

/// `path` relative to folder `base` (`./…` or with `..`), or absolute when they share no root.
fn relative_to(path: &Path, base: &Path) -> PathBuf {
    let abs = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
    let (path, base) = (abs(path), abs(base));
    let (p, b): (Vec<Component>, Vec<Component>) =
        (path.components().collect(), base.components().collect());
    let common = p.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return path;
    }
    let mut rel = PathBuf::new();
    if common == b.len() {
        rel.push(".");
    }
    for _ in common..b.len() {
        rel.push("..");
    }
    p[common..].iter().for_each(|c| rel.push(c));
    rel
}

/// A path that cannot be written as a USD asset path.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{path:?} {reason}, which a USD asset path cannot hold")]
pub struct AssetPathError {
    /// The path.
    pub path: String,
    /// What is wrong with it (`holds a newline (control character 0x0a)`).
    pub reason: String,
}

/// `path` as a USD asset path literal, written as usd-core writes it so that it reads back as
/// exactly `path`: `@path@`, or, when the path holds an `@`, the triple-delimited
/// `@@@path@@@` with each `@@@` inside written `\@@@` (the text format's grammar: `@@@`
/// closes on the last three of 3 to 5 `@`, so a path may end in `@` or `@@`). A control
/// character (a newline, a tab, …) cannot be in an asset path at all (usd-core refuses it):
/// an error.
pub fn asset_ref(path: &str) -> Result<String, AssetPathError> {
    if let Some(c) = path.chars().find(|c| c.is_control()) {
        let what = match c {
            '\n' => "a newline",
            '\r' => "a carriage return",
            '\t' => "a tab",
            _ => "a control character",
        };
        return Err(AssetPathError {
            path: path.to_string(),
            reason: format!("holds {what} (character U+{:04X})", c as u32),
        });
    }
    Ok(if path.contains('@') {
        format!("@@@{}@@@", path.replace("@@@", "\\@@@"))
    } else {
        format!("@{path}@")
    })
}

/// The `.usda` text of `stage`; an error when one of its VDB paths cannot be an asset path
/// ([`asset_ref`]; [`shot_stage`] never makes such a stage).
pub fn stage_text(stage: &Stage) -> Result<String, AssetPathError> {
    let first = stage.start_frame as usize;
    let last = first + stage.cameras.len().max(1) - 1;
    let mut s = String::new();
    let _ = writeln!(s, "#usda 1.0");
    let _ = writeln!(s, "(");
    let _ = writeln!(s, "    defaultPrim = \"shot\"");
    let _ = writeln!(s, "    doc = {}", quoted(&stage.doc));
    let _ = writeln!(s, "    startTimeCode = {first}");
    let _ = writeln!(s, "    endTimeCode = {last}");
    let _ = writeln!(s, "    timeCodesPerSecond = {}", num(stage.fps));
    let _ = writeln!(s, "    framesPerSecond = {}", num(stage.fps));
    let _ = writeln!(s, "    upAxis = \"Y\"");
    let _ = writeln!(s, "    metersPerUnit = 1");
    let _ = writeln!(s, ")\n");
    let _ = writeln!(s, "def Xform \"shot\"\n{{");
    camera(&mut s, stage);
    sun(&mut s, &stage.sun);
    sky(&mut s, &stage.sky, &stage.sun);
    volume(&mut s, &stage.vdb_paths, first)?;
    let _ = writeln!(s, "}}");
    Ok(s)
}

fn camera(s: &mut String, stage: &Stage) {
    let first = stage.cameras.first();
    let tan_v = first.map_or(1.0, |c| c.tan_half_v);
    let tan_h = first.map_or(1.0, |c| c.tan_half_h);
    let focal = 0.5 * VERTICAL_APERTURE / tan_v;
    let _ = writeln!(s, "    def Camera \"camera\"\n    {{");
    let _ = writeln!(s, "        float focalLength = {}", num(focal));
    let _ = writeln!(
        s,
        "        float horizontalAperture = {}",
        num(2.0 * focal * tan_h)
    );
    let _ = writeln!(
        s,
        "        float verticalAperture = {}",
        num(VERTICAL_APERTURE)
    );
    // A shifted lens (a camera read from USD with aperture offsets) keeps its offsets; a
    // centred one writes none, as before.
    let [cx, cy] = first.map_or([0.0; 2], |c| c.center);
    if [cx, cy] != [0.0; 2] {
        let _ = writeln!(
            s,
            "        float horizontalApertureOffset = {}",
            num(focal * cx)
        );
        let _ = writeln!(
            s,
            "        float verticalApertureOffset = {}",
            num(focal * cy)
        );
    }
    let [near, far] = stage.clipping;
    let _ = writeln!(
        s,
        "        float2 clippingRange = ({}, {})",
        num(near),
        num(far)
    );
    let _ = writeln!(s, "        token projection = \"perspective\"");
    // The shutter in frames relative to each frame's time code, centred as nephele's.
    let _ = writeln!(
        s,
        "        double shutter:open = {}",
        num(-0.5 * stage.shutter)
    );
    let _ = writeln!(
        s,
        "        double shutter:close = {}",
        num(0.5 * stage.shutter)
    );
    let _ = writeln!(s, "        matrix4d xformOp:transform.timeSamples = {{");
    for (k, c) in stage.cameras.iter().enumerate() {
        // Camera to world: local +X right, +Y up, +Z backward (it looks down −Z).
        let m = matrix([c.right, c.up, -c.forward], c.eye);
        let _ = writeln!(s, "            {}: {m},", stage.start_frame as usize + k);
    }
    let _ = writeln!(s, "        }}");
    let _ = writeln!(
        s,
        "        uniform token[] xformOpOrder = [\"xformOp:transform\"]"
    );
    let _ = writeln!(s, "    }}\n");
}

fn sun(s: &mut String, sun: &Sun) {
    // Also right for a sun given by elevation and azimuth.
    let d = sun.travel_dir().as_dvec3();
    // Local −Z is the direction the light travels, so local +Z is −d.
    let z = -d;
    let x = [DVec3::Y, DVec3::X]
        .into_iter()
        .find_map(|h| h.cross(z).try_normalize())
        .unwrap_or(DVec3::X);
    let y = z.cross(x);
    let _ = writeln!(s, "    def DistantLight \"sun\"\n    {{");
    let _ = writeln!(
        s,
        "        float inputs:intensity = {}",
        num(sun.intensity as f64)
    );
    let _ = writeln!(
        s,
        "        color3f inputs:color = {}",
        vec3(sun.color.as_dvec3())
    );
    let _ = writeln!(s, "        float inputs:angle = 0.53");
    let _ = writeln!(
        s,
        "        matrix4d xformOp:transform = {}",
        matrix([x, y, z], DVec3::ZERO)
    );
    let _ = writeln!(
        s,
        "        uniform token[] xformOpOrder = [\"xformOp:transform\"]"
    );
    let _ = writeln!(s, "    }}\n");
}

fn sky(s: &mut String, sky: &Sky, sun: &Sun) {
    // The dome's colour: a gradient's mean colour (it also keeps its two colours for round
    // trips); for a Hosek–Wilkie sky the renderer's mean radiance from above.
    let mean = match *sky {
        Sky::Gradient { zenith, horizon } => 0.5 * (zenith + horizon).as_dvec3(),
        Sky::HosekWilkie { .. } | Sky::Uniform { .. } | Sky::Environment(_) => {
            crate::render::SkyDome::new(sky, sun)
                .upper_mean()
                .as_dvec3()
        }
    };
    let _ = writeln!(s, "    def DomeLight \"sky\" (");
    let _ = writeln!(s, "        customData = {{");
    match sky {
        Sky::Uniform { color } => {
            let _ = writeln!(
                s,
                "            float3 nephele_uniform = {}",
                vec3(color.as_dvec3())
            );
        }
        // The map itself is not on the stage (USD's lat-long convention differs from the
        // map's, Mitsuba's); its file and turn are noted.
        Sky::Environment(env) => {
            let _ = writeln!(
                s,
                "            string nephele_environment = {}",
                quoted(&env.file)
            );
            let _ = writeln!(
                s,
                "            float nephele_rotate_deg = {}",
                env.rotate_deg
            );
        }
        &Sky::Gradient { zenith, horizon } => {
            let _ = writeln!(
                s,
                "            float3 nephele_zenith = {}",
                vec3(zenith.as_dvec3())
            );
            let _ = writeln!(
                s,
                "            float3 nephele_horizon = {}",
                vec3(horizon.as_dvec3())
            );
        }
        &Sky::HosekWilkie {
            turbidity,
            ground_albedo,
        } => {
            let _ = writeln!(s, "            float nephele_turbidity = {turbidity}");
            let _ = writeln!(
                s,
                "            float nephele_ground_albedo = {ground_albedo}"
            );
        }
    }
    let _ = writeln!(s, "        }}\n    )\n    {{");
    let _ = writeln!(s, "        color3f inputs:color = {}", vec3(mean));
    let _ = writeln!(s, "        float inputs:intensity = 1");
    let _ = writeln!(s, "    }}\n");
}

/// The cloud: a `Volume` with two fields over the same frame VDBs — `density` (the fog volume)
/// and `vel` (its velocity grid, world units per second, for motion blur).
fn volume(s: &mut String, paths: &[String], first: usize) -> Result<(), AssetPathError> {
    let _ = writeln!(s, "    def Volume \"cloud\"\n    {{");
    let _ = writeln!(s, "        rel field:density = </shot/cloud/density>");
    let _ = writeln!(s, "        rel field:vel = </shot/cloud/vel>\n");
    for (name, data_type) in [("density", "float"), ("vel", "float3")] {
        let _ = writeln!(s, "        def OpenVDBAsset \"{name}\"\n        {{");
        let _ = writeln!(s, "            token fieldName = \"{name}\"");
        let _ = writeln!(s, "            token fieldDataType = \"{data_type}\"");
        if data_type == "float3" {
            let _ = writeln!(s, "            token vectorDataRoleHint = \"Vector\"");
        }
        let _ = writeln!(s, "            asset filePath.timeSamples = {{");
        for (k, p) in paths.iter().enumerate() {
            let _ = writeln!(s, "                {}: {},", first + k, asset_ref(p)?);
        }
        let _ = writeln!(s, "            }}");
        let _ = writeln!(s, "        }}");
    }
    let _ = writeln!(s, "    }}");
    Ok(())
}

/// A row-vector `matrix4d`: rows are the three axes, then the translation.
fn matrix(axes: [DVec3; 3], t: DVec3) -> String {
    let row = |v: DVec3, w: f64| format!("({}, {}, {}, {})", num(v.x), num(v.y), num(v.z), num(w));
    format!(
        "( {}, {}, {}, {} )",
        row(axes[0], 0.0),
        row(axes[1], 0.0),
        row(axes[2], 0.0),
        row(t, 1.0)
    )
}

fn vec3(v: DVec3) -> String {
    format!("({}, {}, {})", num(v.x), num(v.y), num(v.z))
}

/// A number as USD reads it: the shortest round-trip decimal (`1`, `0.25`, `1e-7`).
fn num(v: f64) -> String {
    let v = if v == 0.0 { 0.0 } else { v }; // no "-0"
    format!("{v}")
}

/// A USD string literal (one line: a newline or another control character is escaped, as
/// the text format's string escapes read it back).
fn quoted(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '\\' => out.push_str("\\\\"),
            '"' => out.push_str("\\\""),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            // C0 controls and DEL as `\xHH` (the escape reads one byte: C1 controls stay UTF-8).
            c if c.is_control() && (c as u32) < 0x80 => {
                let _ = write!(out, "\\x{:02x}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_and_matrices_are_usd_literals() {
        assert_eq!(num(1.0), "1");
        assert_eq!(num(-0.0), "0");
        assert_eq!(num(0.25), "0.25");
        let m = matrix([DVec3::X, DVec3::Y, DVec3::Z], DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(
            m,
            "( (1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (1, 2, 3, 1) )"
        );
        assert_eq!(quoted("a \"b\""), "\"a \\\"b\\\"\"");
        assert_eq!(quoted("a\nb\u{1}c\\"), "\"a\\nb\\x01c\\\\\"");
        assert_eq!(asset_ref("out/a.vdb").unwrap(), "@out/a.vdb@");
        assert_eq!(asset_ref("o@v/a.vdb").unwrap(), "@@@o@v/a.vdb@@@");
        assert_eq!(asset_ref("a@@@b@").unwrap(), "@@@a\\@@@b@@@@");
        let e = asset_ref("a\nb").unwrap_err();
        assert!(e.to_string().contains("a newline"), "{e}");
        assert_eq!(
            relative_to(Path::new("/r/out/a.vdb"), Path::new("/r/out")),
            Path::new("./a.vdb")
        );
        assert_eq!(
            relative_to(Path::new("/r/out/a.vdb"), Path::new("/r/usd")),
            Path::new("../out/a.vdb")
        );
    }
}
