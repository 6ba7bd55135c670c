//! Bounded input reads: every file nephele reads (scenes, meshes, models, codec inputs, its own
//! manifests and caches) is read only from a regular file and only up to a stated size, so a
//! device (`/dev/zero`), a FIFO or a runaway file gets a clear error instead of an unbounded
//! read or a read that blocks forever.
//!
//! The limits are part of the documented contract (README, "Limits"): [`Limit`].

use std::fs::File;
use std::io::{self, Read};
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// What a file is read as, with its size limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// A scene file (RON): 16 MiB.
    Scene,
    /// A triangle mesh (OBJ, PLY, STL): 2 GiB.
    Mesh,
    /// A fitted blob model (`.blobs.ron`, binary codecs): 256 MiB.
    Model,
    /// A layer of a USD stage (a shot's tracked camera, `.usda`/`.usdc`/`.usdz`): 256 MiB.
    Stage,
    /// Something nephele wrote itself and reads back (a manifest, a cache index): 16 MiB.
    Own,
    /// An image read as light (the sky's lat-long EXR): 1 GiB.
    Image,
}

impl Limit {
    /// The largest size read, in bytes.
    pub const fn bytes(self) -> u64 {
        match self {
            Limit::Scene | Limit::Own => 16 << 20,
            Limit::Mesh => 2 << 30,
            Limit::Model | Limit::Stage => 256 << 20,
            Limit::Image => 1 << 30,
        }
    }

    /// What the file is, for an error.
    pub const fn what(self) -> &'static str {
        match self {
            Limit::Scene => "a scene file",
            Limit::Mesh => "a mesh",
            Limit::Model => "a blob model",
            Limit::Stage => "a USD layer",
            Limit::Own => "a file nephele wrote",
            Limit::Image => "an environment map (EXR)",
        }
    }
}

/// Open `path` for reading as `limit` says: only a regular file (a FIFO is opened without
/// blocking and refused), of at most [`Limit::bytes`]. Returns the file and its size.
pub fn open(path: &Path, limit: Limit) -> io::Result<(File, u64)> {
    // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer forever. It
    // changes nothing for a regular file.
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        let kind = if meta.is_dir() {
            "a folder"
        } else {
            "not a regular file (a device, FIFO or socket)"
        };
        return Err(io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "is {kind}; nephele reads {} only from a regular file",
                limit.what()
            ),
        ));
    }
    let len = meta.len();
    if len > limit.bytes() {
        return Err(too_large(len, limit));
    }
    Ok((file, len))
}

/// Read all of `path` (see [`open`]); a file that grows past the limit while it is read is
/// refused too.
pub fn read(path: &Path, limit: Limit) -> io::Result<Vec<u8>> {
    let (file, len) = open(path, limit)?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(limit.bytes() + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit.bytes() {
        return Err(too_large(bytes.len() as u64, limit));
    }
    Ok(bytes)
}

/// [`read`] as UTF-8 text.
pub fn read_to_string(path: &Path, limit: Limit) -> io::Result<String> {
    String::from_utf8(read(path, limit)?).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!("is not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

fn too_large(len: u64, limit: Limit) -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidInput,
        format!(
            "is {len} bytes, more than the {} MiB nephele reads as {}",
            limit.bytes() >> 20,
            limit.what()
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_fifos_and_large_files_are_refused() {
        let e = read(Path::new("/dev/zero"), Limit::Scene).unwrap_err();
        assert!(e.to_string().contains("not a regular file"), "{e}");
        let dir = std::env::temp_dir().join(format!("nephele-input-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let big = dir.join("big.ron");
        let f = File::create(&big).unwrap();
        f.set_len(Limit::Scene.bytes() + 1).unwrap();
        let e = read(&big, Limit::Scene).unwrap_err();
        assert!(e.to_string().contains("more than the 16 MiB"), "{e}");
        std::fs::write(&big, b"(a: 1)").unwrap();
        assert_eq!(read_to_string(&big, Limit::Scene).unwrap(), "(a: 1)");
        let e = read(&dir, Limit::Scene).unwrap_err();
        assert!(e.to_string().contains("a folder"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
