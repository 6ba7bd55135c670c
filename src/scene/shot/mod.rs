//! A scene's shot opened for one run: [`Shot`] resolves the folder, the frames and the image
//! size once, loads (or fits) the target and plans the animation on first need, and gives the
//! render settings, blobs and image of any frame. `render`, `--stats`, `usd`, `prepare` and
//! `farm` all go through it.
//!
//! Frames are numbered from `shot.start_frame` (default 1): frame number `f` is the shot's
//! 0-based frame `k = f − start_frame`, at `k / fps` seconds ([`self::frames`]).

pub mod chunk;
pub mod frames;
pub mod request;
pub mod run;
pub mod stats;
pub mod story;
pub mod target;
pub mod usd;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use self::frames::FrameSelection;
use self::target::{TargetOrigin, load_spec, load_target};
use super::file::camera::camera_at;
use super::{Scene, SceneError};
use crate::animate::{self, Plan, Timeline, blob_bounds};
use crate::blobby::{Blob, BlobModel};
use crate::file_error::FileError;
use crate::geometry::Aabb;
use crate::render::BasePlane;
use crate::render::output::cryptomatte::{self, Mattes};
use crate::render::{self, Film, Frame, Quality, Region, RenderSettings};

/// How to render a shot (the command line's choices).
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    /// Frames to render (frame numbers), overriding the scene's `frames`.
    pub frames: Option<FrameSelection>,
    /// Output folder overriding the scene's `output.dir`.
    pub output: Option<PathBuf>,
    /// Quarter resolution (at least 64 px wide) with preview quality, in `<dir>/preview/`.
    pub preview: bool,
    /// Re-render frames whose files already exist.
    pub force: bool,
    /// Remove the files of the frames that the run does not ask for (formats left out of
    /// `--formats` or taken out of the scene); without it they are kept and reported.
    pub clean: bool,
    /// Also write each frame's blobs as `<name>_0001.blobs.ron`.
    pub dump_blobs: bool,
    /// Also write per-frame statistics to `<name>_stats.csv` (see [`self::stats`]); frames
    /// already done are rendered again in memory for their coverage.
    pub stats: bool,
    /// Write the render passes into the EXR, as `output.passes: true` does.
    pub passes: bool,
    /// Render only this window of each frame, `x0,y0,x1,y1` in pixels of the frame as
    /// rendered (`x1`, `y1` exclusive); checked by [`Shot::open`].
    pub region: Option<String>,
}

/// The target and its planned animation.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The target model, placed by the scene's transform.
    pub model: BlobModel,
    /// The planned animation.
    pub plan: Plan,
    /// Bounding box of the target's blobs (camera framing; its diagonal is the length unit).
    pub bounds: Aabb,
    /// What the automatic camera frames: `bounds`, or for a target that moves (keyed
    /// `transform`) the box holding it at every frame.
    pub framing: Aabb,
    /// Where the target came from.
    pub origin: TargetOrigin,
    /// How the shot plays the plan: the scene's wind and retime.
    pub direction: animate::Direction,
}

/// A scene's shot, opened once for a run (see the module doc).
#[derive(Debug)]
pub struct Shot {
    scene: Scene,
    options: RenderOptions,
    dir: PathBuf,
    cache_dir: PathBuf,
    frames: Vec<u32>,
    start: u32,
    total: u32,
    width: u32,
    height: u32,
    region: Option<Region>,
    prepared: OnceLock<Prepared>,
    film: OnceLock<Film>,
}

