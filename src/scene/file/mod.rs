//! The scene file's serde types (RON), parsing with located errors, and validation.
//!
//! Every struct rejects unknown fields, and every field but `target` has a default (listed in
//! `scenes/README.md`). Parsing enables RON's `implicit_some` (write `frames: (1, 24)`, not
//! `Some((1, 24))`). Variants holding a settings struct take it in its own parentheses:
//! `Aggregation((keyframes: 8))`, `Auto((azimuth_deg: 30.0))`; `Fit(mesh: "…")` is a struct
//! variant and takes its fields directly.

pub mod camera;
pub mod chan;
pub mod deforming;
pub mod holdouts;
pub mod locate;
pub mod overrides;
pub mod story;
pub mod transform;
pub mod usd_camera;
pub mod usd_mesh;
pub mod usd_read;
pub mod usd_stage;
pub mod usda_text;

use std::path::Path;

use serde::{Deserialize, Serialize};

pub use self::camera::{AutoCamera, CameraSpec, FixedCamera};
pub use self::holdouts::{GroundSpec, HoldoutSpec};
pub use self::story::StoryEntry;
use self::transform::TargetTransform;
use super::SceneError;
use crate::animate::{Animation, Timing, Wind};
use crate::file_error::FileError;
use crate::render::output::ColorSpace;
use crate::render::{CloudMaterial, PathTracing, QualityPreset, Sky, Sun};

/// Most frames a shot may have (`shot.seconds · shot.fps`): a shot is refused at load beyond
/// this, before any list of frames is made. A million frames is 11.5 hours at 24 fps.
pub const MAX_FRAMES: u64 = 1_000_000;

/// Most digits `output.padding` may ask for (frame numbers are `u32`, at most 10 digits).
pub const MAX_PADDING: u32 = 10;

/// A scene file as written (`Scene(...)`; the struct name may also be left out).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, rename = "Scene")]
pub struct SceneFile {
    /// What the cloud becomes (required, unless a `story` names the targets).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target: Option<Target>,
    /// Targets in turn, each formed from the one before (default none; [`story`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub story: Vec<StoryEntry>,
    /// Orientation, size and place of the target in the shot (default: as fitted).
    #[serde(default)]
    pub transform: TargetTransform,
    /// The animation scheme.
    #[serde(default)]
    pub animation: Animation<Target>,
    /// A steady wind carrying the whole cloud (default: none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wind: Option<Wind>,
    /// A retime curve from the shot's time to the scheme's progress (default: none, the
    /// scheme's own pace).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timing: Option<Timing>,
    /// Camera.
    #[serde(default)]
    pub camera: CameraSpec,
    /// Sun light.
    #[serde(default)]
    pub sun: Sun,
    /// Sky (background and ambient light).
    #[serde(default)]
    pub sky: Sky,
    /// Cloud medium.
    #[serde(default)]
    pub cloud: CloudMaterial,
    /// Resolution, frame rate and length.
    #[serde(default)]
    pub shot: ShotSpec,
    /// Frames to render, first and last frame number, inclusive (`None` = the whole shot).
    #[serde(default)]
    pub frames: Option<(u32, u32)>,
    /// Exposure in stops for the PNG frames.
    #[serde(default)]
    pub exposure: f32,
    /// Render quality preset (`--preview` overrides it with `Preview`).
    #[serde(default)]
    pub quality: QualityPreset,
    /// The path tracer of `quality: Reference`: paths per pixel, longest path, path seed
    /// (default: [`PathTracing::default`]; ignored at the other qualities).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference: Option<PathTracing>,
    /// Where frames go.
    #[serde(default)]
    pub output: OutputSpec,
    /// Seed of every random choice (animation, render jitter, noise).
    #[serde(default = "default_seed")]
    pub seed: u64,
    /// Opaque meshes of the plate that hide the cloud behind them (default none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub holdouts: Vec<HoldoutSpec>,
    /// The ground plane, the shadow catcher of the `shadow` pass (default none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground: Option<GroundSpec>,
}

fn default_seed() -> u64 {
    1
}

