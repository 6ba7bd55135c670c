//! Frame provenance: what made each file of a frame, so that resume keeps only files that are
//! exactly what the scene asks for now — content-addressed, as Bazel and Nix trust an output
//! only by its own hash.
//!
//! **Inputs.** A frame's inputs are hashed by component ([`Component`]): the renderer
//! ([`RENDER_VERSION`]), the image settings, the camera, the sun and sky, the cloud's look, the
//! blobs, the film (region, passes, mattes), the shutter, the grids (voxel size, the blobs'
//! motions, the frame rate of the velocity) and the EXR header (scene name, frame, seed, colour
//! space, frame rate). Every value goes in through its canonical encoding
//! ([`super::canonical`]: field by field, little-endian bits), so a hash is the same on every
//! machine, at any thread count, and changes with any input.
//!
//! **Files.** Each file's hash covers the components it is made from (a PNG does not depend on
//! the EXR header, a VDB not on the camera): adding or removing a format, or changing what only
//! one format depends on, leaves the other files alone. The EXR carries its own hash in its
//! header (`nephele/hash`); every file is listed in the frame's manifest,
//! `<name>_<frame>.manifest.json`, with its hash, its size and the BLAKE3 of its bytes.
//!
//! **Manifest.** Written last, after every file is in place; before the first file of a
//! re-render replaces an old one it is replaced by one listing only the files that write leaves
//! alone. It holds a check hash over its own contents, so an edited or truncated manifest is
//! never trusted, and it may list only the names nephele writes for its frame (a name that is
//! absolute, holds `..` or a separator, or is any other file makes it untrusted: nothing it
//! lists is ever removed). A frame is **up to date** only when its manifest is readable and
//! every file the scene asks for is on disk as a regular file, listed with the hash the scene
//! gives it now, of the listed size, (EXR) carrying that hash in its header, and with the
//! listed BLAKE3 of its bytes: corrupted bytes are never counted done.
//!
//! **Other files.** Files the manifest lists that a run does not ask for (a `--formats`
//! subset, a format taken out of the scene) are kept and listed again, reported as current or
//! not ([`OtherFile`]); only `--clean` removes them. Nothing nephele wrote is deleted except to
//! replace it with its new version.
//!
//! **Reasons.** A frame that is not up to date says why, from the hashes alone: `interrupted`,
//! `manifest unreadable: …`, `renderer changed`, `formats added: +vol`, `files replaced since
//! their manifest`, or the components whose hashes differ (`changed: camera, sun and sky`).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::canonical::{Canonical, Encoder};
use super::{Format, Shot};
use crate::blobby::Blob;
use crate::render::{Film, RenderSettings};

/// The renderer's version: raised whenever a change makes any frame's pixels or grids differ
/// (the pinned seeded frame hashes in the tests change with it, and a test fails if they change
/// while it does not). Frames of another render version are re-rendered on resume.
pub const RENDER_VERSION: u32 = 3;

/// One part of a frame's inputs, hashed on its own so that a reason can name what changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Component {
    /// [`RENDER_VERSION`].
    Renderer,
    /// Image size, quality, exposure, seed, time, length unit.
    Image,
    /// The frame's camera.
    Camera,
    /// Sun and sky.
    Light,
    /// Cloud material, billows and base.
    Look,
    /// The frame's blobs.
    Blobs,
    /// Region, passes and ID mattes.
    Film,
    /// The open shutter's time samples.
    Shutter,
    /// Voxel size, the blobs' motions and the frame rate (the grids and their velocity).
    Grid,
    /// The EXR header's strings and frame rate.
    Header,
}

impl Component {
    /// Every component, in manifest order.
    pub const ALL: [Component; 10] = [
        Component::Renderer,
        Component::Image,
        Component::Camera,
        Component::Light,
        Component::Look,
        Component::Blobs,
        Component::Film,
        Component::Shutter,
        Component::Grid,
        Component::Header,
    ];

