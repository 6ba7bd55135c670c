//! One writer per frame: an advisory lock (`flock`) on `.<stem>.lock` in the frames folder,
//! held from the frame's check until its manifest is written, so two renders (two scenes with
//! the same `output.name`, or a requeued farm task beside its old self) never interleave one
//! frame's files. The lock is per frame, not per shot, because a farm's tasks render disjoint
//! frames of one shot into one folder at the same time.
//!
//! The holder writes who it is into the lock file (process id, host, scene), so the render that
//! finds the frame locked can say which process has it. The file is removed on release; a
//! process that locked a file just removed finds its path gone (or another file there) and
//! locks again, so a removed lock file is never held.
//!
//! The lock file is opened without following links (`O_NOFOLLOW`): a link planted at its name
//! is refused, never written through.
//!
//! Temporary files (`.<file>.<pid>-<n>.tmp`, [`crate::atomic`]) are locked by their writer
//! while written, so a temporary whose lock can be taken belongs to a process that died, and
//! [`remove_stale_temps`] deletes it: the frames', the statistics' and the shared caches'.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::{MetadataExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

use crate::file_error::FileError;
use crate::scene::SceneError;

/// The extensions a frame's temporary files have before `.<token>.tmp`.
const FRAME_FILES: [&str; 6] = ["exr", "png", "vdb", "vol", "blobs.ron", "manifest.json"];

/// A held frame lock; released (and its file removed) on drop.
#[derive(Debug)]
pub struct FrameLock {
    file: File,
    path: PathBuf,
}

/// Why a lock could not be taken.
enum Refused {
    Held(String),
    Io(std::io::Error),
}

impl FrameLock {
    /// Lock frame `stem` in `dir` (created if missing) for `scene`; an error names the process
    /// holding it.
    pub fn acquire(dir: &Path, stem: &str, scene: &Path) -> Result<FrameLock, SceneError> {
        let path = lock_path(dir, stem);
        let io = |source| {
            SceneError::File(FileError::Io {
                path: path.clone(),
                source,
            })
        };
        std::fs::create_dir_all(dir).map_err(io)?;
        match FrameLock::try_acquire(&path, scene) {
            Ok(Some(lock)) => Ok(lock),
            Ok(None) => unreachable!("try_acquire retries until it holds a lock or is refused"),
            Err(Refused::Io(e)) => Err(io(e)),
            Err(Refused::Held(holder)) => Err(SceneError::Locked { path, holder }),
        }
    }

    /// Lock `path` without waiting.
    fn try_acquire(path: &Path, scene: &Path) -> Result<Option<FrameLock>, Refused> {
        for _ in 0..100 {
            // Never through a link: a link planted at the lock's name would have the holder's
            // line written into the file it points to.
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .custom_flags(libc::O_NOFOLLOW | libc::O_NONBLOCK)
                .open(path)
                .map_err(|e| Refused::Io(not_followed(e)))?;
            if !file.metadata().map_err(Refused::Io)?.is_file() {
                return Err(Refused::Io(std::io::Error::other(
                    "is not a regular file; remove it (nephele writes its frame locks there)",
                )));
            }
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    let mut holder = String::new();
                    // One line is all a holder writes; never more than that is read.
                    let _ = (&file).take(4096).read_to_string(&mut holder);
                    let holder = holder.trim();
                    return Err(Refused::Held(if holder.is_empty() {
                        "a process that has not yet said who it is".into()
                    } else {
                        holder.to_string()
                    }));
                }
                Err(std::fs::TryLockError::Error(e)) => return Err(Refused::Io(e)),
            }
            // The file may have been removed (released) between our open and our lock.
            let same = match (file.metadata(), std::fs::symlink_metadata(path)) {
                (Ok(a), Ok(b)) => a.ino() == b.ino() && a.dev() == b.dev(),
                _ => false,
            };
            if !same {
                continue;
            }
            file.set_len(0).map_err(Refused::Io)?;
            let who = format!(
                "nephele process {} on {}, rendering {}",
                std::process::id(),
                host_name(),
                scene.display()
            );
            file.write_all(who.as_bytes()).map_err(Refused::Io)?;
            return Ok(Some(FrameLock {
                file,
                path: path.to_path_buf(),
            }));
        }
        Err(Refused::Io(std::io::Error::other(
            "the lock file kept being replaced while locking it",
        )))
    }
}

impl Drop for FrameLock {
    fn drop(&mut self) {
        // Removed while still locked: see the module doc.
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}

/// The error of opening a link with `O_NOFOLLOW` (`ELOOP`), said plainly.
fn not_followed(e: std::io::Error) -> std::io::Error {
    if e.raw_os_error() == Some(libc::ELOOP) {
        std::io::Error::other(
            "is a symbolic link; nephele does not follow links out of the frames folder \
             (remove it)",
        )
    } else {
        e
    }
}

/// `.<stem>.lock` in `dir`.
pub fn lock_path(dir: &Path, stem: &str) -> PathBuf {
    dir.join(format!(".{stem}.lock"))
}

/// This machine's name (`/proc/sys/kernel/hostname`, else `$HOSTNAME`, else `this host`).
fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "this host".into())
}

