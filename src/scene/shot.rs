//! Rendering a scene's shot to frame files, resumable.
//!
//! Frames are numbered from 1 and named `<name>_0001.<ext>` in the output folder (`--preview`
//! writes to its `preview/` subfolder). Every file is written atomically, so a frame whose
//! files all exist is finished and is skipped unless `force` is set; the target is not even
//! loaded (nor fitted) when every requested frame is done.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::camera::camera_at;
use super::stats::StatsBasis;
use super::target::{TargetOrigin, load_spec, load_target};
use super::{Scene, SceneError};
use crate::animate::{self, Plan, Timeline, blob_bounds};
use crate::blobby::{Blob, BlobModel};
use crate::geometry::Aabb;
use crate::progress::Timings;
use crate::render::{self, Quality, RenderSettings};

/// How to render a shot (the command line's choices).
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    /// 1-based inclusive frame range, overriding the scene's `frames`.
    pub frames: Option<(u32, u32)>,
    /// Output folder overriding the scene's `output.dir`.
    pub output: Option<PathBuf>,
    /// Quarter resolution (at least 64 px wide) with preview quality, in `<dir>/preview/`.
    pub preview: bool,
    /// Re-render frames whose files already exist.
    pub force: bool,
    /// Also write each frame's blobs as `<name>_0001.blobs.ron`.
    pub dump_blobs: bool,
    /// Also write per-frame statistics to `<name>_stats.csv` (see [`super::stats`]); frames
    /// already done are rendered again in memory for their coverage.
    pub stats: bool,
}

/// What happened to one frame.
#[derive(Clone, Debug)]
pub struct FrameReport {
    /// 1-based frame number.
    pub frame: u32,
    /// Frames in the shot.
    pub of: u32,
    /// True when the frame's files existed and it was skipped.
    pub skipped: bool,
    /// Seconds spent rendering and writing it (0 when skipped).
    pub seconds: f64,
}

/// The outcome of a shot.
#[derive(Clone, Debug)]
pub struct ShotReport {
    /// Folder the frames are in.
    pub output_dir: PathBuf,
    /// Frames rendered.
    pub rendered: u32,
    /// Frames skipped because they were done.
    pub skipped: u32,
    /// Where the target came from (`None` when every frame was already done).
    pub target: Option<TargetOrigin>,
    /// Wall time per stage (target, plan, render, write).
    pub timings: Timings,
    /// The statistics file, when asked for.
    pub stats: Option<PathBuf>,
}

/// The resolved geometry of a shot: folder, frames, image size.
#[derive(Clone, Debug, PartialEq)]
pub struct ShotSetup {
    /// Output folder of the frames.
    pub dir: PathBuf,
    /// Folder of the target's fit cache: the output folder, also for previews (so a preview
    /// and the final render share one fit).
    pub cache_dir: PathBuf,
    /// 1-based inclusive frames to render.
    pub frames: RangeInclusive<u32>,
    /// Frames in the shot.
    pub total: u32,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
}

/// Resolve folder, frame range and image size from the scene and options.
pub fn shot_setup(scene: &Scene, opts: &RenderOptions) -> Result<ShotSetup, SceneError> {
    let shot = &scene.file.shot;
    let total = shot.frame_count();
    let (a, b) = opts.frames.or(scene.file.frames).unwrap_or((1, total));
    if a == 0 || a > b || b > total {
        return Err(SceneError::Invalid {
            path: scene.path.clone(),
            field: "frames".into(),
            message: format!("need 1 ≤ first ≤ last ≤ {total} (the shot's frames), got {a}..{b}"),
        });
    }
    let cache_dir = opts
        .output
        .clone()
        .unwrap_or_else(|| scene.output_dir.clone());
    let mut dir = cache_dir.clone();
    let (mut width, mut height) = (shot.width, shot.height);
    if opts.preview {
        dir = dir.join("preview");
        let w = (width / 4).max(64).min(width);
        height = ((height as f64 * w as f64 / width as f64).round() as u32).max(1);
        width = w;
    }
    Ok(ShotSetup {
        dir,
        cache_dir,
        frames: a..=b,
        total,
        width,
        height,
    })
}

/// The files of frame `frame` (1-based): one per format, plus the blob dump if asked.
pub fn frame_paths(scene: &Scene, dir: &Path, frame: u32, dump_blobs: bool) -> Vec<PathBuf> {
    let stem = format!("{}_{frame:04}", scene.name);
    let mut v: Vec<PathBuf> = scene
        .file
        .output
        .formats
        .iter()
        .map(|f| dir.join(format!("{stem}.{}", f.extension())))
        .collect();
    if dump_blobs {
        v.push(dir.join(format!("{stem}.blobs.ron")));
    }
    v
}

/// A shot ready to render frames: the target, the planned animation and its bounds.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The target model.
    pub model: BlobModel,
    /// The planned animation.
    pub plan: Plan,
    /// Bounding box of the target's blobs (camera framing; its diagonal is the length unit).
    pub bounds: Aabb,
}