    /// Its key in a manifest.
    pub fn key(self) -> &'static str {
        match self {
            Component::Renderer => "renderer",
            Component::Image => "image",
            Component::Camera => "camera",
            Component::Light => "light",
            Component::Look => "look",
            Component::Blobs => "blobs",
            Component::Film => "film",
            Component::Shutter => "shutter",
            Component::Grid => "grid",
            Component::Header => "header",
        }
    }

    /// What it is, for a reason.
    pub fn label(self) -> &'static str {
        match self {
            Component::Renderer => "renderer",
            Component::Image => "image size or quality",
            Component::Camera => "camera",
            Component::Light => "sun and sky",
            Component::Look => "cloud look",
            Component::Blobs => "cloud shape (blobs)",
            Component::Film => "region, passes or mattes",
            Component::Shutter => "shutter",
            Component::Grid => "grid (voxel size, motion, fps)",
            Component::Header => "EXR header (scene, seed, colour space, fps)",
        }
    }

    /// The components a file of `kind` is made from.
    fn of(kind: FileKind) -> &'static [Component] {
        use Component::*;
        match kind {
            FileKind::Format(Format::Exr) => &[
                Renderer, Image, Camera, Light, Look, Blobs, Film, Shutter, Header,
            ],
            FileKind::Format(Format::Png) => {
                &[Renderer, Image, Camera, Light, Look, Blobs, Film, Shutter]
            }
            FileKind::Format(Format::Vdb) | FileKind::Format(Format::Vol) => {
                &[Renderer, Look, Blobs, Grid]
            }
            FileKind::Blobs => &[Blobs],
        }
    }
}

/// What a file of a frame is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// One of the scene's output formats.
    Format(Format),
    /// The blob dump (`--dump-blobs`).
    Blobs,
}

impl FileKind {
    /// Its name in a manifest and in reasons (`exr`, …, `blobs`).
    pub fn key(self) -> &'static str {
        match self {
            FileKind::Format(f) => f.extension(),
            FileKind::Blobs => "blobs",
        }
    }

    /// True when the file is made from the rendered image (so writing it needs a render).
    pub fn needs_image(self) -> bool {
        matches!(self, FileKind::Format(Format::Exr | Format::Png))
    }

    fn from_key(key: &str) -> Option<FileKind> {
        if key == "blobs" {
            return Some(FileKind::Blobs);
        }
        Format::ALL
            .into_iter()
            .find(|f| f.extension() == key)
            .map(FileKind::Format)
    }
}

/// A frame's inputs, hashed by component (see the module doc).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameInputs {
    hashes: BTreeMap<Component, u64>,
}

impl FrameInputs {
    /// The hash of one component.
    pub fn hash(&self, c: Component) -> u64 {
        self.hashes[&c]
    }

    /// The hash of a file of `kind`: its kind and the hashes of the components it is made from.
    pub fn file_hash(&self, kind: FileKind) -> u64 {
        let mut e = Encoder::new();
        e.str("nephele frame file").str(kind.key());
        for &c in Component::of(kind) {
            e.str(c.key()).put(&self.hash(c));
        }
        e.finish()
    }
}

