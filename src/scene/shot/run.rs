//! Rendering a shot to frame files, resumable: every file is written atomically and the
//! frame's manifest last, so a frame whose files and manifest exist is finished; it is skipped
//! when its hash matches ([`crate::scene::resume::provenance`]) unless `force` is set, and rendered again,
//! with the reason counted, when it does not.

use std::ops::ControlFlow;
use std::time::Instant;

use super::request::FrameRequest;
use super::stats::StatsBasis;
use super::target::TargetOrigin;
use crate::progress::Timings;
use crate::scene::resume::frame_names;
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
    ///
    /// The steps, frame by frame: [`ShotRun::plan`] once, then for each frame its
    /// [`FrameRequest`], [`ShotRun::check`], [`ShotRun::render`], [`ShotRun::write`] (beside
    /// the next frame's render) and [`ShotRun::account`].
    pub fn run_until(
        &self,
        on_frame: &mut dyn FnMut(&FrameReport) -> ControlFlow<()>,
    ) -> Result<ShotReport, SceneError> {
        let mut run = ShotRun::plan(self)?;
        // Frames in order: a hold reuses the last frame, a still cloud its light grid.
        let mut renderer = crate::render::FrameRenderer::new();
        // A frame's files are encoded and written on their own thread while the next frame
        // renders (one at a time, in order; its error stops the shot before the next write).
        std::thread::scope(|scope| -> Result<(), SceneError> {
            let mut writing: Option<Writer<'_>> = None;
            let frames = self.frames();
            for (n, &frame) in frames.iter().enumerate() {
                let start = Instant::now();
                let request = self.frame_request(self.index(frame))?;
                let checked = run.check(&request)?;
                let finished = checked.check.is_done();
                if finished && !run.stats_wanted() {
                    drop(checked);
                    if run.account(frame, None, start, true, on_frame).is_break() {
                        break;
                    }
                    continue;
                }
                let image = run.render(&mut renderer, &request, &checked.check);
                let rendered = Instant::now();
                finish_writing(&mut writing)?;
                let waited = Instant::now();
                if !finished {
                    let last = n + 1 == frames.len();
                    writing = run.write(scope, &request, image, checked, last)?;
                }
                run.time(start, rendered, waited);
                let stop = run.account(frame, Some((&request, image)), start, finished, on_frame);
                if stop.is_break() {
                    break;
                }
            }
            let last_write = Instant::now();
            finish_writing(&mut writing)?;
            run.write_s += last_write.elapsed().as_secs_f64();
            Ok(())
        })?;
        run.finish()
    }
}

/// A shot's run in progress: what is known once before the frames (the target and plan, the
/// voxel size, the film), the frame renderer carried from frame to frame, and the report.
pub struct ShotRun<'a> {
    shot: &'a Shot,
    voxel: f64,
    film: crate::render::Film,
    basis: Option<StatsBasis>,
    stats: Vec<super::stats::FrameStats>,
    timings: Timings,
    report: ShotReport,
    last: u32,
    render_s: f64,
    write_s: f64,
    stats_s: f64,
    written_at: Option<Instant>,
}

/// A frame checked against its files on disk, its lock held until its manifest is written.
pub struct CheckedFrame {
    /// The frame's inputs.
    pub inputs: provenance::FrameInputs,
    /// What is on disk against what the scene asks for.
    pub check: provenance::FrameCheck,
    /// Held from the check until the frame's manifest is written.
    pub lock: FrameLock,
}

