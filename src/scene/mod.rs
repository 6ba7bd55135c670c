//! Scene files (RON): a target, an animation scheme, camera, lighting, material, shot and
//! output settings; and rendering a shot to frame files with resume and frame ranges.
//!
//! In: a scene file path. Out: frame files `<dir>/<name>_0001.exr/.png/.vdb/.vol` (and optionally
//! `<name>_0001.blobs.ron`), numbered from `shot.start_frame` ([`frames`]), written atomically
//! with the frame's manifest last, so that a frame whose files and manifest exist is finished,
//! and up to date when the manifest's hash matches ([`provenance`]).
//!
//! Paths: the target (`Model("…")`, `Fit(mesh: "…")`) resolves against the scene file's folder,
//! so a scene can sit beside its models; the output folder resolves against the current
//! directory, so renders land in the repository's `renders/` when run from its root.

pub mod file;
pub mod resume;
pub mod shot;

// Each module lives in the folder of its job (`file/`: the scene file's schema and checks;
// `shot/`: a shot and its run; `resume/`: what makes a run resumable); these are their paths in
// the scene API.
pub use file::{camera, transform};
pub use resume::{canonical, frame_files, frame_names, lock, provenance};
pub use shot::{chunk, frames, run, stats, target, usd};

use crate::file_error::FileError;
use std::path::{Path, PathBuf};

pub use file::overrides::{self, Override};
pub use file::{
    AutoCamera, CameraSpec, FixedCamera, Format, OutputSpec, SceneFile, ShotSpec, Target,
};
pub use run::{FrameReport, ShotReport, render_shot};
pub use shot::{Prepared, RenderOptions, Shot};
pub use target::load_target;

/// Everything that can go wrong reading a scene or rendering its shot.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// The scene file (or a file of the run) could not be read or written, or its text does
    /// not parse (at its `line:column`).
    #[error(transparent)]
    File(#[from] FileError),
    /// A value out of range.
    #[error("{path}: {field}: {message}")]
    Invalid {
        /// Scene file.
        path: PathBuf,
        /// Dotted field name (`shot.fps`).
        field: String,
        /// What is wrong, with the value found.
        message: String,
    },
    /// A value out of range, at the place in the scene file where it is written.
    #[error("{path}:{line}:{column}: {field}: {message}")]
    InvalidAt {
        /// Scene file.
        path: PathBuf,
        /// 1-based line of the field's name.
        line: usize,
        /// 1-based column of the field's name.
        column: usize,
        /// Dotted field name (`shot.fps`).
        field: String,
        /// What is wrong, with the value found.
        message: String,
    },
    /// A value set from outside the file (`--set KEY=VALUE`, `--size WxH`) that cannot be
    /// written into the scene, or makes it invalid; `given` is the override as written.
    #[error("{given}: {field}: {message}")]
    Override {
        /// The override as the user gave it (`--set shot.width=abc`).
        given: String,
        /// Dotted field name.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The target's model or mesh file does not exist.
    #[error(
        "{scene}: target file {} does not exist (relative paths resolve against the scene file's folder)",
        target.display()
    )]
    MissingTarget {
        /// Scene file.
        scene: PathBuf,
        /// The resolved missing path.
        target: PathBuf,
    },
    /// The target mesh could not be loaded.
    #[error("{scene}: target mesh: {source}")]
    Mesh {
        /// Scene file.
        scene: PathBuf,
        /// Underlying error.
        source: crate::mesh::MeshError,
    },
    /// The target mesh could not be fitted (it encloses no volume).
    #[error("{scene}: target fit: {source}")]
    Fit {
        /// Scene file.
        scene: PathBuf,
        /// Underlying error.
        source: crate::pipeline::FitError,
    },
    /// The target model could not be read.
    #[error("{scene}: target model: {source}")]
    Model {
        /// Scene file.
        scene: PathBuf,
        /// Underlying error.
        source: crate::blobby::ModelError,
    },
    /// Another process is writing the frame (its lock file is held).
    #[error(
        "{path}: this frame is being written by another {holder}; wait for it to finish, or give \
         this render another output.name or --output"
    )]
    Locked {
        /// The frame's lock file.
        path: PathBuf,
        /// Who holds it, as the holder wrote it (process id, host, scene).
        holder: String,
    },
    /// The animation cannot be planned.
    #[error("{scene}: {source}")]
    Animate {
        /// Scene file.
        scene: PathBuf,
        /// Underlying error.
        source: crate::animate::AnimateError,
    },
}