/// The inputs of the shot's 0-based frame `k` (frame number `frame`), rendered with `settings`
/// from `blobs` into `film`; `voxel` is the density grids' voxel size (0 without grids).
pub fn frame_inputs(
    shot: &Shot,
    k: u32,
    settings: &RenderSettings,
    blobs: &[Blob],
    film: &Film,
    voxel: f64,
) -> FrameInputs {
    let scene = shot.scene();
    let file = &scene.file;
    let hash = |f: &dyn Fn(&mut Encoder)| {
        let mut e = Encoder::new();
        f(&mut e);
        e.finish()
    };
    let mut hashes = BTreeMap::new();
    hashes.insert(
        Component::Renderer,
        hash(&|e| {
            e.str("render version").put(&RENDER_VERSION);
        }),
    );
    let RenderSettings {
        width,
        height,
        camera,
        sun,
        sky,
        cloud,
        exposure,
        length_scale,
        seed,
        time,
        quality,
        base,
    } = settings;
    hashes.insert(
        Component::Image,
        hash(&|e| {
            e.put(width)
                .put(height)
                .put(exposure)
                .put(length_scale)
                .put(seed)
                .put(time)
                .put(quality);
        }),
    );
    hashes.insert(Component::Camera, camera.canonical_hash());
    hashes.insert(
        Component::Light,
        hash(&|e| {
            e.put(sun).put(sky);
        }),
    );
    hashes.insert(
        Component::Look,
        hash(&|e| {
            e.put(cloud).put(base).put(length_scale);
        }),
    );
    hashes.insert(Component::Blobs, blobs.canonical_hash());
    hashes.insert(Component::Film, film.canonical_hash());
    // An open shutter renders the blobs over its time samples.
    let shutter = if file.shot.shutter > 0.0 {
        shot.shutter(k, quality.time_samples).ok().flatten()
    } else {
        None
    };
    hashes.insert(
        Component::Shutter,
        hash(&|e| {
            e.put(&file.shot.shutter).put(&shutter);
        }),
    );
    // A VDB also holds the velocity grid, made from the blobs' motions about the frame's time
    // (in units per second, so the frame rate counts too), and UUIDs from the seed and frame.
    // Also when the run writes no VDB but the frame has one (kept from another run), so that
    // it can be told whether that VDB is still current.
    let frame = shot.number(k);
    let vdb = FileKind::Format(Format::Vdb);
    let lists_vdb = || {
        read_manifest(&manifest_path(shot, frame))
            .is_ok_and(|m| m.files.iter().any(|f| f.kind == vdb.key()))
    };
    let motions = if file.output.formats.contains(&Format::Vdb) || lists_vdb() {
        shot.prepared().ok().map(|prep| {
            let plan = &prep.plan;
            let t = plan.timeline().time(k as usize);
            crate::animate::VelocityField::of_plan(plan, t)
                .motions()
                .to_vec()
        })
    } else {
        None
    };
    hashes.insert(
        Component::Grid,
        hash(&|e| {
            e.put(&voxel)
                .put(&motions)
                .put(&file.shot.fps)
                .put(&file.seed)
                .put(&frame);
        }),
    );
    let meta = super::frame_files::header_strings(shot, frame, 0);
    hashes.insert(
        Component::Header,
        hash(&|e| {
            for (k, v) in &meta {
                // The hash itself is written after it is known.
                if k != "hash" {
                    e.str(k).str(v);
                }
            }
            let (num, den) = crate::render::output::fps_rational(file.shot.fps);
            e.put(&num).put(&den).put(&file.shot.fps);
            e.put(&(file.output.colorspace as u8));
        }),
    );
    FrameInputs { hashes }
}

/// A file as a manifest lists it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ListedFile {
    /// File name, in the manifest's folder.
    pub name: String,
    /// What it is (`exr`, `png`, `vdb`, `vol`, `blobs`).
    pub kind: String,
    /// Its hash ([`FrameInputs::file_hash`], 16 hex digits).
    pub hash: String,
    /// Its size in bytes.
    pub bytes: u64,
    /// BLAKE3 of its bytes (64 hex digits, [`content_hash`]), checked on resume: a file whose
    /// bytes changed since it was written is never counted done. Empty in the manifests of
    /// nephele before content hashes (their frames are rendered again).
    #[serde(default)]
    pub blake3: String,
}

/// What a frame's manifest records.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Frame number.
    pub frame: u32,
    /// [`RENDER_VERSION`] of the renderer that made the files.
    pub render_version: u32,
    /// nephele's crate version (for people; not checked).
    pub nephele: String,
    /// The inputs' hash per component, by [`Component::key`].
    pub inputs: BTreeMap<String, String>,
    /// The frame's files.
    pub files: Vec<ListedFile>,
    /// Hash of everything above ([`Manifest::check_hash`]): a manifest whose check fails was
    /// edited or damaged and is not trusted.
    pub check: String,
}

