//! Rendering a shot to frame files, resumable: every file is written atomically and the
//! frame's manifest last, so a frame whose files and manifest exist is finished; it is skipped
//! when its hash matches ([`crate::scene::resume::provenance`]) unless `force` is set, and rendered again,
//! with the reason counted, when it does not.

use std::ops::ControlFlow;
use std::time::Instant;

use super::stats::StatsBasis;
use super::target::TargetOrigin;
use crate::progress::Timings;
use crate::scene::resume::lock::FrameLock;
use crate::scene::resume::provenance::{self, FrameStatus};
use crate::scene::shot::Shot;
use crate::scene::{RenderOptions, Scene, SceneError, frame_files};

/// What happened to one frame.
#[derive(Clone, Debug)]
pub struct FrameReport {
    /// Frame number.
    pub frame: u32,
    /// The shot's last frame number.
    pub of: u32,
    /// True when the frame was up to date and skipped.
    pub skipped: bool,
    /// Seconds spent rendering and writing it (0 when skipped).
    pub seconds: f64,
}

/// The outcome of a shot.
#[derive(Clone, Debug)]
pub struct ShotReport {
    /// Folder the frames are in.
    pub output_dir: std::path::PathBuf,
    /// Frames rendered.
    pub rendered: u32,
    /// Frames skipped because they were done and up to date.
    pub skipped: u32,
    /// Frames on disk rendered again because they were out of date: `(reason, count)`, in the
    /// order the reasons were first met.
    pub out_of_date: Vec<(String, u32)>,
    /// Where the target came from.
    pub target: Option<TargetOrigin>,
    /// Wall time per stage (target, plan, render, write).
    pub timings: Timings,
    /// The statistics file, when asked for.
    pub stats: Option<std::path::PathBuf>,
    /// Files of the frames that this run did not ask for (other formats), kept or removed.
    pub others: OtherFiles,
}

/// The files of a shot's frames that a run did not ask for: formats left out of `--formats`
/// or taken out of the scene, kept beside the frames (nothing nephele wrote is deleted unless
/// the run cleans, `--clean`).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct OtherFiles {
    /// Kept, made from the scene's inputs as they are now.
    pub current: u32,
    /// Kept, but made from other inputs (the scene changed since): no longer current.
    pub not_current: u32,
    /// Removed (`--clean`).
    pub removed: u32,
    /// Their kinds (`exr`, `png`, …), in the order first met.
    pub kinds: Vec<String>,
}

impl OtherFiles {
    /// Count a frame's other files.
    fn count(&mut self, others: &[provenance::OtherFile]) {
        for o in others {
            match (o.remove, o.current) {
                (true, _) => self.removed += 1,
                (false, true) => self.current += 1,
                (false, false) => self.not_current += 1,
            }
            if !self.kinds.contains(&o.listed.kind) {
                self.kinds.push(o.listed.kind.clone());
            }
        }
    }
}

/// Open `scene`'s shot with `opts` and [`Shot::run`] it.
pub fn render_shot(
    scene: &Scene,
    opts: &RenderOptions,
    on_frame: &mut dyn FnMut(&FrameReport),
) -> Result<ShotReport, SceneError> {
    Shot::open(scene.clone(), opts)?.run(on_frame)
}

impl Shot {
    /// Render the shot: skip finished frames (unless `force`), render and write the rest,
    /// calling `on_frame` after each frame.
    pub fn run(&self, on_frame: &mut dyn FnMut(&FrameReport)) -> Result<ShotReport, SceneError> {
        self.run_until(&mut |f| {
            on_frame(f);
            ControlFlow::Continue(())
        })
    }

