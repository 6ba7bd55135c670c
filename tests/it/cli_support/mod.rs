//! Running the `nephele` binary from integration tests.

use std::path::Path;
use std::process::{Command, Output};

/// nephele run in `dir`, with no job-array index variable inherited from the environment (a
/// test run inside a farm job must not pick up its task).
pub fn nephele_in(dir: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_nephele"));
    c.current_dir(dir);
    for v in nephele::scene::chunk::ARRAY_INDEX_VARS {
        c.env_remove(v);
    }
    c
}

/// A finished process's stdout then stderr, as text.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// `o`'s text, after asserting that it succeeded.
pub fn succeeded(o: Output) -> String {
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    t
}

/// Run `c`, assert it succeeded, return its output text.
#[allow(dead_code)] // not every test binary runs commands this way
pub fn run(c: &mut Command) -> String {
    succeeded(c.output().unwrap())
}