impl Manifest {
    /// A manifest of frame number `frame` with these inputs and files, its check hash set.
    pub fn new(frame: u32, inputs: &FrameInputs, files: Vec<ListedFile>) -> Manifest {
        let mut m = Manifest {
            frame,
            render_version: RENDER_VERSION,
            nephele: env!("CARGO_PKG_VERSION").to_string(),
            inputs: Component::ALL
                .iter()
                .map(|&c| (c.key().to_string(), hash_text(inputs.hash(c))))
                .collect(),
            files,
            check: String::new(),
        };
        m.check = hash_text(m.check_hash());
        m
    }

    /// The canonical hash of every field but `check`.
    pub fn check_hash(&self) -> u64 {
        let mut e = Encoder::new();
        e.str("nephele manifest")
            .put(&self.frame)
            .put(&self.render_version)
            .str(&self.nephele);
        e.len(self.inputs.len());
        for (k, v) in &self.inputs {
            e.str(k).str(v);
        }
        e.len(self.files.len());
        for f in &self.files {
            e.str(&f.name).str(&f.kind).str(&f.hash).put(&f.bytes);
            // Manifests before content hashes had none; their check stays as it was written.
            if !f.blake3.is_empty() {
                e.str(&f.blake3);
            }
        }
        e.finish()
    }

    /// The manifest's text.
    pub fn to_text(&self) -> String {
        // A plain struct of strings and numbers always serializes.
        serde_json::to_string_pretty(self).unwrap_or_default() + "\n"
    }
}

/// Why a manifest cannot be used.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ManifestProblem {
    /// There is none.
    Missing,
    /// There is one, but it cannot be trusted; the reason says why.
    Unreadable(String),
    /// A manifest of a nephele before render versions.
    Old,
}

/// Read and check the manifest at `path`.
pub fn read_manifest(path: &Path) -> Result<Manifest, ManifestProblem> {
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(ManifestProblem::Missing),
        Err(e) => return Err(ManifestProblem::Unreadable(e.to_string())),
        Ok(m) if m.file_type().is_symlink() => {
            return Err(ManifestProblem::Unreadable(
                "it is a symbolic link (nephele never follows links out of the frames folder)"
                    .into(),
            ));
        }
        Ok(_) => {}
    }
    let text = match crate::input::read_to_string(path, crate::input::Limit::Own) {
        Ok(t) => t,
        Err(e) => return Err(ManifestProblem::Unreadable(e.to_string())),
    };
    if text.trim().is_empty() {
        return Err(ManifestProblem::Unreadable("empty file".into()));
    }
    let m: Manifest = match serde_json::from_str(&text) {
        Ok(m) => m,
        Err(e) => {
            // The manifests of nephele before render versions had `hash` and `version`.
            let old = serde_json::from_str::<serde_json::Value>(&text)
                .ok()
                .is_some_and(|v| v.get("version").is_some() && v.get("check").is_none());
            return Err(if old {
                ManifestProblem::Old
            } else {
                ManifestProblem::Unreadable(e.to_string())
            });
        }
    };
    if m.check != hash_text(m.check_hash()) {
        return Err(ManifestProblem::Unreadable(
            "its check hash does not match its contents (edited or damaged)".into(),
        ));
    }
    Ok(m)
}

/// A file the scene asks for, with the hash it must have.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WantedFile {
    /// What it is.
    pub kind: FileKind,
    /// Where it goes.
    pub path: PathBuf,
    /// Its hash.
    pub hash: u64,
}

/// What resume does with a frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameStatus {
    /// Every file present, listed and of the right hash: skip it.
    UpToDate,
    /// Never rendered (no files, no manifest).
    New,
    /// On disk but not up to date; the reason, for the run's summary.
    OutOfDate(String),
}

/// The check of one frame on disk against what the scene asks for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameCheck {
    /// Frame number.
    pub frame: u32,
    /// The verdict.
    pub status: FrameStatus,
    /// The files the scene asks for.
    pub wanted: Vec<WantedFile>,
    /// Which of `wanted` must be written (the others are on disk and up to date).
    pub write: Vec<bool>,
    /// For each of `wanted` that is up to date, its entry in the manifest (listed again as it
    /// is when the frame's manifest is rewritten).
    pub verified: Vec<Option<ListedFile>>,
    /// Files the manifest lists that this run does not ask for (another `--formats`, a format
    /// taken out of the scene, the blob dump): kept and listed again, unless `clean`.
    pub others: Vec<OtherFile>,
}