    /// [`Shot::run`] that `on_frame` can stop: when it returns `Break` the shot stops after
    /// that frame, whose files are written (and its manifest, so it counts as done) before
    /// this returns; the frames after it are left for the next run. The report counts the
    /// frames up to the stop. (For front ends that take an interrupt between frames, like the
    /// Python package's `render_all`.)
    pub fn run_until(
        &self,
        on_frame: &mut dyn FnMut(&FrameReport) -> ControlFlow<()>,
    ) -> Result<ShotReport, SceneError> {
        let opts = self.options();
        let mut timings = Timings::default();
        let mut report = ShotReport {
            output_dir: self.dir().to_path_buf(),
            rendered: 0,
            skipped: 0,
            out_of_date: Vec::new(),
            target: None,
            timings: Timings::default(),
            stats: None,
            others: OtherFiles::default(),
        };
        let last = self.number(self.total() - 1);
        // The hashes need every frame's inputs, so the target is loaded (from its cache when
        // there is one) even when every frame turns out to be up to date.
        let prep = timings.stage("target and plan", || self.prepared())?;
        report.target = Some(prep.origin.clone());
        let voxel = frame_files::grid_voxel(self)?;
        let basis = if opts.stats {
            Some(StatsBasis::new(self)?)
        } else {
            None
        };
        let mut stats = Vec::new();
        let (mut render_s, mut write_s, mut stats_s) = (0.0, 0.0, 0.0);
        // The memory a frame needs, checked on the machine that renders it (a farm's head node
        // that only loads the scene may have far less).
        let first = self.settings(0)?;
        crate::render::memory::check_available(first.width, first.height, &first.quality).map_err(
            |message| SceneError::Invalid {
                path: self.scene().path.clone(),
                field: "shot".into(),
                message,
            },
        )?;
        // Temporary files of frames no process is writing were left by a killed render.
        self.remove_stale_temps()?;
        let film = self.film()?.clone();
        // Frames in order: a hold reuses the last frame, a still cloud its light grid.
        let mut renderer = crate::render::FrameRenderer::new();
        // A frame's files are encoded and written on their own thread while the next frame
        // renders (one at a time, in order; its error stops the shot before the next write).
        std::thread::scope(|scope| -> Result<(), SceneError> {
            let mut writing: Option<Writer<'_>> = None;
            let frames = self.frames();
            for (n, &frame) in frames.iter().enumerate() {
                let start = Instant::now();
                let k = self.index(frame);
                let blobs = self.blobs(k)?;
                let settings = self.settings(k)?;
                let inputs = provenance::frame_inputs(self, k, &settings, &blobs, &film, voxel);
                // Held from the check until the manifest is written (by the writer thread).
                let lock = FrameLock::acquire(
                    self.dir(),
                    &crate::scene::resume::frame_names::frame_stem(self, frame),
                    &self.scene().path,
                )?;
                let check = provenance::check_frame(self, frame, &inputs, opts.force, opts.clean);
                report.others.count(&check.others);
                let finished = check.is_done();
                if let FrameStatus::OutOfDate(reason) = &check.status {
                    match report.out_of_date.iter_mut().find(|(r, _)| r == reason) {
                        Some((_, n)) => *n += 1,
                        None => report.out_of_date.push((reason.clone(), 1)),
                    }
                }
                // With statistics every frame is rendered (finished ones again, in memory only).
                let render = check.needs_render() || opts.stats;
                if finished && !opts.stats {
                    drop(lock);
                    report.skipped += 1;
                    if on_frame(&skipped(frame, last)).is_break() {
                        break;
                    }
                    continue;
                }
                let shutter = self.shutter(k, settings.quality.time_samples)?;
                let options = crate::render::FrameOptions {
                    shutter: shutter.as_ref(),
                    film: &film,
                };
                let image = render.then(|| renderer.render(&settings, &blobs, &options));
                let rendered = Instant::now();
                finish_writing(&mut writing)?;
                let written = Instant::now();
                if !finished {
                    if n + 1 < frames.len() {
                        let (image, settings, blobs) =
                            (image.cloned(), settings.clone(), blobs.clone());
                        // Written beside the next frame's render: sequentially, or its formats
                        // would only take the render's cores.
                        writing = Some(scope.spawn(move || {
                            let out = frame_files::FrameOutput {
                                image: image.as_ref(),
                                settings: &settings,
                                blobs: &blobs,
                                voxel,
                                inputs: &inputs,
                                check: &check,
                            };
                            let written = frame_files::write_frame(self, frame, &out, false);
                            drop(lock);
                            written
                        }));
                    } else {
                        // The last frame: nothing to overlap with, so no copy of it, and its
                        // formats in parallel.
                        let out = frame_files::FrameOutput {
                            image,
                            settings: &settings,
                            blobs: &blobs,
                            voxel,
                            inputs: &inputs,
                            check: &check,
                        };
                        frame_files::write_frame(self, frame, &out, true)?;
                        drop(lock);
                    }
                } else {
                    drop(lock);
                }
                let written_last = Instant::now();
                if let (Some(basis), Some(image)) = (&basis, image) {
                    stats.push(basis.frame(frame, &blobs, Some(image)));
                }
                render_s += (rendered - start).as_secs_f64();
                // Writing costs the shot only what it did not overlap: the wait for the previous
                // frame's writer, and the last frame's own write.
                write_s +=
                    (written - rendered).as_secs_f64() + (written_last - written).as_secs_f64();
                stats_s += written_last.elapsed().as_secs_f64();
                if finished {
                    report.skipped += 1;
                } else {
                    report.rendered += 1;
                }
                let stop = on_frame(&FrameReport {
                    frame,
                    of: last,
                    skipped: finished,
                    seconds: start.elapsed().as_secs_f64(),
                });
                if stop.is_break() {
                    break;
                }
            }
            let last_write = Instant::now();
            finish_writing(&mut writing)?;
            write_s += last_write.elapsed().as_secs_f64();
            Ok(())
        })?;
        timings.stages.push(("render".into(), render_s));
        timings.stages.push(("write".into(), write_s));
        if basis.is_some() {
            timings.stages.push(("stats".into(), stats_s));
            let path = super::stats::stats_path(self);
            super::stats::write_csv(&path, &stats)?;
            report.stats = Some(path);
        }
        // The blend path this run made (a frame inside a diffusion's blend), for the next.
        self.cache_blend_path()?;
        report.timings = timings;
        Ok(report)
    }
}