/// The shape the cloud takes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Target {
    /// A fitted model file (RON or encoded), relative to the scene file's folder.
    Model(String),
    /// A mesh fitted on first use and cached beside the output as `target-<hash>.ron`.
    Fit {
        /// Mesh path (relative to the scene file's folder) or `builtin:NAME`.
        mesh: String,
        /// Blobs to select.
        #[serde(default = "default_blobs")]
        blobs: usize,
        /// Candidate ellipsoids.
        #[serde(default = "default_candidates")]
        candidates: usize,
        /// Surface samples.
        #[serde(default = "default_samples")]
        samples: usize,
        /// Seed of the fit.
        #[serde(default = "default_seed")]
        seed: u64,
    },
}

fn default_blobs() -> usize {
    crate::pipeline::FitConfig::DEFAULT_BLOBS
}
fn default_candidates() -> usize {
    crate::pipeline::FitConfig::DEFAULT_CANDIDATES
}
fn default_samples() -> usize {
    crate::pipeline::FitConfig::DEFAULT_SAMPLES
}

/// Resolution, frame rate and length of the shot (the scene file's `shot`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ShotSpec {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Frames per second.
    pub fps: f64,
    /// Length in seconds; the shot has `max(1, round(seconds · fps))` frames.
    pub seconds: f64,
    /// Open shutter as a fraction of a frame, centred on the frame's time (`0` = no motion
    /// blur, the default; `0.5` = a 180° film shutter; at most 1).
    pub shutter: f64,
    /// Number of the first frame (film pipelines start at 1001); see [`super::shot::frames`].
    pub start_frame: u32,
}

impl Default for ShotSpec {
    fn default() -> Self {
        ShotSpec {
            width: 640,
            height: 360,
            fps: 24.0,
            seconds: 4.0,
            shutter: 0.0,
            start_frame: 1,
        }
    }
}

impl ShotSpec {
    /// Number of frames (a validated shot has at most [`MAX_FRAMES`]).
    pub fn frame_count(&self) -> u32 {
        ((self.seconds * self.fps).round() as u32).max(1)
    }

    /// The last frame number.
    pub fn last_frame(&self) -> u32 {
        self.start_frame + (self.frame_count() - 1)
    }
}

/// An output format: an image, or the cloud's density grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Format {
    /// Linear HDR OpenEXR (RGBA + depth).
    Exr,
    /// Tone-mapped 8-bit sRGB PNG over the sky.
    Png,
    /// OpenVDB: the renderer's extinction as a fog-volume float grid `density`.
    Vdb,
    /// Mitsuba's binary `.vol` grid of the same extinction (dense over the cloud's box).
    Vol,
}

impl Format {
    /// Every format, in the order of their names in [`Format::from_name`].
    pub const ALL: [Format; 4] = [Format::Exr, Format::Png, Format::Vdb, Format::Vol];

    /// File extension.
    pub fn extension(self) -> &'static str {
        match self {
            Format::Exr => "exr",
            Format::Png => "png",
            Format::Vdb => "vdb",
            Format::Vol => "vol",
        }
    }

    /// The format whose extension is `name` (any case), e.g. `vdb`.
    pub fn from_name(name: &str) -> Option<Format> {
        Format::ALL
            .into_iter()
            .find(|f| f.extension().eq_ignore_ascii_case(name.trim()))
    }

    /// True for the density grids (sampled from the frame's medium, not its image).
    pub fn is_grid(self) -> bool {
        matches!(self, Format::Vdb | Format::Vol)
    }

    /// Check a list of formats to write: at least one, none twice (two writers of one file
    /// would race and leave the frame without its manifest).
    pub fn check_list(formats: &[Format]) -> Result<(), String> {
        if formats.is_empty() {
            return Err("list at least one format".to_string());
        }
        for (i, f) in formats.iter().enumerate() {
            if formats[..i].contains(f) {
                return Err(format!(
                    "{} is listed twice; list each format once",
                    f.extension()
                ));
            }
        }
        Ok(())
    }
}

