//! Atomic file output: write a temporary file beside the target, then rename it into place,
//! so an interrupted run never leaves a truncated file that looks finished.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

/// The temporary path used while writing `target`: hidden, same folder, ends in `.tmp`, and
/// unique to this process ([`process_token`]), so that processes writing the same file at once
/// (farm tasks refitting a missing target cache) never share a temporary file.
pub fn temp_path(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".into());
    target.with_file_name(format!(".{name}.{}.tmp", process_token()))
}

/// This process's id and its start time in nanoseconds (`1234-5678`), fixed for the process's
/// life. The process id alone collides across the machines of a farm sharing one folder, and in
/// containers (where every task may be process 1).
pub fn process_token() -> &'static str {
    static TOKEN: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TOKEN.get_or_init(|| {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() % 1_000_000_000_000)
            .unwrap_or(0);
        format!("{}-{nanos}", std::process::id())
    })
}

/// Check, without leaving anything behind, that files can be written in `dir` (which need not
/// exist yet): its nearest existing ancestor must be a folder in which a file can be created.
pub fn check_writable(dir: &Path) -> io::Result<()> {
    let mut existing = dir;
    while !existing.exists() {
        match existing.parent() {
            Some(p) if !p.as_os_str().is_empty() => existing = p,
            _ => {
                existing = Path::new(".");
                break;
            }
        }
    }
    if !existing.is_dir() {
        return Err(io::Error::other(format!(
            "{} is not a folder",
            existing.display()
        )));
    }
    let probe = existing.join(format!(".nephele-probe.{}.tmp", process_token()));
    File::create(&probe)?;
    std::fs::remove_file(&probe)
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
        if let Some(name) = target.file_name() {
            crate::test_hook::stop_at(&format!("before-rename:{}", name.to_string_lossy()));
        }
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

    #[test]
    fn writable_check_creates_nothing() {
        let dir = std::env::temp_dir().join(format!("nephele-writable-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        check_writable(&dir.join("a/b")).unwrap();
        assert!(!dir.join("a").exists());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
        // A folder below a file can never be created (even by root).
        std::fs::write(dir.join("file"), b"x").unwrap();
        assert!(check_writable(&dir.join("file/out")).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
