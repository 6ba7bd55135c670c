//! Temporary folders for the tests that write files: each is removed with everything in it when
//! the test ends, also when it fails, so test runs leave nothing in the system's temporary
//! folder.

use std::path::PathBuf;

/// A fresh temporary folder, removed on drop; derefs to its path.
pub struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = PathBuf;
    fn deref(&self) -> &PathBuf {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// An empty folder `nephele-<what>-<pid>` in the system's temporary folder (emptied first if a
/// crashed run left it).
pub fn temp_dir(what: &str) -> TempDir {
    let d = std::env::temp_dir().join(format!("nephele-{what}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    TempDir(d)
}