/// A file a frame's manifest lists that the run does not ask for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OtherFile {
    /// Its manifest entry (its name checked to be one nephele writes for the frame).
    pub listed: ListedFile,
    /// Where it is.
    pub path: PathBuf,
    /// True when its hash is the one the scene would give it now (made from the same inputs).
    pub current: bool,
    /// True when it is to be removed (`--clean`); otherwise it is kept and listed again.
    pub remove: bool,
}

impl FrameCheck {
    /// True when some file to write is made from the image (the frame must be rendered).
    pub fn needs_render(&self) -> bool {
        self.wanted
            .iter()
            .zip(&self.write)
            .any(|(w, &go)| go && w.kind.needs_image())
    }

    /// True when nothing needs doing at all, the manifest included.
    pub fn is_done(&self) -> bool {
        self.status == FrameStatus::UpToDate && !self.others.iter().any(|o| o.remove)
    }
}

/// The files frame number `frame` of `shot` needs, with their hashes from `inputs`.
pub fn wanted_files(shot: &Shot, frame: u32, inputs: &FrameInputs) -> Vec<WantedFile> {
    let stem = super::frame_files::frame_stem(shot, frame);
    let mut kinds: Vec<FileKind> = shot
        .scene()
        .file
        .output
        .formats
        .iter()
        .map(|&f| FileKind::Format(f))
        .collect();
    if shot.options().dump_blobs {
        kinds.push(FileKind::Blobs);
    }
    kinds
        .into_iter()
        .map(|kind| WantedFile {
            kind,
            path: shot.dir().join(file_name(&stem, kind)),
            hash: inputs.file_hash(kind),
        })
        .collect()
}

/// `<stem>.exr`, …, `<stem>.blobs.ron`.
pub fn file_name(stem: &str, kind: FileKind) -> String {
    match kind {
        FileKind::Format(f) => format!("{stem}.{}", f.extension()),
        FileKind::Blobs => format!("{stem}.blobs.ron"),
    }
}