/// Apply the scene's target transform to `model` and plan its animation.
pub fn prepare(scene: &Scene, mut model: BlobModel) -> Result<Prepared, SceneError> {
    scene.file.transform.apply(&mut model.blobs);
    let shot = &scene.file.shot;
    let timeline = Timeline {
        frames: shot.frame_count() as usize,
        fps: shot.fps,
        hold_seconds: scene.file.animation.hold_seconds(),
    };
    // A morph's source: fitted sources are cached in the scene's output folder.
    let source = match &scene.file.animation {
        animate::Animation::Morph(m) => Some(load_spec(scene, &m.from, &scene.output_dir)?.0),
        _ => None,
    };
    let plan = animate::plan_with_source(
        &scene.file.animation,
        &model,
        source.as_ref(),
        timeline,
        scene.file.seed,
    )
    .map_err(|source| SceneError::Animate {
        scene: scene.path.clone(),
        source,
    })?;
    let bounds = blob_bounds(&model.blobs);
    Ok(Prepared {
        model,
        plan,
        bounds,
    })
}

/// Render settings of 0-based frame `k`.
pub fn frame_settings(
    scene: &Scene,
    prep: &Prepared,
    setup: &ShotSetup,
    k: u32,
    preview: bool,
) -> RenderSettings {
    let f = &scene.file;
    let u = if setup.total > 1 {
        k as f64 / (setup.total - 1) as f64
    } else {
        0.0
    };
    let aspect = setup.width as f32 / setup.height as f32;
    RenderSettings {
        width: setup.width,
        height: setup.height,
        camera: camera_at(&f.camera, &prep.bounds, aspect, u, k as f64 / f.shot.fps),
        sun: f.sun,
        sky: f.sky,
        cloud: f.cloud,
        exposure: f.exposure,
        length_scale: prep.bounds.diagonal().max(1e-12) as f32,
        seed: f.seed,
        time: k as f32 / f.shot.fps as f32,
        quality: if preview {
            Quality::preview()
        } else {
            Quality::preset(f.quality)
        },
    }
}

/// Render the shot: skip finished frames (unless `force`), render and write the rest,
/// calling `on_frame` after each frame.
pub fn render_shot(
    scene: &Scene,
    opts: &RenderOptions,
    on_frame: &mut dyn FnMut(&FrameReport),
) -> Result<ShotReport, SceneError> {
    let setup = shot_setup(scene, opts)?;
    let mut timings = Timings::default();
    let done = |frame: u32| {
        !opts.force
            && frame_paths(scene, &setup.dir, frame, opts.dump_blobs)
                .iter()
                .all(|p| p.is_file())
    };
    // Each frame's files are looked for once: (frame, finished).
    let frames: Vec<(u32, bool)> = setup.frames.clone().map(|f| (f, done(f))).collect();
    // With statistics, finished frames are rendered again in memory (not written).
    let render_it = |finished: bool| opts.stats || !finished;
    let mut report = ShotReport {
        output_dir: setup.dir.clone(),
        rendered: 0,
        skipped: 0,
        target: None,
        timings: Timings::default(),
        stats: None,
    };
    if frames.iter().any(|&(_, finished)| render_it(finished)) {
        let (model, origin) = timings.stage("target", || load_target(scene, &setup.cache_dir))?;
        report.target = Some(origin);
        let prep = timings.stage("plan", || prepare(scene, model))?;
        let voxel = grid_voxel(scene, &prep)?;
        let basis = opts.stats.then(|| StatsBasis::new(&prep));
        let mut stats = Vec::new();
        let (mut render_s, mut write_s, mut stats_s) = (0.0, 0.0, 0.0);
        // Frames in order: a hold reuses the last frame, a still cloud its light grid.
        let mut renderer = render::ShotRenderer::new();
        for &(frame, finished) in &frames {
            if !render_it(finished) {
                report.skipped += 1;
                on_frame(&skipped(frame, setup.total));
                continue;
            }
            let start = Instant::now();
            let k = frame - 1;
            let blobs = prep.plan.frame(k as usize);
            let settings = frame_settings(scene, &prep, &setup, k, opts.preview);
            let image = renderer.render(&settings, &blobs);
            let rendered = Instant::now();
            let write = !finished;
            if write {
                let out = FrameOutput {
                    image,
                    settings: &settings,
                    blobs: &blobs,
                    voxel,
                };
                write_frame(scene, &setup.dir, frame, &out, opts)?;
            }
            let written = Instant::now();
            if let Some(basis) = &basis {
                stats.push(basis.frame(frame, &blobs, Some(image)));
            }
            render_s += (rendered - start).as_secs_f64();
            write_s += (written - rendered).as_secs_f64();
            stats_s += written.elapsed().as_secs_f64();
            if write {
                report.rendered += 1;
            } else {
                report.skipped += 1;
            }
            on_frame(&FrameReport {
                frame,
                of: setup.total,
                skipped: !write,
                seconds: start.elapsed().as_secs_f64(),
            });
        }
        timings.stages.push(("render".into(), render_s));
        timings.stages.push(("write".into(), write_s));
        if basis.is_some() {
            timings.stages.push(("stats".into(), stats_s));
            let path = super::stats::stats_path(scene, &setup.dir);
            super::stats::write_csv(&path, &stats)?;
            report.stats = Some(path);
        }
    } else {
        for frame in setup.frames.clone() {
            report.skipped += 1;
            on_frame(&skipped(frame, setup.total));
        }
    }
    report.timings = timings;
    Ok(report)
}