impl Shot {
    /// Open `scene`'s shot with `options`: check the frames, resolve the output folder
    /// (`<dir>/preview/` for previews; the fit cache stays in `<dir>`) and the image size.
    /// Nothing is loaded or written yet.
    pub fn open(scene: Scene, options: &RenderOptions) -> Result<Shot, SceneError> {
        let spec = &scene.file.shot;
        let (start, last, total) = (spec.start_frame, spec.last_frame(), spec.frame_count());
        // Checked again here: a front end's override (`--formats`) bypasses the scene's checks.
        super::Format::check_list(&scene.file.output.formats).map_err(|message| {
            SceneError::Invalid {
                path: scene.path.clone(),
                field: "output.formats (or --formats)".into(),
                message,
            }
        })?;
        let (selection, field) = match (&options.frames, scene.file.frames) {
            (Some(sel), _) => (sel.clone(), "--frames"),
            (None, Some((a, b))) => (FrameSelection::range(a, b), "frames"),
            (None, None) => (FrameSelection::range(start, last), "frames"),
        };
        let frames = selection
            .resolve(start, last)
            .map_err(|message| SceneError::Invalid {
                path: scene.path.clone(),
                field: field.into(),
                message,
            })?;
        let cache_dir = options
            .output
            .clone()
            .unwrap_or_else(|| scene.output_dir.clone());
        let mut dir = cache_dir.clone();
        let (mut width, mut height) = (spec.width, spec.height);
        if options.preview {
            dir = dir.join("preview");
            let w = (width / 4).max(64).min(width);
            height = ((height as f64 * w as f64 / width as f64).round() as u32).max(1);
            width = w;
        }
        let region =
            match &options.region {
                None => None,
                Some(text) => Some(Region::parse(text, width, height).map_err(|message| {
                    SceneError::Invalid {
                        path: scene.path.clone(),
                        field: "--region".into(),
                        message,
                    }
                })?),
            };
        Ok(Shot {
            scene,
            options: options.clone(),
            dir,
            cache_dir,
            frames,
            start,
            total,
            width,
            height,
            region,
            prepared: OnceLock::new(),
            film: OnceLock::new(),
        })
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The options it was opened with.
    pub fn options(&self) -> &RenderOptions {
        &self.options
    }

    /// Folder of the frame files.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// Folder of the target's fit cache: the output folder, also for previews (so a preview and
    /// the final render share one fit).
    pub fn cache_dir(&self) -> &Path {
        &self.cache_dir
    }

    /// The frame numbers to render, sorted.
    pub fn frames(&self) -> &[u32] {
        &self.frames
    }

    /// Render only `frames` (a farm task's chunk of [`Shot::frames`]).
    pub fn set_frames(&mut self, frames: Vec<u32>) {
        self.frames = frames;
    }

    /// Frames in the whole shot.
    pub fn total(&self) -> u32 {
        self.total
    }

    /// Frame number of the shot's 0-based frame `k`.
    pub fn number(&self, k: u32) -> u32 {
        self.start + k
    }

    /// The shot's 0-based frame of frame number `frame` (one of the shot's).
    pub fn index(&self, frame: u32) -> u32 {
        frame - self.start
    }

    /// Image width and height in pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// True when the EXR frames get the render passes (`--passes` or `output.passes`).
    pub fn passes(&self) -> bool {
        self.options.passes || self.scene.file.output.passes
    }

    /// The window each frame renders (`--region`), `None` for the whole frame.
    pub fn region(&self) -> Option<Region> {
        self.region
    }

    /// What the frames are rendered into: the region, and with the passes the ID mattes of
    /// the animation's pieces ([`crate::animate::mattes`], layer `CryptoObject`).
    pub fn film(&self) -> Result<&Film, SceneError> {
        if let Some(f) = self.film.get() {
            return Ok(f);
        }
        let mattes = if self.passes() {
            let m = self.prepared()?.plan.mattes();
            Some(Mattes {
                layer: cryptomatte::OBJECT_LAYER.to_string(),
                names: m.names,
                of_blob: m
                    .of_blob
                    .into_iter()
                    .map(|k| {
                        if k == animate::mattes::NO_MATTE {
                            cryptomatte::NO_MATTE
                        } else {
                            k
                        }
                    })
                    .collect(),
            })
        } else {
            None
        };
        let film = Film {
            region: self.region,
            passes: self.passes(),
            mattes,
            motion: self.scene.file.output.motion_vectors,
        };
        Ok(self.film.get_or_init(|| film))
    }

    /// The target (loaded from its file, its fit cache, or fitted and cached now) and the
    /// planned animation; done once, on first call.
    pub fn prepared(&self) -> Result<&Prepared, SceneError> {
        if let Some(p) = self.prepared.get() {
            return Ok(p);
        }
        let prepared = if self.scene.file.story.is_empty() {
            let (model, origin) = load_target(&self.scene, &self.cache_dir)?;
            plan(&self.scene, model, origin)?
        } else {
            story::plan(&self.scene, &self.cache_dir)?
        };
        // The diffusion's blend path, if another process made it for this very plan.
        super::resume::blend_cache::load(&self.cache_dir, &prepared.plan);
        Ok(self.prepared.get_or_init(|| prepared))
    }

    /// Leave the diffusion's blend path in the cache folder for the next process, when this
    /// one has made it (nothing for other animations, or when it is cached already).
    pub fn cache_blend_path(&self) -> Result<(), SceneError> {
        match self.prepared.get() {
            Some(p) => super::resume::blend_cache::store(&self.cache_dir, &p.plan),
            None => Ok(()),
        }
    }

    /// Where the target came from, once it is loaded.
    pub fn origin(&self) -> Option<&TargetOrigin> {
        self.prepared.get().map(|p| &p.origin)
    }

    /// Render settings of 0-based frame `k`.
    pub fn settings(&self, k: u32) -> Result<RenderSettings, SceneError> {
        let prep = self.prepared()?;
        let f = &self.scene.file;
        let u = if self.total > 1 {
            k as f64 / (self.total - 1) as f64
        } else {
            0.0
        };
        let aspect = self.width as f32 / self.height as f32;
        Ok(RenderSettings {
            width: self.width,
            height: self.height,
            camera: camera_at(
                &f.camera,
                &prep.framing,
                aspect,
                u,
                k as f64 / f.shot.fps,
                self.number(k),
            ),
            sun: f.sun,
            sky: f.sky.clone(),
            cloud: f.cloud,
            exposure: f.exposure,
            length_scale: prep.bounds.diagonal().max(1e-12) as f32,
            seed: f.seed,
            time: k as f32 / f.shot.fps as f32,
            quality: if self.options.preview {
                Quality::preview()
            } else {
                let mut q = Quality::preset(f.quality);
                // The path tracer's own settings, at `quality: Reference` only.
                if q.reference.is_some() && f.reference.is_some() {
                    q.reference = f.reference;
                }
                q
            },
            base: f.cloud.base.map(|b| {
                let (bottom, height) = (prep.bounds.min.y, prep.bounds.max.y - prep.bounds.min.y);
                // The base moves with the cloud (only when the wind or the target moves it: same
                // bits without): the bottom's centre carried, the height scaled.
                let d = &prep.direction;
                let t = k as f64 / f.shot.fps;
                let (bottom, height) = match (&d.motion, d.wind) {
                    (None, None) => (bottom, height),
                    (None, Some(_)) => (bottom + d.drift(t).y, height),
                    (Some(_), _) => {
                        let c = prep.bounds.center();
                        let foot = d.carry(t, glam::DVec3::new(c.x, bottom, c.z));
                        (foot.y, height * d.target_motion(t).scale)
                    }
                };
                BasePlane {
                    y: (bottom + b.height as f64 * height) as f32,
                    softness: (b.softness as f64 * height) as f32,
                }
            }),
            surfaces: self.scene.surfaces.clone(),
        })
    }

    /// Check, without leaving anything behind, that the frames can be written into the shot's
    /// folder (which need not exist yet).
    pub fn check_writable(&self) -> Result<(), SceneError> {
        crate::atomic::check_output_dir(self.dir()).map_err(|e| {
            SceneError::File(FileError::Io {
                path: e.dir,
                source: std::io::Error::new(
                    e.source.kind(),
                    format!("the output folder is not writable: {}", e.source),
                ),
            })
        })
    }

    /// The blobs of 0-based frame `k`.
    pub fn blobs(&self, k: u32) -> Result<Vec<Blob>, SceneError> {
        let prep = self.prepared()?;
        Ok(prep.direction.frame(&prep.plan, k as usize))
    }

    /// Render 0-based frame `k` in memory (with the passes if the shot asks for them).
    pub fn render_frame(&self, k: impl Into<render::FrameIndex>) -> Result<Frame, SceneError> {
        let render::FrameIndex(k) = k.into();
        let request = self.frame_request(k)?;
        Ok(render::FrameRenderer::render_once(
            &request.settings,
            &request.blobs,
            &request.options(self.film()?),
        )
        .0)
    }

    /// The open shutter of 0-based frame `k` with `time_samples` strata (`shot.shutter` of a
    /// frame, centred on it), each with the blobs at its time and their centres' velocities
    /// from the plan; `None` when the shutter is closed or nothing moves while it is open.
    pub fn shutter(
        &self,
        k: u32,
        time_samples: u32,
    ) -> Result<Option<render::Shutter>, SceneError> {
        let spec = &self.scene.file.shot;
        if spec.shutter <= 0.0 {
            return Ok(None);
        }
        let prep = self.prepared()?;
        let (plan, direction) = (&prep.plan, &prep.direction);
        let t = plan.timeline().time(k as usize);
        let (centres, stratum) =
            render::integrator::motion_blur::strata(spec.shutter, time_samples, spec.fps);
        let samples = centres
            .into_iter()
            .map(|offset| {
                let field = direction.velocity(plan, t + offset);
                render::TimeSample {
                    offset,
                    blobs: direction.at(plan, t + offset),
                    velocity: field.motions().iter().map(|m| m.velocity).collect(),
                }
            })
            .collect();
        let shutter = render::Shutter { samples, stratum };
        Ok((!shutter.is_still(&direction.frame(plan, k as usize))).then_some(shutter))
    }
}

/// Apply the scene's target transform to `model` and plan its animation (a morph's fitted
/// source is cached in the scene's output folder).
fn plan(scene: &Scene, mut model: BlobModel, origin: TargetOrigin) -> Result<Prepared, SceneError> {
    scene.file.transform.apply(&mut model.blobs);
    // Before planning: a target the renderer cannot draw is refused, not rendered empty.
    let bounds = blob_bounds(&model.blobs);
    if let Some(target) = &scene.file.target {
        self::target::check_target_box(scene, &bounds, &self::target::spec_name(target))?;
    }
    let shot = &scene.file.shot;
    let timeline = Timeline {
        frames: shot.frame_count() as usize,
        fps: shot.fps,
        hold_seconds: scene.file.animation.hold_seconds(),
    };
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
    .map_err(|source| match source {
        // A setting checked against the target (the diffusion's `start` and `order`): at its
        // place in the scene file when the file can be read again.
        animate::AnimateError::Invalid { field, message } => {
            let e = SceneError::Invalid {
                path: scene.path.clone(),
                field,
                message,
            };
            match std::fs::read_to_string(&scene.path) {
                Ok(text) => e.located(&text),
                Err(_) => e,
            }
        }
        source => SceneError::Animate {
            scene: scene.path.clone(),
            source,
        },
    })?;
    let mut direction = animate::Direction::new(&plan, scene.file.wind, scene.file.timing.clone())
        .with_motion(scene.file.transform.motion());
    let mut bounds = bounds;
    if let Some(seq) = &scene.deforming {
        let deformation = deformation(scene, seq, &plan);
        bounds = bounds.union(deformation.bounds(&plan.frame(timeline.frames - 1)));
        direction.deform = Some(std::sync::Arc::new(deformation));
    }
    let framing = framing(&direction, bounds, &timeline);
    Ok(Prepared {
        model,
        bounds,
        framing,
        origin,
        direction,
        plan,
    })
}

/// The deforming target's motion: the sequence placed by the scene's transform, its frames at
/// the shot's times (`file::deforming`'s rule), anchored to the plan's formed target. The
/// blobs are carried, and re-stretched where the surface leaves what their affine map follows
/// (`Deformation::with_shape_refit`, measured not to lose silhouette IoU); the local refit of
/// `A`, `B` (`Deformation::with_refit`) was measured to lose it (docs/MEASUREMENTS.md,
/// "Bending"), so a shot does not use that.
fn deformation(
    scene: &Scene,
    seq: &crate::mesh::sequence::MeshSequence,
    plan: &Plan,
) -> animate::Deformation {
    let shot = &scene.file.shot;
    let t = &scene.file.transform;
    let frames: Vec<Vec<glam::DVec3>> = seq
        .frames
        .iter()
        .map(|f| f.iter().map(|&p| t.apply_point(p)).collect())
        .collect();
    let first = if seq.from_shot_start {
        0.0
    } else {
        shot.start_frame as f64
    };
    let times: Vec<f64> = seq.numbers.iter().map(|n| (n - first) / shot.fps).collect();
    let formed = plan.frame(plan.timeline().frames - 1);
    let refit = animate::deform::refit::RefitConfig::default();
    animate::Deformation::with_shape_refit(&formed, &frames, &times, &refit)
}

/// The box the camera frames: the target's `bounds`, carried over the whole shot for a target
/// that moves (its corners at every frame).
pub(crate) fn framing(direction: &animate::Direction, bounds: Aabb, timeline: &Timeline) -> Aabb {
    if direction.motion.is_none() {
        return bounds;
    }
    (0..timeline.frames).fold(Aabb::EMPTY, |framing, k| {
        let t = timeline.time(k);
        bounds
            .corners()
            .into_iter()
            .fold(framing, |framing, c| framing.grown(direction.carry(t, c)))
    })
}