/// Check frame number `frame` of `shot` on disk against `inputs` (see the module doc); with
/// `force` every wanted file is written; with `clean` the files the manifest lists that the run
/// does not ask for are to be removed.
pub fn check_frame(
    shot: &Shot,
    frame: u32,
    inputs: &FrameInputs,
    force: bool,
    clean: bool,
) -> FrameCheck {
    let wanted = wanted_files(shot, frame, inputs);
    let stem = super::frame_files::frame_stem(shot, frame);
    let manifest =
        read_manifest(&manifest_path(shot, frame)).and_then(|m| check_names(&m, &stem).map(|()| m));
    let present = wanted.iter().filter(|w| is_plain_file(&w.path)).count();
    let all = |status| FrameCheck {
        frame,
        status,
        write: vec![true; wanted.len()],
        verified: vec![None; wanted.len()],
        wanted: wanted.clone(),
        others: Vec::new(),
    };
    let m = match manifest {
        Ok(m) => m,
        Err(ManifestProblem::Missing) if present == 0 => return all(FrameStatus::New),
        Err(problem) => {
            let reason = match problem {
                ManifestProblem::Missing => "interrupted (files without their manifest)".into(),
                ManifestProblem::Old => {
                    "renderer changed (a manifest of nephele before render versions)".into()
                }
                ManifestProblem::Unreadable(e) => format!("manifest unreadable: {e}"),
            };
            return all(if force {
                FrameStatus::New
            } else {
                FrameStatus::OutOfDate(reason)
            });
        }
    };
    if m.frame != frame {
        return all(FrameStatus::OutOfDate(format!(
            "manifest unreadable: it is frame {}'s",
            m.frame
        )));
    }
    let dir = shot.dir();
    let others: Vec<OtherFile> = m
        .files
        .iter()
        .filter(|f| !wanted.iter().any(|w| file_name_of(&w.path) == f.name))
        .map(|f| OtherFile {
            listed: f.clone(),
            path: dir.join(&f.name),
            current: FileKind::from_key(&f.kind)
                .is_some_and(|k| f.hash == hash_text(inputs.file_hash(k))),
            remove: clean,
        })
        .collect();
    let mut write = Vec::with_capacity(wanted.len());
    let mut verified = Vec::with_capacity(wanted.len());
    let mut why = Reasons::default();
    for w in &wanted {
        let name = file_name_of(&w.path);
        let listed = m.files.iter().find(|f| f.name == name);
        let ok = match listed {
            None if is_plain_file(&w.path) => {
                why.interrupted = true;
                false
            }
            None => {
                why.added.push(w.kind.key());
                false
            }
            Some(f) if f.hash != hash_text(w.hash) => {
                let changed = changed_components(&m, inputs, w.kind);
                // None when the manifest's inputs are newer than the file (a file kept by a
                // run that did not write it, made from an earlier state of the scene).
                why.earlier |= changed.is_empty();
                why.changed.extend(changed);
                false
            }
            Some(f) => match verify_file(&w.path, w.kind, f) {
                Ok(()) => true,
                Err(FileProblem::Missing) => {
                    why.missing = true;
                    false
                }
                Err(FileProblem::Replaced) => {
                    why.replaced = true;
                    false
                }
                Err(FileProblem::Unhashed) => {
                    why.unhashed = true;
                    false
                }
            },
        };
        why.writes |= !ok;
        write.push(force || !ok);
        verified.push((ok && !force).then(|| listed.cloned()).flatten());
    }
    let status = if force {
        FrameStatus::New
    } else if m.render_version != RENDER_VERSION {
        FrameStatus::OutOfDate(format!(
            "renderer changed (render version {} → {RENDER_VERSION})",
            m.render_version
        ))
    } else {
        why.status()
    };
    // Another render version: every file is redone, whatever its hash says.
    let (write, verified) = if m.render_version != RENDER_VERSION {
        (vec![true; wanted.len()], vec![None; wanted.len()])
    } else {
        (write, verified)
    };
    FrameCheck {
        frame,
        status,
        wanted,
        write,
        verified,
        others,
    }
}

/// Why a frame on disk is not up to date, gathered file by file.
#[derive(Default)]
struct Reasons {
    changed: Vec<Component>,
    added: Vec<&'static str>,
    earlier: bool,
    interrupted: bool,
    missing: bool,
    replaced: bool,
    unhashed: bool,
    /// Some file is to be written (never called up to date then, whatever the reasons say).
    writes: bool,
}

impl Reasons {
    fn status(mut self) -> FrameStatus {
        let mut why = Vec::new();
        if !self.changed.is_empty() {
            self.changed.sort();
            self.changed.dedup();
            let labels: Vec<&str> = self.changed.iter().map(|c| c.label()).collect();
            why.push(format!("changed: {}", labels.join(", ")));
        }
        if self.earlier {
            why.push("files kept from an earlier state of the scene".into());
        }
        if !self.added.is_empty() {
            let f: Vec<String> = self.added.iter().map(|k| format!("+{k}")).collect();
            why.push(format!("formats added: {}", f.join(" ")));
        }
        if self.interrupted {
            why.push("interrupted (files without their manifest entry)".into());
        }
        if self.missing {
            why.push("files missing".into());
        }
        if self.replaced {
            why.push("files replaced since their manifest".into());
        }
        if self.unhashed {
            why.push("a manifest without content hashes (nephele before them)".into());
        }
        if why.is_empty() && !self.writes {
            FrameStatus::UpToDate
        } else if why.is_empty() {
            FrameStatus::OutOfDate("files out of date".into())
        } else {
            FrameStatus::OutOfDate(why.join("; "))
        }
    }
}