/// Where and how frames are written.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct OutputSpec {
    /// Output folder, relative to the current directory (default `renders/<scene name>`).
    pub dir: Option<String>,
    /// Frame name prefix (default: the scene file's name without extension).
    pub name: Option<String>,
    /// Formats written per frame.
    pub formats: Vec<Format>,
    /// Voxel size of the `Vdb` and `Vol` grids, world units (default: the target's bounding-box
    /// diagonal / 512).
    pub voxel: Option<f64>,
    /// Voxel size of the grids in pixels instead: the voxel is this many times the width of
    /// one pixel's footprint at the centre of the target's box, seen from the shot's nearest
    /// camera (the smallest footprint over its frames), so a small preview writes coarse grids
    /// ([`crate::export::footprint_voxel`]). Not with `voxel`.
    pub voxel_pixels: Option<f64>,
    /// How the VDB's grids store their values: `Full` 32-bit floats, or `Half` (16-bit, as
    /// Houdini's "Write 16-bit Floats" / OpenVDB's `saveFloatAsHalf`).
    pub vdb_precision: crate::export::Precision,
    /// Digits of the frame number in file names (default 4: `name_0001.exr`).
    pub padding: u32,
    /// The RGB space of the EXR's linear values (the PNG is always sRGB display-referred).
    pub colorspace: ColorSpace,
    /// Also write the render passes (`sun`, `sky`, `multiple` layers) into the EXR.
    pub passes: bool,
    /// Also write the cloud's motion vectors into the EXR: the layer `forward` (`forward.u`,
    /// `forward.v`), each pixel's forward motion over one frame in pixels, u right and v up
    /// (what Nuke's VectorBlur reads).
    pub motion_vectors: bool,
}

impl Default for OutputSpec {
    fn default() -> Self {
        OutputSpec {
            dir: None,
            name: None,
            formats: vec![Format::Exr, Format::Png],
            voxel: None,
            voxel_pixels: None,
            vdb_precision: crate::export::Precision::Full,
            padding: 4,
            colorspace: ColorSpace::default(),
            passes: false,
            motion_vectors: false,
        }
    }
}

/// Parse scene text (`path` labels errors). Syntax and type errors carry line and column.
pub fn parse(path: &Path, text: &str) -> Result<SceneFile, SceneError> {
    parse_ron(text).map_err(|e| SceneError::File(FileError::ron(path, &e)))
}

/// [`parse`] with RON's own error.
fn parse_ron(text: &str) -> Result<SceneFile, ron::error::SpannedError> {
    ron::Options::default()
        .with_default_extension(ron::extensions::Extensions::IMPLICIT_SOME)
        .from_str::<SceneFile>(text)
}

/// Lowest frame rate a shot may have.
pub const MIN_FPS: f64 = 1.0;
/// Highest frame rate a shot may have.
pub const MAX_FPS: f64 = 1000.0;

