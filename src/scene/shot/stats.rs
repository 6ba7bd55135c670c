//! Per-frame statistics of a shot (`nephele render SCENE --stats`, `NAME_stats.csv`): how much
//! of the target is visible, in how many pieces, and how much of the screen it covers.
//!
//! - 3D: the blob field's solid `F ≥ 0` on a lattice of 1 % of the target's diagonal, with its
//!   6-connected components ([`crate::animate::stats`]); independent of the renderer's look.
//! - 2D: the rendered alpha from the scene's camera, pixels with alpha > 0.05, 4-connected
//!   components ([`crate::animate::stats::coverage`]).
//!
//! CSV columns: `frame` (the frame number), `time_s`, `visible_blobs`, `volume_fraction` (visible cells
//! over the last frame's), `components_3d`, `largest_3d` (share of the visible cells in the
//! largest component), `coverage` (fraction of the image's pixels), `components_2d`,
//! `largest_2d`. The 2D columns are empty for frames whose image was not rendered.

use std::fmt::Write as _;
use std::path::Path;

use crate::animate::stats::{
    ALPHA_LEVEL, Coverage, DEFAULT_CELL_FRACTION, Lattice, VisibleVolume, coverage, visible_volume,
};
use crate::blobby::Blob;
use crate::file_error::FileError;
use crate::render::Frame;
use crate::scene::shot::Shot;
use crate::scene::{RenderOptions, Scene, SceneError};

/// The statistics of one frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameStats {
    /// Frame number.
    pub frame: u32,
    /// Time of the frame in seconds.
    pub time: f64,
    /// Live blobs in the frame.
    pub visible_blobs: usize,
    /// The visible solid on the lattice.
    pub volume: VisibleVolume,
    /// Visible cells over the last frame's.
    pub volume_fraction: f64,
    /// Screen coverage, when the frame's image was rendered.
    pub coverage: Option<Coverage>,
}

/// What the statistics of every frame of a shot share: the lattice and the final volume.
#[derive(Clone, Copy, Debug)]
pub struct StatsBasis {
    lattice: Lattice,
    threshold: f64,
    final_voxels: usize,
    fps: f64,
    /// Frame number of the shot's first frame.
    first: u32,
}

impl StatsBasis {
    /// The basis of `shot`: lattice from the target's box, final volume from the last frame of
    /// the plan.
    pub fn new(shot: &Shot) -> Result<StatsBasis, SceneError> {
        let prep = shot.prepared()?;
        let timeline = prep.plan.timeline();
        let last_k = timeline.frames.saturating_sub(1);
        // A target that moves is measured on a lattice over its whole path, against its last
        // frame where the keys put it (a still target: the plan's box and last frame, as ever).
        let (lattice, last) = match prep.direction.motion {
            None => (
                Lattice::for_target(&prep.bounds, DEFAULT_CELL_FRACTION),
                prep.plan.frame(last_k),
            ),
            Some(_) => (
                Lattice::for_target(&prep.framing, DEFAULT_CELL_FRACTION),
                prep.direction.frame(&prep.plan, last_k),
            ),
        };
        let threshold = prep.model.threshold;
        let final_voxels = visible_volume(&last, threshold, lattice).voxels;
        Ok(StatsBasis {
            lattice,
            threshold,
            final_voxels,
            fps: timeline.fps,
            first: shot.number(0),
        })
    }

    /// Statistics of frame number `frame` with blobs `blobs` and, if rendered, its image.
    pub fn frame(&self, frame: u32, blobs: &[Blob], image: Option<&Frame>) -> FrameStats {
        let volume = visible_volume(blobs, self.threshold, self.lattice);
        FrameStats {
            frame,
            time: (frame - self.first) as f64 / self.fps,
            visible_blobs: blobs.iter().filter(|b| b.is_live()).count(),
            volume,
            volume_fraction: volume.voxels as f64 / self.final_voxels.max(1) as f64,
            coverage: image
                .map(|f| coverage(&f.alpha, f.width as usize, f.height as usize, ALPHA_LEVEL)),
        }
    }
}

/// Statistics of every frame in the options' range without writing frames: the 3D part for
/// every frame, the 2D part from an in-memory render of every `alpha_every`-th frame (counted
/// from the first of the range; the range's last frame always; 0 = never).
pub fn shot_stats(
    scene: &Scene,
    opts: &RenderOptions,
    alpha_every: u32,
) -> Result<Vec<FrameStats>, SceneError> {
    let shot = Shot::open(scene.clone(), opts)?;
    let basis = StatsBasis::new(&shot)?;
    let frames = shot.frames();
    let (first, last) = (frames[0], frames[frames.len() - 1]);
    frames
        .iter()
        .map(|&frame| {
            let k = shot.index(frame);
            let blobs = shot.blobs(k)?;
            let render = alpha_every > 0 && ((frame - first) % alpha_every == 0 || frame == last);
            let image = if render {
                Some(shot.render_frame(k)?)
            } else {
                None
            };
            Ok(basis.frame(frame, &blobs, image.as_ref()))
        })
        .collect()
}

/// The CSV text of `stats` (header, then one line per frame).
pub fn to_csv(stats: &[FrameStats]) -> String {
    let mut s = String::from(
        "frame,time_s,visible_blobs,volume_fraction,components_3d,largest_3d,coverage,components_2d,largest_2d\n",
    );
    for f in stats {
        let _ = write!(
            s,
            "{},{:.4},{},{:.5},{},{:.5},",
            f.frame,
            f.time,
            f.visible_blobs,
            f.volume_fraction,
            f.volume.components,
            f.volume.largest_share()
        );
        match f.coverage {
            Some(c) => {
                let _ = writeln!(
                    s,
                    "{:.5},{},{:.5}",
                    c.fraction,
                    c.components,
                    c.largest_share()
                );
            }
            None => s.push_str(",,\n"),
        }
    }
    s
}

/// Write `stats` as CSV to `path` atomically.
pub fn write_csv(path: &Path, stats: &[FrameStats]) -> Result<(), SceneError> {
    crate::atomic::write_bytes_atomically(path, to_csv(stats).as_bytes()).map_err(|source| {
        SceneError::File(FileError::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// The stats file of a shot: `<dir>/<name>_stats.csv`.
pub fn stats_path(shot: &Shot) -> std::path::PathBuf {
    shot.dir().join(format!("{}_stats.csv", shot.scene().name))
}
