//! The readers we did not write, which some checks run on nephele's files: OpenVDB's python
//! module (`export`), Pixar's usd-core (`export`), OpenImageIO's `oiiotool` (`frames`) and
//! Mitsuba 3 (`mitsuba`). Where one is missing its check skips, said plainly — unless
//! `NEPHELE_REQUIRE_READERS=1` (as `.ci/run` sets), where the check fails instead: a run cannot
//! pass with none of them there.

/// The environment variable that turns a missing reader into a failure (when it is `1`).
pub const REQUIRE: &str = "NEPHELE_REQUIRE_READERS";

/// Whether `NEPHELE_REQUIRE_READERS=1`.
pub fn required() -> bool {
    std::env::var(REQUIRE).is_ok_and(|v| v == "1")
}

/// The check with `reader` cannot run because of `why`: prints `skipped: …` (the caller then
/// returns), or panics with `why` when `NEPHELE_REQUIRE_READERS=1`.
#[track_caller]
pub fn skip_or_fail(reader: &str, why: &str) {
    if required() {
        panic!("{reader} is required ({REQUIRE}=1) but missing: {why}");
    }
    eprintln!("skipped: the {reader} check: {why} ({REQUIRE}=1 makes this a failure)");
}
