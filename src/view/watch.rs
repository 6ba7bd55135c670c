//! Watching the scene file and the files it reads: a save re-renders.
//!
//! The files' stamps (modification time, length, inode) are polled every [`POLL`]: a handful
//! of files cost nothing to stat, and polling sees what inotify misses — a save that renames a
//! temporary over the file (the watched inode is gone), files on network file systems (a
//! studio's NFS, where inotify hears only local writes) — with no dependency. A change is
//! debounced: the scene is loaded once the stamps have held still for [`SETTLE`] (editors write
//! a file in several steps, and a partial file would show a false error).

use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use super::session::Session;

/// How often the files are looked at.
pub const POLL: Duration = Duration::from_millis(25);

/// How long the files must hold still after a change before the scene is loaded.
pub const SETTLE: Duration = Duration::from_millis(50);

/// What a file looks like from outside: `None` when it does not exist.
type Stamp = Option<(SystemTime, u64, u64)>;

fn stamp(path: &PathBuf) -> Stamp {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(path).ok()?;
    Some((m.modified().ok()?, m.len(), m.ino()))
}

fn stamps(paths: &[PathBuf]) -> Vec<Stamp> {
    paths.iter().map(stamp).collect()
}

/// Load the scene now, then again after every settled change of its files, on a thread of its
/// own (for the session's life).
pub fn spawn(session: Arc<Session>) {
    std::thread::spawn(move || {
        loop {
            let before = session.watched();
            let seen: std::collections::HashMap<PathBuf, Stamp> =
                before.iter().cloned().zip(stamps(&before)).collect();
            session.reload();
            // A file changed while the scene loaded is a change after the load: its stamp
            // from before is kept.
            let mut paths = session.watched();
            let mut last: Vec<Stamp> = paths
                .iter()
                .map(|p| seen.get(p).copied().unwrap_or_else(|| stamp(p)))
                .collect();
            // Wait for a change…
            loop {
                std::thread::sleep(POLL);
                let fresh = session.watched();
                if fresh != paths {
                    paths = fresh;
                    last = stamps(&paths);
                    continue;
                }
                let now = stamps(&paths);
                if now != last {
                    last = now;
                    break;
                }
            }
            // …and for the files to hold still.
            let mut still = Duration::ZERO;
            while still < SETTLE {
                std::thread::sleep(POLL);
                let now = stamps(&paths);
                if now == last {
                    still += POLL;
                } else {
                    last = now;
                    still = Duration::ZERO;
                }
            }
        }
    });
}