/// Check ranges and finiteness; errors name the field.
pub fn validate(path: &Path, s: &SceneFile) -> Result<(), SceneError> {
    let bad = |field: &str, message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        field: field.to_string(),
        message,
    };
    let finite = |field: &str, v: &[f32]| check_finite(&bad, field, v);
    if s.shot.width == 0 || s.shot.height == 0 {
        return Err(bad(
            "shot",
            format!(
                "width and height must be positive, got {}×{}",
                s.shot.width, s.shot.height
            ),
        ));
    }
    for (name, v) in [("shot.fps", s.shot.fps), ("shot.seconds", s.shot.seconds)] {
        if !(v.is_finite() && v > 0.0) {
            return Err(bad(name, format!("must be a positive number, got {v}")));
        }
    }
    // A frame rate is frames per second of film or video (1 to 1000); 1e-9 would put each
    // frame 30 years apart and be written to the EXR as 0/1001.
    if !(MIN_FPS..=MAX_FPS).contains(&s.shot.fps) {
        return Err(bad(
            "shot.fps",
            format!(
                "must be {MIN_FPS} to {MAX_FPS} frames per second (e.g. 24, 23.976, 30), got {}",
                s.shot.fps
            ),
        ));
    }
    if !(s.shot.shutter.is_finite() && (0.0..=1.0).contains(&s.shot.shutter)) {
        return Err(bad(
            "shot.shutter",
            format!(
                "must be a fraction of a frame in [0, 1], got {}",
                s.shot.shutter
            ),
        ));
    }
    // Counted in f64 before any integer conversion or list of frames.
    let count = (s.shot.seconds * s.shot.fps).round();
    let max = MAX_FRAMES;
    if count > max as f64 {
        return Err(bad(
            "shot",
            format!(
                "{} s at {} fps is {count:.3e} frames, more than the limit of {max} \
                 (11.5 hours at 24 fps); shorten shot.seconds or lower shot.fps",
                s.shot.seconds, s.shot.fps
            ),
        ));
    }
    let (first, n) = (s.shot.start_frame, s.shot.frame_count());
    if u64::from(first) + u64::from(n) - 1 > u64::from(u32::MAX) {
        return Err(bad(
            "shot.start_frame",
            format!(
                "{first} + {n} frames passes the largest frame number {}",
                u32::MAX
            ),
        ));
    }
    let last = s.shot.last_frame();
    if let Some((a, b)) = s.frames
        && (a < first || a > b || b > last)
    {
        return Err(bad(
            "frames",
            format!("need {first} ≤ first ≤ last ≤ {last} (the shot's frames), got ({a}, {b})"),
        ));
    }
    let padding = s.output.padding;
    if !(1..=MAX_PADDING).contains(&padding) {
        return Err(bad(
            "output.padding",
            format!("must be 1 to {} digits, got {padding}", MAX_PADDING),
        ));
    }
    finite("exposure", &[s.exposure])?;
    if let Some(g) = &s.ground
        && !(g.height.is_finite() && g.height.abs() < 1e30)
    {
        return Err(bad(
            "ground.height",
            format!("must be a finite height in scene units, got {}", g.height),
        ));
    }
    // A holdout is the plate's still geometry; only the target's transform is keyed.
    if let Some(i) = s.holdouts.iter().position(|h| !h.transform.keys.is_empty()) {
        return Err(bad(
            "holdouts",
            format!(
                "holdouts[{i}].transform has keys; a holdout stays where its transform puts it \
                 (only the target's transform may be keyed)"
            ),
        ));
    }
    if let Some(i) = s.holdouts.iter().position(|h| h.mesh.trim().is_empty()) {
        return Err(bad(
            "holdouts",
            format!("holdouts[{i}].mesh is empty; name a mesh file (OBJ, PLY, OFF, STL or USD)"),
        ));
    }
    s.camera.validate().map_err(|e| bad(e.field, e.message))?;
    let field = |e: crate::render::InvalidField| bad(e.field, e.message);
    s.sun.validate().map_err(field)?;
    s.sky.validate(&s.sun).map_err(field)?;
    s.cloud.validate().map_err(field)?;
    if let Some(r) = &s.reference {
        r.validate().map_err(field)?;
    }
    crate::render::memory::check_size(s.shot.width, s.shot.height, s.quality)
        .map_err(|message| bad("shot", message))?;
    Format::check_list(&s.output.formats).map_err(|message| bad("output.formats", message))?;
    if let Some(v) = s.output.voxel
        && !(v.is_finite() && v > 0.0)
    {
        return Err(bad(
            "output.voxel",
            format!("must be a positive number of world units, got {v}"),
        ));
    }
    if let Some(p) = s.output.voxel_pixels {
        if !(p.is_finite() && p > 0.0) {
            return Err(bad(
                "output.voxel_pixels",
                format!("must be a positive number of pixels (e.g. 1.0), got {p}"),
            ));
        }
        if s.output.voxel.is_some() {
            return Err(bad(
                "output.voxel_pixels",
                "set either output.voxel (world units) or output.voxel_pixels (pixels), not both"
                    .to_string(),
            ));
        }
    }
    if let Some(Target::Fit {
        blobs,
        candidates,
        samples,
        ..
    }) = &s.target
    {
        let fit = crate::pipeline::FitConfig {
            blobs: *blobs,
            candidates: *candidates,
            samples: *samples,
            ..Default::default()
        };
        fit.validate().map_err(|e| bad("target", e.to_string()))?;
    }
    story::validate(s).map_err(|(field, message)| bad(&field, message))?;
    s.animation.validate().map_err(|e| match e {
        crate::animate::AnimateError::Invalid { field, message } => bad(&field, message),
        other => bad("animation", other.to_string()),
    })
}

/// `v` all finite, else an error naming `field`.
fn check_finite(
    bad: &dyn Fn(&str, String) -> SceneError,
    field: &str,
    v: &[f32],
) -> Result<(), SceneError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(bad(field, format!("must be finite, got {v:?}")))
    }
}
