//! A frame's files: their names, and writing them atomically (EXR with its header attributes,
//! PNG, the density grids, the optional blob dump).

use std::path::Path;

use rayon::prelude::*;

use super::provenance::{
    self, FileKind, FrameCheck, FrameInputs, ListedFile, Manifest, WantedFile,
};
use crate::blobby::Blob;
use crate::file_error::FileError;
use crate::render::{self, RenderSettings};
use crate::scene::shot::Shot;
use crate::scene::{Format, SceneError};

/// The voxel size of the shot's density grids (`output.voxel`; else `output.voxel_pixels`
/// pixels' footprint at the target's centre from the shot's nearest camera,
/// [`crate::export::footprint_voxel`]; else the target's diagonal / 512), checked against the
/// target's box before any frame is rendered when the scene writes a grid. (Also known when it
/// writes none, so a grid kept from another run can be told current or not.)
pub fn grid_voxel(shot: &Shot) -> Result<f64, SceneError> {
    let scene = shot.scene();
    let bounds = shot.prepared()?.bounds;
    let (voxel, field) = match scene.file.output.voxel_pixels {
        Some(pixels) if scene.file.output.voxel.is_none() => {
            let cameras = (0..shot.total())
                .map(|k| shot.settings(k).map(|s| s.camera))
                .collect::<Result<Vec<_>, _>>()?;
            let voxel = crate::export::footprint_voxel(pixels, &cameras, shot.size().1, &bounds)
                .unwrap_or_else(|| crate::export::voxel_size(None, &bounds));
            (voxel, "output.voxel_pixels")
        }
        _ => (
            crate::export::voxel_size(scene.file.output.voxel, &bounds),
            "output.voxel",
        ),
    };
    if scene.file.output.formats.iter().any(|f| f.is_grid()) {
        crate::export::check_voxel_budget(voxel, &bounds).map_err(|message| {
            SceneError::Invalid {
                path: scene.path.clone(),
                field: field.into(),
                message,
            }
        })?;
    }
    Ok(voxel)
}

/// What one frame's files are made from.
pub(crate) struct FrameOutput<'a> {
    /// The rendered image (`None` when no file to write needs it).
    pub image: Option<&'a render::Frame>,
    pub settings: &'a RenderSettings,
    pub blobs: &'a [Blob],
    /// Voxel size of the density grids.
    pub voxel: f64,
    /// The frame's inputs ([`super::provenance`]).
    pub inputs: &'a FrameInputs,
    /// Which files to write, and which to remove.
    pub check: &'a FrameCheck,
}