impl<'a> ShotRun<'a> {
    /// Before the first frame: the output folder writable, the target and its plan (the hashes
    /// need every frame's inputs, so the target is loaded, from its cache when there is one,
    /// even when every frame turns out to be up to date), the grids' voxel, the memory a frame
    /// needs (checked on the machine that renders it), and the temporaries killed runs left.
    pub fn plan(shot: &'a Shot) -> Result<ShotRun<'a>, SceneError> {
        shot.check_writable()?;
        let mut timings = Timings::default();
        let prep = timings.stage("target and plan", || shot.prepared())?;
        let report = ShotReport {
            output_dir: shot.dir().to_path_buf(),
            rendered: 0,
            skipped: 0,
            out_of_date: Vec::new(),
            target: Some(prep.origin.clone()),
            timings: Timings::default(),
            stats: None,
            others: OtherFiles::default(),
        };
        let voxel = frame_files::grid_voxel(shot)?;
        let basis = if shot.options().stats {
            Some(StatsBasis::new(shot)?)
        } else {
            None
        };
        // A farm's head node that only loads the scene may have far less memory.
        let first = shot.settings(0)?;
        crate::render::memory::check_available(first.width, first.height, &first.quality).map_err(
            |message| SceneError::Invalid {
                path: shot.scene().path.clone(),
                field: "shot".into(),
                message,
            },
        )?;
        shot.remove_stale_temps()?;
        Ok(ShotRun {
            shot,
            voxel,
            film: shot.film()?.clone(),
            basis,
            stats: Vec::new(),
            timings,
            report,
            last: shot.number(shot.total() - 1),
            render_s: 0.0,
            write_s: 0.0,
            stats_s: 0.0,
            written_at: None,
        })
    }

    /// True when every frame is rendered for its statistics (finished ones again, in memory).
    pub fn stats_wanted(&self) -> bool {
        self.basis.is_some()
    }

    /// Lock the frame and check its files on disk against its inputs; the reason it is out of
    /// date, and the files of other formats it has, are counted in the report.
    pub fn check(&mut self, request: &FrameRequest) -> Result<CheckedFrame, SceneError> {
        let shot = self.shot;
        let opts = shot.options();
        // The manifest is read under the lock: no other writer changes it until the frame's
        // own manifest is written.
        let lock = FrameLock::acquire(
            shot.dir(),
            &frame_names::frame_stem(shot, request.frame),
            &shot.scene().path,
        )?;
        let on_disk = provenance::frame_manifest(shot, request.frame);
        let inputs =
            provenance::frame_inputs(shot, request, &self.film, self.voxel, on_disk.as_ref().ok());
        let check = provenance::check_frame(
            shot,
            request.frame,
            &inputs,
            on_disk,
            opts.force,
            opts.clean,
        );
        let report = &mut self.report;
        report.others.count(&check.others);
        if let FrameStatus::OutOfDate(reason) = &check.status {
            match report.out_of_date.iter_mut().find(|(r, _)| r == reason) {
                Some((_, n)) => *n += 1,
                None => report.out_of_date.push((reason.clone(), 1)),
            }
        }
        Ok(CheckedFrame {
            inputs,
            check,
            lock,
        })
    }

    /// Render the frame with `renderer` if a file to write needs its image (or its statistics
    /// do).
    pub fn render<'r>(
        &self,
        renderer: &'r mut crate::render::FrameRenderer,
        request: &FrameRequest,
        check: &provenance::FrameCheck,
    ) -> Option<&'r crate::render::Frame> {
        (check.needs_render() || self.stats_wanted())
            .then(|| request.render_into(renderer, &self.film))
    }

    /// Write the frame's files: on a thread beside the next frame's render (sequentially, or
    /// its formats would only take the render's cores), or, for the last frame, here with its
    /// formats in parallel. The lock is released once the manifest is written.
    pub fn write<'scope>(
        &self,
        scope: &'scope std::thread::Scope<'scope, '_>,
        request: &FrameRequest,
        image: Option<&crate::render::Frame>,
        checked: CheckedFrame,
        last: bool,
    ) -> Result<Option<Writer<'scope>>, SceneError>
    where
        'a: 'scope,
    {
        let (shot, voxel, frame) = (self.shot, self.voxel, request.frame);
        let write = move |image: Option<&crate::render::Frame>,
                          settings: &crate::render::RenderSettings,
                          blobs: &[crate::blobby::Blob],
                          parallel: bool| {
            let out = frame_files::FrameOutput {
                image,
                settings,
                blobs,
                voxel,
                inputs: &checked.inputs,
                check: &checked.check,
            };
            let written = frame_files::write_frame(shot, frame, &out, parallel);
            drop(checked.lock);
            written
        };
        if last {
            // Nothing to overlap with: no copy of the frame.
            write(image, &request.settings, &request.blobs, true)?;
            return Ok(None);
        }
        // What the writer needs, copied (not the shutter's time samples).
        let (image, settings, blobs) = (
            image.cloned(),
            request.settings.clone(),
            request.blobs.clone(),
        );
        Ok(Some(scope.spawn(move || {
            write(image.as_ref(), &settings, &blobs, false)
        })))
    }

    /// Count a rendered frame's times: its render (from `start` to `rendered`), and what
    /// writing cost the shot: the wait for the previous frame's writer (to `waited`) and, for
    /// the last frame, its own write (to now).
    fn time(&mut self, start: Instant, rendered: Instant, waited: Instant) {
        let now = Instant::now();
        self.render_s += (rendered - start).as_secs_f64();
        self.write_s += (waited - rendered).as_secs_f64() + (now - waited).as_secs_f64();
        self.written_at = Some(now);
    }

    /// Count the frame in the report (and its statistics) and tell `on_frame`.
    fn account(
        &mut self,
        frame: u32,
        rendered: Option<(&FrameRequest, Option<&crate::render::Frame>)>,
        start: Instant,
        finished: bool,
        on_frame: &mut dyn FnMut(&FrameReport) -> ControlFlow<()>,
    ) -> ControlFlow<()> {
        if let Some((request, image)) = rendered {
            let written = self.written_at.take().unwrap_or_else(Instant::now);
            if let (Some(basis), Some(image)) = (&self.basis, image) {
                self.stats
                    .push(basis.frame(frame, &request.blobs, Some(image)));
            }
            self.stats_s += written.elapsed().as_secs_f64();
        }
        if finished {
            self.report.skipped += 1;
        } else {
            self.report.rendered += 1;
        }
        on_frame(&FrameReport {
            frame,
            of: self.last,
            skipped: finished,
            seconds: if rendered.is_some() {
                start.elapsed().as_secs_f64()
            } else {
                0.0
            },
        })
    }

    /// After the last frame: the stage times, the statistics file, and the blend path this run
    /// made (a frame inside a diffusion's blend), cached for the next.
    fn finish(mut self) -> Result<ShotReport, SceneError> {
        self.timings.stages.push(("render".into(), self.render_s));
        self.timings.stages.push(("write".into(), self.write_s));
        if self.basis.is_some() {
            self.timings.stages.push(("stats".into(), self.stats_s));
            let path = super::stats::stats_path(self.shot);
            super::stats::write_csv(&path, &self.stats)?;
            self.report.stats = Some(path);
        }
        self.shot.cache_blend_path()?;
        self.report.timings = self.timings;
        Ok(self.report)
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
                let request = self.frame_request(self.index(frame))?;
                let on_disk = provenance::frame_manifest(self, frame);
                let inputs =
                    provenance::frame_inputs(self, &request, &film, voxel, on_disk.as_ref().ok());
                let check = provenance::check_frame(self, frame, &inputs, on_disk, false, false);
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
