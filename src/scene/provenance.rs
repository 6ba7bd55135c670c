//! Frame provenance: what made a frame, so that resume skips only frames that are up to date.
//!
//! A frame's **hash** covers everything its pixels are computed from: the renderer's inputs for
//! that frame — its blobs (which follow from the target model, the target transform, the
//! animation and the seed) and its render settings (image size, camera at that frame, sun,
//! sky, cloud look, exposure, quality, seed, time) — the output kind (final or preview, the
//! region of a look test, render passes, the EXR's colour space, the grids' voxel size; with
//! VDBs, the blobs' motions about the frame, which make the velocity grid) and the renderer's
//! version. It is written into the EXR header (`nephele/hash`, 16 hex digits)
//! and, for every format, into a small manifest beside the frame, `<name>_<frame>.manifest.json`
//! (frame, hash, version, output kind, file names), written last: a frame whose manifest and
//! files are there and whose hash matches is finished and up to date.
//!
//! Resume renders a frame again when its files or its manifest are missing (a frame written by
//! an older nephele has no manifest) or its hash differs, and says why: the renderer's version
//! changed, the output kind changed (a region or preview frame is never taken for a full one),
//! or — everything else — the scene changed. Hashing a frame's own inputs means that a scene
//! edit re-renders exactly the frames whose inputs it changes (a morph's `stagger` leaves the
//! held frames at both ends alone). The hash is FNV-1a over exact text (shortest round-trip
//! floats), so it is the same on every machine and at any thread count.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::Shot;
use crate::blobby::Blob;
use crate::render::RenderSettings;

/// How [`output_kind`] names a region render.
const REGION: &str = "region";

/// What a frame's manifest records.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Frame number.
    pub frame: u32,
    /// The frame's hash (16 hex digits).
    pub hash: String,
    /// nephele's version that rendered it.
    pub version: String,
    /// The output kind ([`output_kind`]).
    pub output: String,
    /// The frame's files, by name, in the manifest's folder.
    pub files: Vec<String>,
}

/// Whether a frame on disk can be kept.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameStatus {
    /// Files and manifest present, hash matching: skip it.
    UpToDate,
    /// Never rendered (no files).
    New,
    /// On disk but not up to date; the reason, for the run's summary.
    OutOfDate(String),
}

/// The output kind of `shot`'s frames: `final` or `preview`, the EXR colour space, the render
/// passes with their ID mattes, and the region of a look test (`final; Rec709`, `final;
/// Rec709; passes + CryptoObject; region 0,0,64,32`). Part of the hash, and what a manifest's
/// `output` says.
pub fn output_kind(shot: &Shot) -> String {
    let out = &shot.scene().file.output;
    let mut kind = if shot.is_preview() {
        "preview".to_string()
    } else {
        "final".to_string()
    };
    kind.push_str(&format!("; {:?}", out.colorspace));
    if shot.passes() {
        // Passes frames of a nephele without the mattes said `; passes`: they are re-rendered.
        kind.push_str("; passes + ");
        kind.push_str(crate::render::cryptomatte::OBJECT_LAYER);
    }
    if let Some(r) = shot.region() {
        kind.push_str(&format!("; {REGION} {r}"));
    }
    kind
}

/// The hash of the shot's 0-based frame `k`, rendered with `settings` from `blobs` by `shot`
/// (see the module doc); `voxel` is the density grids' voxel size (0 without grids).
pub fn frame_hash(
    shot: &Shot,
    k: u32,
    settings: &RenderSettings,
    blobs: &[Blob],
    voxel: f64,
) -> u64 {
    let head = format!(
        "nephele frame; version {}; output {}; voxel {voxel:?}",
        env!("CARGO_PKG_VERSION"),
        output_kind(shot)
    );
    let time_samples = settings.quality.time_samples;
    let settings = format!("{settings:?}");
    let blobs = format!("{blobs:?}");
    // A VDB also holds the velocity grid, made from the blobs' motions about the frame's time
    // (in units per second, so the frame rate counts too).
    let motion = match shot.prepared() {
        Ok(prep)
            if shot
                .scene()
                .file
                .output
                .formats
                .contains(&super::Format::Vdb) =>
        {
            let plan = &prep.plan;
            let t = plan.timeline().time(k as usize);
            let field = crate::animate::VelocityField::of_plan(plan, t);
            format!(
                "fps {:?}; {:?}",
                shot.scene().file.shot.fps,
                field.motions()
            )
        }
        _ => String::new(),
    };
    // An open shutter renders the blobs over its time samples (nothing added when closed, so
    // such frames keep their hashes).
    let shutter = if shot.scene().file.shot.shutter > 0.0 {
        format!(
            "shutter {:?}; {:?}",
            shot.scene().file.shot.shutter,
            shot.shutter(k, time_samples).ok().flatten()
        )
    } else {
        String::new()
    };
    super::target::fnv1a(&[
        head.as_bytes(),
        settings.as_bytes(),
        blobs.as_bytes(),
        motion.as_bytes(),
        shutter.as_bytes(),
    ])
}

/// The manifest of frame number `frame`: `<name>_<frame>.manifest.json` beside its files.
pub fn manifest_path(shot: &Shot, frame: u32) -> PathBuf {
    shot.dir().join(format!(
        "{}.manifest.json",
        super::files::frame_stem(shot, frame)
    ))
}

/// The manifest text of a frame.
pub fn record_text(record: &FrameRecord) -> String {
    // A plain struct of strings always serializes.
    serde_json::to_string_pretty(record).unwrap_or_default() + "\n"
}

/// The record in the manifest at `path`, if it is there and readable.
pub fn read_record(path: &Path) -> Option<FrameRecord> {
    let text = std::fs::read_to_string(path).ok()?;
    serde_json::from_str(&text).ok()
}

/// Whether frame number `frame` of `shot` with hash `hash` is on disk and up to date.
pub fn status(shot: &Shot, frame: u32, hash: u64) -> FrameStatus {
    let files = super::files::frame_paths(shot, frame);
    let present = files.iter().filter(|p| p.is_file()).count();
    let record = read_record(&manifest_path(shot, frame));
    if record.is_none() && present == 0 {
        return FrameStatus::New;
    }
    let Some(record) = record else {
        return FrameStatus::OutOfDate("no manifest (rendered by an older nephele)".into());
    };
    if present < files.len() {
        return FrameStatus::OutOfDate("files missing".into());
    }
    if record.hash == hash_text(hash) {
        return FrameStatus::UpToDate;
    }
    let version = env!("CARGO_PKG_VERSION");
    let kind = output_kind(shot);
    FrameStatus::OutOfDate(if record.version != version {
        format!("renderer changed ({} → {version})", record.version)
    } else if record.output.contains(REGION) && !kind.contains(REGION) {
        // A look test's frame is never taken for the full frame.
        "region render".into()
    } else if record.output != kind {
        format!("output changed ({} → {kind})", record.output)
    } else {
        "scene changed".into()
    })
}

/// A hash as written in headers and manifests: 16 lowercase hex digits.
pub fn hash_text(hash: u64) -> String {
    format!("{hash:016x}")
}