/// True when `target` (the file a temporary was to become, [`crate::atomic::temp_target`]) is
/// one of the files nephele writes for shot `name`: a frame file or manifest
/// (`<name>_<digits>[.region].<ext>`), its statistics (`<name>_stats.csv`), its job files and
/// USD stage, a cache shared by the shots of the folder (`target-<hash>.ron`,
/// `blend-<key>.ron`), or the writability probe (`nephele-probe`).
pub fn is_shot_file(target: &str, name: &str) -> bool {
    // The shot's own files beside its frames: statistics, job files, the USD stage; and the
    // writability probe every run makes.
    let own = [
        format!("{name}_stats.csv"),
        format!("{name}.sbatch"),
        format!("{name}.prepare.sbatch"),
        format!("{name}.k8s.yaml"),
        format!("{name}.prepare.k8s.yaml"),
        format!("{name}.usda"),
        "nephele-probe".to_string(),
    ];
    if own.iter().any(|f| f == target) {
        return true;
    }
    let hex = |s: &str| !s.is_empty() && s.chars().all(|c| c.is_ascii_hexdigit());
    for prefix in ["target-", "blend-"] {
        if let Some(key) = target
            .strip_prefix(prefix)
            .and_then(|t| t.strip_suffix(".ron"))
            && hex(key)
        {
            return true;
        }
    }
    let Some(ext) = FRAME_FILES
        .iter()
        .find(|e| target.ends_with(&format!(".{e}")))
    else {
        return false;
    };
    let stem = &target[..target.len() - ext.len() - 1];
    let Some(number) = stem.strip_prefix(name).and_then(|s| s.strip_prefix('_')) else {
        return false;
    };
    let digits = number.strip_suffix(".region").unwrap_or(number);
    !digits.is_empty() && digits.chars().all(|c| c.is_ascii_digit())
}

/// Remove the temporary files of shot `name` in `dirs` (its frames folder and its cache
/// folder) whose writer was killed ([`crate::atomic::remove_dead_temp`]: a temporary being
/// written is locked by its writer); returns how many were removed.
pub fn remove_stale_temps(dirs: &[&Path], name: &str) -> Result<usize, SceneError> {
    let mut removed = 0;
    for dir in dirs {
        let entries = match std::fs::read_dir(dir) {
            Ok(e) => e,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(source) => {
                return Err(SceneError::File(FileError::Io {
                    path: dir.to_path_buf(),
                    source,
                }));
            }
        };
        for entry in entries.filter_map(|e| e.ok()) {
            let file = entry.file_name().to_string_lossy().into_owned();
            let ours = crate::atomic::temp_target(&file).is_some_and(|t| is_shot_file(t, name));
            if ours && crate::atomic::remove_dead_temp(&entry.path()) {
                removed += 1;
            }
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_names_are_recognised_by_shot() {
        let ours = |f: &str| crate::atomic::temp_target(f).is_some_and(|t| is_shot_file(t, "duck"));
        for f in [
            ".duck_0002.vdb.1234-5678.tmp",
            ".duck_0002.region.exr.1-2.tmp",
            ".duck_0002.manifest.json.1-2.tmp",
            ".duck_stats.csv.1-2.tmp",
            ".target-00ff12.ron.1-2.tmp",
            ".blend-00ff12.ron.1-2.tmp",
            ".duck.sbatch.1-2.tmp",
            ".duck.usda.1-2.tmp",
            ".nephele-probe.1-2.tmp",
        ] {
            assert!(ours(f), "{f}");
        }
        // Another shot's, not a temporary at all, or not nephele's token.
        for f in [
            ".goose_0002.exr.1-2.tmp",
            ".duck.fit.ron.1-2.tmp",
            "duck_0002.exr",
            ".duck_0002.exr.x.tmp",
            ".duck_0002.exr.1.tmp",
            ".target-zz.ron.1-2.tmp",
        ] {
            assert!(!ours(f), "{f}");
        }
    }

    #[test]
    fn a_held_lock_is_refused_with_its_holder_and_released_on_drop() {
        let dir = std::env::temp_dir().join(format!("nephele-lock-{}", std::process::id()));
        let scene = Path::new("a.ron");
        let held = FrameLock::acquire(&dir, "s_0001", scene).unwrap();
        // flock locks belong to the open file, so a second open in this process is refused too.
        let e = FrameLock::acquire(&dir, "s_0001", scene).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains(&format!("process {}", std::process::id())),
            "{text}"
        );
        assert!(text.contains("a.ron"), "{text}");
        drop(held);
        assert!(!lock_path(&dir, "s_0001").exists());
        let again = FrameLock::acquire(&dir, "s_0001", scene).unwrap();
        // A temporary whose writer died goes; one being written (locked by its writer) stays.
        std::fs::write(dir.join(".s_0002.png.99-1.tmp"), b"x").unwrap();
        let live = dir.join(".s_0001.png.99-1.tmp");
        let writer = File::create(&live).unwrap();
        writer.lock().unwrap();
        assert_eq!(remove_stale_temps(&[&dir], "s").unwrap(), 1);
        assert!(live.exists());
        assert!(!dir.join(".s_0002.png.99-1.tmp").exists());
        drop(writer);
        assert_eq!(remove_stale_temps(&[&dir], "s").unwrap(), 1);
        assert!(!live.exists());
        drop(again);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