fn skipped(frame: u32, of: u32) -> FrameReport {
    FrameReport {
        frame,
        of,
        skipped: true,
        seconds: 0.0,
    }
}

/// The voxel size of the shot's density grids (`output.voxel`, else the target's diagonal /
/// 256), checked against the target's box before any frame is rendered; 0 when the scene
/// writes no grid.
pub fn grid_voxel(scene: &Scene, prep: &Prepared) -> Result<f64, SceneError> {
    if !scene.file.output.formats.iter().any(|f| f.is_grid()) {
        return Ok(0.0);
    }
    let voxel = crate::export::voxel_size(scene.file.output.voxel, &prep.bounds);
    crate::export::check_voxel_budget(voxel, &prep.bounds).map_err(|message| {
        SceneError::Invalid {
            path: scene.path.clone(),
            field: "output.voxel".into(),
            message,
        }
    })?;
    Ok(voxel)
}

/// What one frame's files are made from.
struct FrameOutput<'a> {
    image: &'a render::Frame,
    settings: &'a RenderSettings,
    blobs: &'a [Blob],
    /// Voxel size of the density grids.
    voxel: f64,
}

/// Write one frame's files atomically; the blob dump (if any) is written last. The density
/// grid is sampled once, if a grid format is asked for.
fn write_frame(
    scene: &Scene,
    dir: &Path,
    frame: u32,
    out: &FrameOutput,
    opts: &RenderOptions,
) -> Result<(), SceneError> {
    let FrameOutput {
        image,
        settings,
        blobs,
        voxel,
    } = *out;
    let paths = frame_paths(scene, dir, frame, opts.dump_blobs);
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SceneError::Io { path, source }
    };
    let mut grid = None;
    for (format, path) in scene.file.output.formats.iter().zip(&paths) {
        if format.is_grid() && grid.is_none() {
            let g = crate::export::frame_grid(settings, blobs, voxel).map_err(|e| {
                SceneError::Invalid {
                    path: scene.path.clone(),
                    field: "output.voxel".into(),
                    message: format!("frame {frame}: {e}"),
                }
            })?;
            grid = Some(g);
        }
        match format {
            super::Format::Exr => {
                let meta = frame_metadata(scene, settings, frame);
                render::output::write_exr_with(path, image, &meta).map_err(io(path))?
            }
            super::Format::Png => {
                render::output::write_png(path, image, settings).map_err(io(path))?
            }
            super::Format::Vdb => {
                let g = grid.as_ref().expect("sampled above");
                let uuid_seed =
                    crate::rng::key(scene.file.seed, crate::rng::Stream::Render, frame as u64);
                crate::export::write_vdb(path, g, crate::export::GRID_NAME, uuid_seed)
                    .map_err(io(path))?
            }
            super::Format::Vol => {
                let g = grid.as_ref().expect("sampled above");
                crate::export::write_vol(path, g).map_err(io(path))?
            }
        }
    }
    if opts.dump_blobs {
        let path = paths.last().expect("dump path");
        let text = blobs_to_ron(blobs);
        crate::atomic::write_bytes_atomically(path, text.as_bytes()).map_err(io(path))?;
    }
    Ok(())
}

/// The EXR attributes of frame `frame` (1-based): the camera's matrices and the strings
/// `nephele/scene` (the scene file's name), `nephele/frame`, `nephele/seed` (the scene's) and
/// `nephele/version` (the crate's). Nothing depends on the run, so frames stay byte-identical.
pub fn frame_metadata(
    scene: &Scene,
    settings: &RenderSettings,
    frame: u32,
) -> render::output::FrameMetadata {
    let file = scene
        .path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let strings = vec![
        ("scene".to_string(), file),
        ("frame".to_string(), frame.to_string()),
        ("seed".to_string(), scene.file.seed.to_string()),
        ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
    ];
    render::output::FrameMetadata::new(&settings.camera, settings.width, settings.height, strings)
}

/// A frame's blob list as RON (a list of `Blob`s, index = identity).
pub fn blobs_to_ron(blobs: &[Blob]) -> String {
    let config = ron::ser::PrettyConfig::new()
        .depth_limit(2)
        .struct_names(true)
        .new_line("\n");
    ron::ser::to_string_pretty(&blobs, config).expect("blobs always serialize")
}