/// 1-based line and column of the quoted `value` after the first `key` in `text` (or of `key`,
/// or 1:1, when not found).
fn locate(text: &str, key: &str, value: &str) -> (usize, usize) {
    let at = text.find(key).unwrap_or(0);
    let quoted = format!("\"{value}\"");
    let pos = text[at..].find(&quoted).map_or(at, |p| at + p);
    let before = &text[..pos];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// A loaded, validated scene with its paths resolved.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The scene file.
    pub path: PathBuf,
    /// Its content; target paths are resolved (relative to the current directory).
    pub file: SceneFile,
    /// Output folder (from `output.dir`, default `renders/<scene name>`).
    pub output_dir: PathBuf,
    /// Frame file prefix (from `output.name`, default the scene file's stem).
    pub name: String,
    /// The holdouts (read and placed) and the ground plane, when the scene has any.
    pub surfaces: Option<std::sync::Arc<crate::render::Surfaces>>,
    /// The target's mesh sequence, when the target deforms (`file::deforming`).
    pub deforming: Option<std::sync::Arc<crate::mesh::sequence::MeshSequence>>,
}

impl SceneError {
    /// This error at its place in the scene's `text`: a value out of range whose field the
    /// text writes becomes [`SceneError::InvalidAt`]; anything else is returned as it is.
    pub fn located(self, text: &str) -> SceneError {
        match self {
            SceneError::Invalid {
                path,
                field,
                message,
            } => match file::locate::locate(text, &field) {
                Some((line, column)) => SceneError::InvalidAt {
                    path,
                    line,
                    column,
                    field,
                    message,
                },
                None => SceneError::Invalid {
                    path,
                    field,
                    message,
                },
            },
            other => other,
        }
    }

    /// This error without a place in the text (for text a front end generated, whose lines
    /// mean nothing to the user).
    pub fn unlocated(self) -> SceneError {
        match self {
            SceneError::InvalidAt {
                path,
                field,
                message,
                ..
            } => SceneError::Invalid {
                path,
                field,
                message,
            },
            other => other,
        }
    }
}

/// Read, parse and validate a scene file; resolve its paths and check that the target exists.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    load_scene_with(path, &[])
}

/// [`load_scene`] with `overrides` (`--set`, `--size`) applied to the file's values
/// ([`file::overrides`]): the scene is the one the file would be with those values written in.
pub fn load_scene_with(path: &Path, overrides: &[Override]) -> Result<Scene, SceneError> {
    let text =
        crate::input::read_to_string(path, crate::input::Limit::Scene).map_err(|source| {
            SceneError::File(FileError::Io {
                path: path.to_path_buf(),
                source,
            })
        })?;
    scene_with_overrides(path, &text, overrides)
}

/// [`load_scene`] on text already read (`path` locates relative paths and labels errors).
pub fn scene_from_str(path: &Path, text: &str) -> Result<Scene, SceneError> {
    scene_with_overrides(path, text, &[])
}

/// [`load_scene_with`] on text already read. An error in an overridden value names the
/// override; the file's own errors keep their place in `text`.
pub fn scene_with_overrides(
    path: &Path,
    text: &str,
    overrides: &[Override],
) -> Result<Scene, SceneError> {
    let edited = file::overrides::apply(path, text, overrides)?;
    scene_from_parsed(path, &edited.text, edited.file.clone())
        .map_err(|e| edited.attribute(text, e))
}

