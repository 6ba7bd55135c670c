//! Progress reporting with indicatif: one bar per long stage, drawn on stderr only when it is a
//! terminal (so logs and tests stay clean).

use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

/// A bar of `len` steps labelled `stage`.
pub fn bar(stage: &str, len: u64) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(
        ProgressStyle::with_template(
            "{prefix:>12.bold} [{bar:30}] {pos}/{len} {elapsed_precise} eta {eta}",
        )
        .expect("valid template")
        .progress_chars("=> "),
    );
    pb.set_prefix(stage.to_string());
    pb
}

/// A spinner for a stage without a known length.
pub fn spinner(stage: &str) -> ProgressBar {
    let pb = ProgressBar::new_spinner();
    pb.set_style(
        ProgressStyle::with_template("{prefix:>12.bold} {spinner} {elapsed_precise}")
            .expect("valid template"),
    );
    pb.set_prefix(stage.to_string());
    pb.enable_steady_tick(Duration::from_millis(120));
    pb
}

/// Wall-clock time of each named stage, in order.
#[derive(Clone, Debug, Default)]
pub struct Timings {
    /// `(stage, seconds)` in the order the stages ran.
    pub stages: Vec<(String, f64)>,
}

impl Timings {
    /// Run `f` as stage `name` with a spinner, recording its wall time.
    pub fn stage<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let pb = spinner(name);
        let start = Instant::now();
        let out = f();
        self.stages
            .push((name.to_string(), start.elapsed().as_secs_f64()));
        pb.finish_and_clear();
        out
    }

    /// Sum of all stages.
    pub fn total(&self) -> f64 {
        self.stages.iter().map(|s| s.1).sum()
    }

    /// A small aligned table, one stage a line, then the total.
    pub fn report(&self) -> String {
        let mut s = String::new();
        for (name, secs) in &self.stages {
            s.push_str(&format!("  {name:<14} {secs:>8.3} s\n"));
        }
        s.push_str(&format!("  {:<14} {:>8.3} s\n", "total", self.total()));
        s
    }
}
