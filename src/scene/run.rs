//! Rendering a shot to frame files, resumable: every file is written atomically, so a frame
//! whose files all exist is finished and is skipped unless `force` is set; the target is not
//! even loaded (nor fitted) when every requested frame is done.

use std::time::Instant;

use super::shot::Shot;
use super::stats::StatsBasis;
use super::target::TargetOrigin;
use super::{RenderOptions, Scene, SceneError, files};
use crate::progress::Timings;

/// What happened to one frame.
#[derive(Clone, Debug)]
pub struct FrameReport {
    /// Frame number.
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
    pub output_dir: std::path::PathBuf,
    /// Frames rendered.
    pub rendered: u32,
    /// Frames skipped because they were done.
    pub skipped: u32,
    /// Where the target came from (`None` when every frame was already done).
    pub target: Option<TargetOrigin>,
    /// Wall time per stage (target, plan, render, write).
    pub timings: Timings,
    /// The statistics file, when asked for.
    pub stats: Option<std::path::PathBuf>,
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
        let opts = self.options();
        let mut timings = Timings::default();
        let done =
            |frame: u32| !opts.force && files::frame_paths(self, frame).iter().all(|p| p.is_file());
        // Each frame's files are looked for once: (frame, finished).
        let frames: Vec<(u32, bool)> = self.frames().map(|f| (f, done(f))).collect();
        // With statistics, finished frames are rendered again in memory (not written).
        let render_it = |finished: bool| opts.stats || !finished;
        let mut report = ShotReport {
            output_dir: self.dir().to_path_buf(),
            rendered: 0,
            skipped: 0,
            target: None,
            timings: Timings::default(),
            stats: None,
        };
        let total = self.total();
        if !frames.iter().any(|&(_, finished)| render_it(finished)) {
            for &(frame, _) in &frames {
                report.skipped += 1;
                on_frame(&skipped(frame, total));
            }
            return Ok(report);
        }
        let prep = timings.stage("target and plan", || self.prepared())?;
        report.target = Some(prep.origin.clone());
        let voxel = files::grid_voxel(self)?;
        let basis = if opts.stats {
            Some(StatsBasis::new(self)?)
        } else {
            None
        };
        let mut stats = Vec::new();
        let (mut render_s, mut write_s, mut stats_s) = (0.0, 0.0, 0.0);
        for &(frame, finished) in &frames {
            if !render_it(finished) {
                report.skipped += 1;
                on_frame(&skipped(frame, total));
                continue;
            }
            let start = Instant::now();
            let k = self.index(frame);
            let blobs = self.blobs(k)?;
            let settings = self.settings(k)?;
            let image = self.image(k, &settings, &blobs)?;
            let rendered = Instant::now();
            let write = !finished;
            if write {
                let out = files::FrameOutput {
                    image: &image,
                    settings: &settings,
                    blobs: &blobs,
                    voxel,
                };
                files::write_frame(self, frame, &out)?;
            }
            let written = Instant::now();
            if let Some(basis) = &basis {
                stats.push(basis.frame(frame, &blobs, Some(&image)));
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
                of: total,
                skipped: !write,
                seconds: start.elapsed().as_secs_f64(),
            });
        }
        timings.stages.push(("render".into(), render_s));
        timings.stages.push(("write".into(), write_s));
        if basis.is_some() {
            timings.stages.push(("stats".into(), stats_s));
            let path = super::stats::stats_path(self);
            super::stats::write_csv(&path, &stats)?;
            report.stats = Some(path);
        }
        report.timings = timings;
        Ok(report)
    }
}

fn skipped(frame: u32, of: u32) -> FrameReport {
    FrameReport {
        frame,
        of,
        skipped: true,
        seconds: 0.0,
    }
}