/// A parsed scene `file` (of `text`) validated, with its paths resolved and files read.
fn scene_from_parsed(path: &Path, text: &str, mut file: SceneFile) -> Result<Scene, SceneError> {
    file::validate(path, &file).map_err(|e| e.located(text))?;
    let base = path.parent().unwrap_or(Path::new(""));
    // A file the scene names that cannot be read: an error at that field, located in the text.
    let invalid_at = |field: &str, message: String| {
        SceneError::Invalid {
            path: path.to_path_buf(),
            field: field.into(),
            message,
        }
        .located(text)
    };
    let resolve = |p: &str| -> Result<String, SceneError> {
        if p.starts_with("builtin:") {
            return Ok(p.to_string());
        }
        let full = base.join(p);
        if !full.exists() {
            return Err(SceneError::MissingTarget {
                scene: path.to_path_buf(),
                target: full,
            });
        }
        Ok(full.to_string_lossy().into_owned())
    };
    // A deforming target's frames are read now: a gap, one frame or a frame of another
    // topology is an error at `target.mesh`.
    let deforming = file::deforming::load(base, &file)
        .map_err(|(field, message)| invalid_at(&field, message))?;
    match &mut file.target {
        Some(Target::Model(p)) => *p = resolve(p)?,
        // A sequence's pattern names no one file.
        Some(Target::Fit { mesh, .. }) if crate::mesh::sequence::is_pattern(mesh) => {
            *mesh = base.join(&*mesh).to_string_lossy().into_owned()
        }
        Some(Target::Fit { mesh, .. }) => *mesh = resolve(mesh)?,
        None => {}
    }
    // A story's targets: one that cannot be read is located at its path in the text.
    for (i, entry) in file.story.iter_mut().enumerate() {
        let from = entry.animation.as_mut().and_then(|a| match a {
            crate::animate::Animation::Morph(m) => Some(&mut m.from),
            _ => None,
        });
        for (field, target) in std::iter::once(("target", &mut entry.target))
            .chain(from.map(|f| ("animation.from", f)))
        {
            let p = match target {
                Target::Model(p) => p,
                Target::Fit { mesh, .. } => mesh,
            };
            let resolved = resolve(p).map_err(|e| match e {
                SceneError::MissingTarget { target, .. } => {
                    let (line, column) = locate(text, "story", p);
                    SceneError::File(FileError::Parse {
                        path: path.to_path_buf(),
                        line,
                        column,
                        message: format!(
                            "story[{i}].{field}: {} does not exist (relative paths resolve \
                             against the scene file's folder)",
                            target.display()
                        ),
                    })
                }
                other => other,
            })?;
            *p = resolved;
        }
    }
    // A tracked camera's lines are read now: every frame of the shot must have one.
    if let file::CameraSpec::Chan(c) = &mut file.camera {
        let full = base.join(&c.file);
        let frames = file.shot.start_frame..=file.shot.last_frame();
        c.load(&full, frames)
            .map_err(|message| invalid_at("camera.file", message))?;
        c.file = full.to_string_lossy().into_owned();
    }
    // So is a USD camera's every frame.
    if let file::CameraSpec::Usd(c) = &mut file.camera {
        let full = base.join(&c.file);
        let frames = file.shot.start_frame..=file.shot.last_frame();
        c.load(&full, frames, file.shot.fps).map_err(|e| {
            let field = match e.field {
                file::usd_read::Field::File => "camera.file",
                file::usd_read::Field::Prim => "camera.prim",
            };
            invalid_at(field, e.message)
        })?;
        c.file = full.to_string_lossy().into_owned();
    }
    // The plate's light is read now: a missing or bad map is an error at `sky.file`.
    if let crate::render::Sky::Environment(env) = &mut file.sky {
        env.load(base)
            .map_err(|message| invalid_at("sky.file", message))?;
        // `sun_from_map`: the map's sun is the scene's sun.
        if let Some(sun) = env.map_sun() {
            file.sun = sun;
        }
    }
    if let crate::animate::Animation::Morph(m) = &mut file.animation {
        // A `from` that cannot be read is located at its path in the scene text.
        let located = |p: &str, e: SceneError| match e {
            SceneError::MissingTarget { target, .. } => {
                let (line, column) = locate(text, "from", p);
                SceneError::File(FileError::Parse {
                    path: path.to_path_buf(),
                    line,
                    column,
                    message: format!(
                        "animation.from: {} does not exist (relative paths resolve against the scene file's folder)",
                        target.display()
                    ),
                })
            }
            other => other,
        };
        match &mut m.from {
            Target::Model(p) => *p = resolve(p).map_err(|e| located(p, e))?,
            Target::Fit { mesh, .. } => *mesh = resolve(mesh).map_err(|e| located(mesh, e))?,
        }
    }
    // The holdouts' meshes are read now: one that cannot be is the scene's error, before any
    // frame is written.
    let surfaces = file::holdouts::load(path, text, base, &file.holdouts, file.ground)?;
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "shot".into());
    let name = file.output.name.clone().unwrap_or_else(|| stem.clone());
    if name.is_empty() || name.contains(['/', '\\']) {
        return Err(SceneError::Invalid {
            path: path.to_path_buf(),
            field: "output.name".into(),
            message: format!("must be a non-empty file name without slashes, got {name:?}"),
        });
    }
    let output_dir = match &file.output.dir {
        Some(d) => PathBuf::from(d),
        None => Path::new("renders").join(&stem),
    };
    Ok(Scene {
        path: path.to_path_buf(),
        file,
        output_dir,
        name,
        surfaces,
        deforming,
    })
}