/// Write one frame's files atomically, the formats in parallel if `parallel`: first the
/// manifest is replaced by one listing only the files this write leaves alone (removed when
/// there are none), so an interrupted write never leaves old and new files under one
/// manifest; then the files `out.check` says to write; then the other formats' files are
/// removed if the run cleans (`--clean`; otherwise they are kept); and the manifest listing
/// every file with its content hash is written last. The density grid is sampled once, if a
/// grid file is written.
pub(crate) fn write_frame(
    shot: &Shot,
    frame: u32,
    out: &FrameOutput,
    parallel: bool,
) -> Result<(), SceneError> {
    let scene = shot.scene();
    let FrameOutput {
        image,
        settings,
        blobs,
        voxel,
        inputs,
        check,
    } = *out;
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SceneError::File(FileError::Io { path, source })
    };
    let manifest = provenance::manifest_path(shot, frame);
    // The files this write does not touch: the wanted ones already up to date, and the other
    // formats' files it keeps.
    let untouched: Vec<ListedFile> = check
        .verified
        .iter()
        .flatten()
        .cloned()
        .chain(
            check
                .others
                .iter()
                .filter(|o| !o.remove)
                .map(|o| o.listed.clone()),
        )
        .collect();
    if untouched.is_empty() {
        match std::fs::remove_file(&manifest) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(io(&manifest)(e)),
        }
    } else {
        let record = Manifest::new(frame, inputs.listed(), untouched.clone());
        crate::atomic::write_bytes_atomically(&manifest, record.to_text().as_bytes())
            .map_err(io(&manifest))?;
    }
    let todo: Vec<&WantedFile> = check
        .wanted
        .iter()
        .zip(&check.write)
        .filter_map(|(w, &go)| go.then_some(w))
        .collect();
    // The density grid is sampled once, before the files, if a grid file is written.
    let grid = if todo
        .iter()
        .any(|w| matches!(w.kind, FileKind::Format(f) if f.is_grid()))
    {
        Some(
            crate::export::frame_grid(settings, blobs, voxel).map_err(|e| SceneError::Invalid {
                path: scene.path.clone(),
                field: "output.voxel".into(),
                message: format!("frame {frame}: {e}"),
            })?,
        )
    } else {
        None
    };
    let needs_image = || {
        image.ok_or_else(|| SceneError::Invalid {
            path: scene.path.clone(),
            field: "output.formats".into(),
            message: format!("frame {frame}: an image file to write but no image rendered"),
        })
    };
    // The files are independent: written in parallel when asked (a 1080p frame's EXR and PNG
    // had taken 0.42 s one after the other), the first error in the scene's order reported
    // either way.
    let write = |w: &&WantedFile| -> Result<(), SceneError> {
        let path = &w.path;
        match w.kind {
            FileKind::Format(Format::Exr) => {
                let meta = frame_metadata(shot, settings, frame, w.hash);
                render::output::write_exr_with(path, needs_image()?, &meta).map_err(io(path))?
            }
            FileKind::Format(Format::Png) => {
                render::output::write_png(path, needs_image()?, settings).map_err(io(path))?
            }
            FileKind::Format(Format::Vdb) => {
                let g = grid.as_ref().expect("sampled above");
                let uuid_seed =
                    crate::rng::key(scene.file.seed, crate::rng::Stream::Render, frame as u64);
                // The velocity of the density on its voxels, at the frame's time.
                let prep = shot.prepared()?;
                let time = prep.plan.timeline().time(shot.index(frame) as usize);
                let field = prep.direction.velocity(&prep.plan, time);
                let vel = crate::export::sample_velocity(g, &field);
                let precision = scene.file.output.vdb_precision;
                let grids = [
                    crate::export::VdbGrid::fog(crate::export::GRID_NAME, g)
                        .with_precision(precision),
                    crate::export::velocity_vdb_grid(&vel, scene.file.shot.fps)
                        .with_precision(precision),
                ];
                crate::export::write_vdb_grids(path, &grids, uuid_seed).map_err(io(path))?
            }
            FileKind::Format(Format::Vol) => {
                let g = grid.as_ref().expect("sampled above");
                crate::export::write_vol(path, g).map_err(io(path))?
            }
            FileKind::Blobs => {
                let text = blobs_to_ron(blobs);
                crate::atomic::write_bytes_atomically(path, text.as_bytes()).map_err(io(path))?
            }
        }
        Ok(())
    };
    if parallel {
        let written: Vec<Result<(), SceneError>> = todo.par_iter().map(write).collect();
        written.into_iter().collect::<Result<(), SceneError>>()?;
    } else {
        todo.iter().try_for_each(write)?;
    }
    crate::test_hook::stop_at(&format!("after-files:{frame}"));
    // Only files the manifest listed under the frame's own names (checked when it was read),
    // and only when asked: a link there is removed itself, never what it points to.
    for other in check.others.iter().filter(|o| o.remove) {
        match std::fs::remove_file(&other.path) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(io(&other.path)(e)),
        }
    }
    let mut listed = Vec::with_capacity(check.wanted.len() + untouched.len());
    for (w, verified) in check.wanted.iter().zip(&check.verified) {
        if let Some(entry) = verified {
            listed.push(entry.clone());
            continue;
        }
        let bytes = std::fs::metadata(&w.path).map_err(io(&w.path))?.len();
        listed.push(ListedFile {
            name: w
                .path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            kind: w.kind.key().to_string(),
            hash: provenance::hash_text(w.hash),
            bytes,
            blake3: provenance::content_hash(&w.path).map_err(io(&w.path))?,
        });
    }
    listed.extend(
        check
            .others
            .iter()
            .filter(|o| !o.remove)
            .map(|o| o.listed.clone()),
    );
    let record = Manifest::new(frame, inputs.listed(), listed);
    crate::atomic::write_bytes_atomically(&manifest, record.to_text().as_bytes())
        .map_err(io(&manifest))?;
    Ok(())
}

/// The EXR attributes of frame number `frame` whose EXR has hash `hash`: the camera's
/// matrices, `chromaticities` of `output.colorspace`, `framesPerSecond`, and the
/// [`header_strings`]. Nothing depends on the run, so frames stay byte-identical.
pub fn frame_metadata(
    shot: &Shot,
    settings: &RenderSettings,
    frame: u32,
    hash: u64,
) -> render::output::FrameMetadata {
    let scene = shot.scene();
    let space = scene.file.output.colorspace;
    let mut meta = render::output::FrameMetadata::new(
        &settings.camera,
        settings.width,
        settings.height,
        provenance::header_strings(shot, frame, hash),
    );
    meta.color_space = space;
    meta.frames_per_second = Some(render::output::fps_rational(scene.file.shot.fps));
    meta
}

/// A frame's blob list as RON (a list of `Blob`s, index = identity).
pub fn blobs_to_ron(blobs: &[Blob]) -> String {
    let config = ron::ser::PrettyConfig::new()
        .depth_limit(2)
        .struct_names(true)
        .new_line("\n");
    ron::ser::to_string_pretty(&blobs, config).expect("blobs always serialize")
}
