//! A frame's files: their names, and writing them atomically (EXR with its header attributes,
//! PNG, the density grids, the optional blob dump).

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::shot::Shot;
use super::{Format, SceneError, provenance};
use crate::blobby::Blob;
use crate::render::{self, RenderSettings};

/// The files of frame number `frame`: one per format, plus the blob dump if asked.
pub fn frame_paths(shot: &Shot, frame: u32) -> Vec<PathBuf> {
    let scene = shot.scene();
    let stem = frame_stem(shot, frame);
    let mut v: Vec<PathBuf> = scene
        .file
        .output
        .formats
        .iter()
        .map(|f| shot.dir().join(format!("{stem}.{}", f.extension())))
        .collect();
    if shot.options().dump_blobs {
        v.push(shot.dir().join(format!("{stem}.blobs.ron")));
    }
    v
}

/// `<name>_0001`: the file name of frame number `frame` without its extension, the number
/// zero-padded to `output.padding` digits.
pub fn frame_stem(shot: &Shot, frame: u32) -> String {
    let scene = shot.scene();
    let digits = scene.file.output.padding as usize;
    format!("{}_{frame:0digits$}", scene.name)
}

/// The voxel size of the shot's density grids (`output.voxel`, else the target's diagonal /
/// 512), checked against the target's box before any frame is rendered; 0 when the scene
/// writes no grid.
pub fn grid_voxel(shot: &Shot) -> Result<f64, SceneError> {
    let scene = shot.scene();
    if !scene.file.output.formats.iter().any(|f| f.is_grid()) {
        return Ok(0.0);
    }
    let bounds = shot.prepared()?.bounds;
    let voxel = crate::export::voxel_size(scene.file.output.voxel, &bounds);
    crate::export::check_voxel_budget(voxel, &bounds).map_err(|message| SceneError::Invalid {
        path: scene.path.clone(),
        field: "output.voxel".into(),
        message,
    })?;
    Ok(voxel)
}

/// What one frame's files are made from.
pub(crate) struct FrameOutput<'a> {
    pub image: &'a render::Frame,
    pub settings: &'a RenderSettings,
    pub blobs: &'a [Blob],
    /// Voxel size of the density grids.
    pub voxel: f64,
    /// The frame's provenance hash ([`super::provenance`]).
    pub hash: u64,
}

/// Write one frame's files atomically, the formats in parallel if `parallel`; the blob dump (if
/// any), then the manifest, are written last. The density grid is sampled once, if a grid
/// format is asked for.
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
        hash,
    } = *out;
    let paths = frame_paths(shot, frame);
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SceneError::Io { path, source }
    };
    // The density grid is sampled once, before the files, if a grid format is asked for.
    let formats = &scene.file.output.formats;
    let grid = if formats.iter().any(|f| f.is_grid()) {
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
    // The formats are independent files: written in parallel when asked (a 1080p frame's EXR
    // and PNG had taken 0.42 s one after the other), the first error in the scene's order
    // reported either way.
    let write = |(format, path): (&Format, &PathBuf)| -> Result<(), SceneError> {
        match format {
            Format::Exr => {
                let meta = frame_metadata(shot, settings, frame, hash);
                render::output::write_exr_with(path, image, &meta).map_err(io(path))?
            }
            Format::Png => render::output::write_png(path, image, settings).map_err(io(path))?,
            Format::Vdb => {
                let g = grid.as_ref().expect("sampled above");
                let uuid_seed =
                    crate::rng::key(scene.file.seed, crate::rng::Stream::Render, frame as u64);
                // The velocity of the density on its voxels, at the frame's time.
                let plan = &shot.prepared()?.plan;
                let time = plan.timeline().time(shot.index(frame) as usize);
                let field = crate::animate::VelocityField::of_plan(plan, time);
                let vel = crate::export::sample_velocity(g, &field);
                let grids = [
                    crate::export::VdbGrid::fog(crate::export::GRID_NAME, g),
                    crate::export::velocity_vdb_grid(&vel, scene.file.shot.fps),
                ];
                crate::export::write_vdb_grids(path, &grids, uuid_seed).map_err(io(path))?
            }
            Format::Vol => {
                let g = grid.as_ref().expect("sampled above");
                crate::export::write_vol(path, g).map_err(io(path))?
            }
        }
        Ok(())
    };
    if parallel {
        let written: Vec<Result<(), SceneError>> =
            formats.par_iter().zip(&paths).map(write).collect();
        written.into_iter().collect::<Result<(), SceneError>>()?;
    } else {
        formats.iter().zip(&paths).try_for_each(write)?;
    }
    if shot.options().dump_blobs {
        let path = paths.last().expect("dump path");
        let text = blobs_to_ron(blobs);
        crate::atomic::write_bytes_atomically(path, text.as_bytes()).map_err(io(path))?;
    }
    let record = provenance::FrameRecord {
        frame,
        hash: provenance::hash_text(hash),
        version: env!("CARGO_PKG_VERSION").to_string(),
        output: provenance::output_kind(shot),
        files: paths
            .iter()
            .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect(),
    };
    let manifest = provenance::manifest_path(shot, frame);
    crate::atomic::write_bytes_atomically(&manifest, provenance::record_text(&record).as_bytes())
        .map_err(io(&manifest))?;
    Ok(())
}

/// The EXR attributes of frame number `frame` with provenance hash `hash`: the camera's
/// matrices, `chromaticities` of `output.colorspace`, `framesPerSecond`, and the strings
/// `nephele/scene` (the scene file's name), `nephele/frame`, `nephele/hash`,
/// `nephele/colorspace`, `nephele/seed` (the scene's) and `nephele/version` (the crate's).
/// Nothing depends on the run, so frames stay byte-identical.
pub fn frame_metadata(
    shot: &Shot,
    settings: &RenderSettings,
    frame: u32,
    hash: u64,
) -> render::output::FrameMetadata {
    let scene = shot.scene();
    let file = scene
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let space = scene.file.output.colorspace;
    let strings = vec![
        ("scene".to_string(), file),
        ("frame".to_string(), frame.to_string()),
        ("hash".to_string(), provenance::hash_text(hash)),
        ("colorspace".to_string(), space.name().to_string()),
        ("seed".to_string(), scene.file.seed.to_string()),
        ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
    ];
    let mut meta = render::output::FrameMetadata::new(
        &settings.camera,
        settings.width,
        settings.height,
        strings,
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
