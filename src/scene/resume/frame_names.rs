//! The names of a frame's files in the output folder: `<name>_0001.exr`, …, its manifest
//! `<name>_0001.manifest.json` and its lock `.<name>_0001.lock` — the only names nephele
//! writes, removes or locks for a frame.

use std::path::PathBuf;

use crate::scene::Format;
use crate::scene::Shot;

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

    /// The kind whose [`FileKind::key`] is `key` (as a manifest lists it).
    pub fn from_key(key: &str) -> Option<FileKind> {
        if key == "blobs" {
            return Some(FileKind::Blobs);
        }
        Format::ALL
            .into_iter()
            .find(|f| f.extension() == key)
            .map(FileKind::Format)
    }
}

/// The files of frame number `frame`: one per format, plus the blob dump if asked.
pub fn frame_paths(shot: &Shot, frame: u32) -> Vec<std::path::PathBuf> {
    let stem = frame_stem(shot, frame);
    let formats = shot.scene().file.output.formats.iter();
    let dump = shot.options().dump_blobs.then_some(FileKind::Blobs);
    formats
        .map(|&f| FileKind::Format(f))
        .chain(dump)
        .map(|kind| shot.dir().join(file_name(&stem, kind)))
        .collect()
}

/// `<name>_0001`: the file name of frame number `frame` without its extension, the number
/// zero-padded to `output.padding` digits; a look test's region render is `<name>_0001.region`,
/// so it never replaces (or is taken for) the frame itself.
pub fn frame_stem(shot: &Shot, frame: u32) -> String {
    let scene = shot.scene();
    let digits = scene.file.output.padding as usize;
    let region = if shot.region().is_some() {
        ".region"
    } else {
        ""
    };
    format!("{}_{frame:0digits$}{region}", scene.name)
}

/// `<stem>.exr`, …, `<stem>.blobs.ron`.
pub fn file_name(stem: &str, kind: FileKind) -> String {
    match kind {
        FileKind::Format(f) => format!("{stem}.{}", f.extension()),
        FileKind::Blobs => format!("{stem}.blobs.ron"),
    }
}

/// The manifest of frame number `frame`: `<stem>.manifest.json` beside its files.
pub fn manifest_path(shot: &Shot, frame: u32) -> PathBuf {
    shot.dir()
        .join(format!("{}.manifest.json", frame_stem(shot, frame)))
}
