//! Atomic file output: write a temporary file beside the target, then rename it into place,
//! so an interrupted run never leaves a truncated file that looks finished.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::os::unix::fs::OpenOptionsExt;
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
    // Created as every temporary is (new, never through a link, locked while it exists), so
    // a probe left by a killed process is removed like the others.
    let probe = existing.join(format!(".nephele-probe.{}.tmp", process_token()));
    let file = create_temp(&probe)?;
    let removed = std::fs::remove_file(&probe);
    drop(file);
    removed
}

/// An output folder files cannot be written in: `output folder DIR is not writable`, its
/// source the reason ([`check_output_dir`]).
#[derive(Debug, thiserror::Error)]
#[error("output folder {} is not writable", dir.display())]
pub struct NotWritable {
    /// The folder.
    pub dir: PathBuf,
    /// Why ([`check_writable`]'s error).
    #[source]
    pub source: io::Error,
}

/// [`check_writable`] for a shot's output folder, before any frame is rendered: what
/// `nephele render`, `prepare` and `farm` and the Python binding's `render_all` check.
pub fn check_output_dir(dir: &Path) -> Result<(), NotWritable> {
    check_writable(dir).map_err(|source| NotWritable {
        dir: dir.to_path_buf(),
        source,
    })
}

/// Write `target` through `body` atomically. Parent folders are created. On any error the
/// temporary file is removed and `target` is left as it was.
pub fn write_atomically(
    target: &Path,
    body: impl FnOnce(&mut BufWriter<&File>) -> io::Result<()>,
) -> io::Result<()> {
    if let Some(parent) = target.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)?;
    }
    let tmp = temp_path(target);
    let file = create_temp(&tmp)?;
    let result = (|| {
        let mut w = BufWriter::new(&file);
        body(&mut w)?;
        w.flush()?;
        drop(w);
        file.sync_all()?;
        if let Some(name) = target.file_name() {
            crate::test_hook::stop_at(&format!("before-rename:{}", name.to_string_lossy()));
        }
        // rename replaces a link at `target` itself, never the file it points to.
        std::fs::rename(&tmp, target)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    // The temporary's lock is released only now, after the rename (see `create_temp`).
    drop(file);
    result
}

/// Create the temporary file `tmp`: a new file (never one already there, nor through a
/// symbolic link planted at its name), locked (`flock`) for as long as it is being written, so
/// that [`remove_dead_temp`] can tell a temporary whose writer died from one being written.
fn create_temp(tmp: &Path) -> io::Result<File> {
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .custom_flags(libc::O_NOFOLLOW)
        .open(tmp)?;
    if let Err(e) = file.try_lock() {
        let _ = std::fs::remove_file(tmp);
        return Err(match e {
            std::fs::TryLockError::Error(e) => e,
            std::fs::TryLockError::WouldBlock => io::Error::other("a new temporary file is locked"),
        });
    }
    Ok(file)
}

/// True when `name` is a temporary file name of [`temp_path`] (`.<name>.<pid>-<nanos>.tmp`);
/// returns the name of the file it was to become.
pub fn temp_target(name: &str) -> Option<&str> {
    let rest = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (target, token) = rest.rsplit_once('.')?;
    let (pid, nanos) = token.split_once('-')?;
    let digits = |s: &str| !s.is_empty() && s.chars().all(|c| c.is_ascii_digit());
    (digits(pid) && digits(nanos) && !target.is_empty()).then_some(target)
}

/// Remove the temporary file `path` if no process is writing it (its writer was killed: the
/// lock [`write_atomically`] holds while writing is free). Links and other non-files are left
/// alone. True when it was removed.
pub fn remove_dead_temp(path: &Path) -> bool {
    let Ok(file) = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
        .open(path)
    else {
        return false;
    };
    if !file.metadata().is_ok_and(|m| m.is_file()) || file.try_lock().is_err() {
        return false;
    }
    std::fs::remove_file(path).is_ok()
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