/// Every file a manifest lists must be one nephele writes for that frame (`<stem>.exr`, …,
/// `<stem>.blobs.ron`, by its kind), listed once: a name that is absolute, holds `..` or a
/// separator, or is any other file, makes the whole manifest untrusted, so nothing it lists is
/// ever removed or counted done.
fn check_names(m: &Manifest, stem: &str) -> Result<(), ManifestProblem> {
    for (i, f) in m.files.iter().enumerate() {
        let expected = FileKind::from_key(&f.kind).map(|k| file_name(stem, k));
        if expected.as_deref() != Some(f.name.as_str()) {
            return Err(ManifestProblem::Unreadable(format!(
                "it lists {:?} ({:?}), not a file nephele writes for this frame; nothing it \
                 lists is touched",
                f.name, f.kind
            )));
        }
        if m.files[..i].iter().any(|g| g.name == f.name) {
            return Err(ManifestProblem::Unreadable(format!(
                "it lists {:?} twice",
                f.name
            )));
        }
    }
    Ok(())
}

/// Why a listed file on disk is not the one its manifest describes.
enum FileProblem {
    Missing,
    Replaced,
    Unhashed,
}

/// Check the file at `path` against its manifest entry `f`: a regular file (not a link) of
/// the listed size, (EXR) carrying its hash in its header, whose bytes have the listed BLAKE3.
fn verify_file(path: &Path, kind: FileKind, f: &ListedFile) -> Result<(), FileProblem> {
    let meta = std::fs::symlink_metadata(path).map_err(|_| FileProblem::Missing)?;
    if !meta.is_file() || meta.len() != f.bytes {
        return Err(FileProblem::Replaced);
    }
    if kind == FileKind::Format(Format::Exr) && exr_hash(path).as_deref() != Some(f.hash.as_str()) {
        return Err(FileProblem::Replaced);
    }
    if f.blake3.is_empty() {
        return Err(FileProblem::Unhashed);
    }
    match content_hash(path) {
        Ok(h) if h == f.blake3 => Ok(()),
        _ => Err(FileProblem::Replaced),
    }
}

/// BLAKE3 of the bytes of the regular file at `path` (not followed if it is a link), as 64
/// lowercase hex digits.
pub fn content_hash(path: &Path) -> std::io::Result<String> {
    use std::os::unix::fs::OpenOptionsExt;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)?;
    if !file.metadata()?.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    let mut hasher = blake3::Hasher::new();
    hasher.update_reader(file)?;
    Ok(hasher.finalize().to_hex().to_string())
}

/// True when `path` is a regular file itself (a link is not).
fn is_plain_file(path: &Path) -> bool {
    std::fs::symlink_metadata(path).is_ok_and(|m| m.is_file())
}

/// The components whose hashes differ between manifest `m` and `inputs`, among those a file
/// of `kind` is made from.
fn changed_components(m: &Manifest, inputs: &FrameInputs, kind: FileKind) -> Vec<Component> {
    Component::of(kind)
        .iter()
        .copied()
        .filter(|&c| m.inputs.get(c.key()) != Some(&hash_text(inputs.hash(c))))
        .collect()
}

fn file_name_of(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// The `nephele/hash` string in the header of the EXR at `path`, if it has one.
pub fn exr_hash(path: &Path) -> Option<String> {
    let meta = exr::meta::MetaData::read_from_file(path, false).ok()?;
    let header = meta.headers.first()?;
    header
        .own_attributes
        .other
        .iter()
        .find(|(k, _)| k.to_string().as_str() == "nephele/hash")
        .and_then(|(_, v)| match v {
            exr::meta::attribute::AttributeValue::Text(t) => Some(t.to_string()),
            _ => None,
        })
}

/// The manifest of frame number `frame`: `<stem>.manifest.json` beside its files.
pub fn manifest_path(shot: &Shot, frame: u32) -> PathBuf {
    shot.dir().join(format!(
        "{}.manifest.json",
        super::frame_files::frame_stem(shot, frame)
    ))
}

/// A hash as written in headers and manifests: 16 lowercase hex digits.
pub fn hash_text(hash: u64) -> String {
    format!("{hash:016x}")
}
