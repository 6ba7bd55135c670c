//! A hook for the tests that kill a render at a chosen point: with `NEPHELE_TEST_HOOK=POINT`
//! set, the process that reaches `POINT` says so on stderr (`nephele test hook: stopped at
//! POINT`) and waits there until it is killed. Points: `after-files:<frame>` (every file of the
//! frame renamed into place, its manifest not yet written) and `before-rename:<file name>` (the
//! file's temporary written, not yet renamed). Without the variable nothing happens.

use std::sync::OnceLock;

/// The environment variable naming the point.
pub const VAR: &str = "NEPHELE_TEST_HOOK";

/// Stop here forever if [`VAR`] names `point`.
pub fn stop_at(point: &str) {
    static WANTED: OnceLock<Option<String>> = OnceLock::new();
    let wanted = WANTED.get_or_init(|| std::env::var(VAR).ok().filter(|v| !v.is_empty()));
    if wanted.as_deref() == Some(point) {
        eprintln!("nephele test hook: stopped at {point}");
        loop {
            std::thread::sleep(std::time::Duration::from_secs(1));
        }
    }
}