impl Shot {
    /// Remove the temporary files that killed runs left in the frames folder and the cache
    /// folder (frames, statistics, the fitted target's and the blend path's caches; those no
    /// running process is writing, [`crate::scene::resume::lock::remove_stale_temps`]); returns how many.
    pub fn remove_stale_temps(&self) -> Result<usize, SceneError> {
        crate::scene::resume::lock::remove_stale_temps(
            &[self.dir(), self.cache_dir()],
            &self.scene().name,
        )
    }

    /// What [`Shot::run`] would do with each requested frame: up to date, new, or out of date
    /// with the reason (the run's rule, for `prepare` and the farm).
    pub fn statuses(&self) -> Result<Vec<(u32, FrameStatus)>, SceneError> {
        let voxel = frame_files::grid_voxel(self)?;
        let film = self.film()?.clone();
        self.frames()
            .iter()
            .map(|&frame| {
                let k = self.index(frame);
                let (settings, blobs) = (self.settings(k)?, self.blobs(k)?);
                let inputs = provenance::frame_inputs(self, k, &settings, &blobs, &film, voxel);
                let check = provenance::check_frame(self, frame, &inputs, false, false);
                Ok((frame, check.status))
            })
            .collect()
    }
}

/// The thread writing a frame's files.
type Writer<'scope> = std::thread::ScopedJoinHandle<'scope, Result<(), SceneError>>;

/// Wait for the frame being written, if any, and pass on its error.
fn finish_writing(writing: &mut Option<Writer<'_>>) -> Result<(), SceneError> {
    writing
        .take()
        .map_or(Ok(()), |w| w.join().expect("the frame writer panicked"))
}

fn skipped(frame: u32, of: u32) -> FrameReport {
    FrameReport {
        frame,
        of,
        skipped: true,
        seconds: 0.0,
    }
}
