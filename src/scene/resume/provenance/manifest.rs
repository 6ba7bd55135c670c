//! A frame's manifest: its files with their hashes, sizes and content hashes, and a check hash
//! over all of it; read back only when it is intact and names only the frame's own files.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::render::RENDER_VERSION;
use crate::scene::resume::canonical::Encoder;
use crate::scene::resume::frame_names::{FileKind, file_name};

/// A file as a manifest lists it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ListedFile {
    /// File name, in the manifest's folder.
    pub name: String,
    /// What it is (`exr`, `png`, `vdb`, `vol`, `blobs`).
    pub kind: String,
    /// Its hash ([`super::FrameInputs::file_hash`], 16 hex digits).
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
    /// The inputs' hash per component, by [`super::Component::key`].
    pub inputs: BTreeMap<String, String>,
    /// The frame's files.
    pub files: Vec<ListedFile>,
    /// Hash of everything above ([`Manifest::check_hash`]): a manifest whose check fails was
    /// edited or damaged and is not trusted.
    pub check: String,
}

impl Manifest {
    /// A manifest of frame number `frame` with these inputs and files, its check hash set.
    /// `inputs` are the frame's inputs as listed ([`super::FrameInputs::listed`]).
    pub fn new(frame: u32, inputs: BTreeMap<String, String>, files: Vec<ListedFile>) -> Manifest {
        let mut m = Manifest {
            frame,
            render_version: RENDER_VERSION,
            nephele: env!("CARGO_PKG_VERSION").to_string(),
            inputs,
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

/// Every file a manifest lists must be one nephele writes for that frame (`<stem>.exr`, …,
/// `<stem>.blobs.ron`, by its kind), listed once: a name that is absolute, holds `..` or a
/// separator, or is any other file, makes the whole manifest untrusted, so nothing it lists is
/// ever removed or counted done.
pub(super) fn check_names(m: &Manifest, stem: &str) -> Result<(), ManifestProblem> {
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

/// A hash as written in headers and manifests: 16 lowercase hex digits.
pub fn hash_text(hash: u64) -> String {
    format!("{hash:016x}")
}
