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

mod inputs;
mod manifest;

use std::path::{Path, PathBuf};

pub use self::inputs::{Component, FrameInputs, frame_inputs, header_strings};
pub use self::manifest::{ListedFile, Manifest, ManifestProblem, hash_text, read_manifest};
pub use super::frame_names::{FileKind, file_name, manifest_path};
pub use crate::render::RENDER_VERSION;

use self::manifest::check_names;
use crate::scene::{Format, Shot};

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
    let stem = super::frame_names::frame_stem(shot, frame);
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

/// Check frame number `frame` of `shot` on disk against `inputs` (see the module doc); with
/// `on_disk` its manifest as read ([`frame_manifest`]); with `force` every wanted file is
/// written; with `clean` the files the manifest lists that the run
/// does not ask for are to be removed.
pub fn check_frame(
    shot: &Shot,
    frame: u32,
    inputs: &FrameInputs,
    on_disk: Result<Manifest, ManifestProblem>,
    force: bool,
    clean: bool,
) -> FrameCheck {
    let wanted = wanted_files(shot, frame, inputs);
    let stem = super::frame_names::frame_stem(shot, frame);
    let manifest = on_disk.and_then(|m| check_names(&m, &stem).map(|()| m));
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

/// The manifest of frame number `frame` of `shot` as it is on disk (read once a frame, for
/// [`frame_inputs`] and [`check_frame`]).
pub fn frame_manifest(shot: &Shot, frame: u32) -> Result<Manifest, ManifestProblem> {
    read_manifest(&manifest_path(shot, frame))
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
