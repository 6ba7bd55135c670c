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
//! A frame whose lock can be taken has no writer: any temporary file of it left in the folder
//! (`.<stem>.exr.<pid>-<n>.tmp`) belongs to a process that died, and [`remove_stale_temps`]
//! deletes it.

use std::fs::{File, OpenOptions};
use std::io::{Read, Write};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

use super::SceneError;

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
        let io = |source| SceneError::Io {
            path: path.clone(),
            source,
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
            let mut file = OpenOptions::new()
                .read(true)
                .write(true)
                .create(true)
                .truncate(false)
                .open(path)
                .map_err(Refused::Io)?;
            match file.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => {
                    let mut holder = String::new();
                    let _ = file.read_to_string(&mut holder);
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
            let same = match (file.metadata(), std::fs::metadata(path)) {
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

/// The frame stem of a temporary file name `.<stem>.<ext>.<token>.tmp` of a frame of shot
/// `name` (`<stem>` = `<name>_<digits>` or `<name>_<digits>.region`), if it is one.
pub fn temp_stem<'a>(file_name: &'a str, name: &str) -> Option<&'a str> {
    let rest = file_name.strip_prefix('.')?.strip_suffix(".tmp")?;
    // Strip the token (`<pid>-<nanos>`).
    let (body, token) = rest.rsplit_once('.')?;
    if token.is_empty() || !token.chars().all(|c| c.is_ascii_digit() || c == '-') {
        return None;
    }
    let ext = FRAME_FILES
        .iter()
        .find(|e| body.ends_with(&format!(".{e}")))?;
    let stem = &body[..body.len() - ext.len() - 1];
    let number = stem.strip_prefix(name)?.strip_prefix('_')?;
    let digits = number.strip_suffix(".region").unwrap_or(number);
    (!digits.is_empty() && digits.chars().all(|c| c.is_ascii_digit())).then_some(stem)
}

/// Remove the temporary files of shot `name`'s frames in `dir` whose frame no process holds
/// (left by a process that was killed); returns how many were removed. Frames locked by a
/// running render keep theirs.
pub fn remove_stale_temps(dir: &Path, name: &str, scene: &Path) -> Result<usize, SceneError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(source) => {
            return Err(SceneError::Io {
                path: dir.to_path_buf(),
                source,
            });
        }
    };
    let mut temps: Vec<(String, PathBuf)> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let file = e.file_name().to_string_lossy().into_owned();
            temp_stem(&file, name).map(|s| (s.to_string(), e.path()))
        })
        .collect();
    temps.sort();
    let mut removed = 0;
    let mut i = 0;
    while i < temps.len() {
        let stem = temps[i].0.clone();
        let group = temps[i..].iter().take_while(|(s, _)| *s == stem).count();
        if let Ok(Some(_lock)) = FrameLock::try_acquire(&lock_path(dir, &stem), scene) {
            for (_, path) in &temps[i..i + group] {
                if std::fs::remove_file(path).is_ok() {
                    removed += 1;
                }
            }
        }
        i += group;
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temp_names_are_recognised_by_frame() {
        assert_eq!(
            temp_stem(".duck_0002.vdb.1234-5678.tmp", "duck"),
            Some("duck_0002")
        );
        assert_eq!(
            temp_stem(".duck_0002.region.exr.1-2.tmp", "duck"),
            Some("duck_0002.region")
        );
        assert_eq!(
            temp_stem(".duck_0002.manifest.json.1-2.tmp", "duck"),
            Some("duck_0002")
        );
        // Another shot's, the fit cache's, or not a temporary at all.
        assert_eq!(temp_stem(".goose_0002.exr.1-2.tmp", "duck"), None);
        assert_eq!(temp_stem(".duck.fit.ron.1-2.tmp", "duck"), None);
        assert_eq!(temp_stem("duck_0002.exr", "duck"), None);
        assert_eq!(temp_stem(".duck_0002.exr.x.tmp", "duck"), None);
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
        // A stale temporary of an unlocked frame goes; one of a locked frame stays.
        std::fs::write(dir.join(".s_0002.png.99-1.tmp"), b"x").unwrap();
        std::fs::write(dir.join(".s_0001.png.99-1.tmp"), b"x").unwrap();
        assert_eq!(remove_stale_temps(&dir, "s", scene).unwrap(), 1);
        assert!(dir.join(".s_0001.png.99-1.tmp").exists());
        assert!(!dir.join(".s_0002.png.99-1.tmp").exists());
        drop(again);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
