//! Atomic file output: write a temporary file beside the target, then rename it into place,
//! so an interrupted run never leaves a truncated file that looks finished.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// The temporary path used while writing `target`: hidden, same folder, ends in `.tmp`.
pub fn temp_path(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    target.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
}

/// Write `target` through `body` atomically. Parent folders are created. On any error the
/// temporary file is removed and `target` is left as it was.
pub fn write_atomically(
    target: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> io::Result<()>,
) -> io::Result<()> {
    if let Some(parent) = target.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    let tmp = temp_path(target);
    let result = (|| {
        let mut w = BufWriter::new(File::create(&tmp)?);
        body(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        drop(file);
        std::fs::rename(&tmp, target)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// [`write_atomically`] for a byte buffer already in memory.
pub fn write_bytes_atomically(target: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomically(target, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("nephele-atomic-{}", std::process::id()));
        let target = dir.join("a.bin");
        let err = write_atomically(&target, |w| {
            w.write_all(b"partial")?;
            Err(io::Error::other("interrupted"))
        });
        assert!(err.is_err());
        assert!(!target.exists());
        assert!(!temp_path(&target).exists());
        write_bytes_atomically(&target, b"done").unwrap();
        assert_eq!(std::fs::read(&target).unwrap(), b"done");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
