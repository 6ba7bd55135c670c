//! The flags the rendering commands share, as a renderer's users expect them (`husk -j`,
//! `kick -t`, `kick -set`, Deadline/Tractor progress): [`SceneArgs`] (`--set`, `--size`) for
//! commands that read a scene, [`RunArgs`] (`--threads`, `--progress json`, `-q`, `-v`) for
//! every rendering command. A command takes them with `#[command(flatten)]` and reports
//! through [`Report`]. The rules themselves are the library's
//! ([`nephele::scene::Override`]); this only passes strings.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use nephele::scene::{self, Override, Scene};

/// `--set` and `--size`: a scene's values overridden from the command line.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct SceneArgs {
    /// Override a value of the scene in its own dotted names, as if the file said it (RON
    /// value; repeatable, later ones win): `--set cloud.density=30 --set
    /// camera.fov_deg=20 --set 'output.formats=[Exr]'`. Part of the frames' provenance like
    /// the file's values.
    #[arg(long = "set", value_name = "KEY=VALUE", value_parser = Override::set)]
    pub set: Vec<Override>,
    /// Image size in pixels, WIDTHxHEIGHT: short for --set shot.width=W --set shot.height=H
    /// (applied before the --set overrides).
    #[arg(long, value_name = "WxH", value_parser = Override::size)]
    pub size: Option<[Override; 2]>,
}

impl SceneArgs {
    /// The overrides in the order they apply: `--size`, then each `--set`.
    pub fn overrides(&self) -> Vec<Override> {
        nephele::scene::overrides::in_order(self.size.as_ref(), &self.set)
    }

    /// The scene at `path` with these overrides.
    pub fn load(&self, path: &Path) -> Result<Scene, scene::SceneError> {
        scene::load_scene_with(path, &self.overrides())
    }
}

/// How a command reports progress for a machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ProgressFormat {
    /// One JSON object a line on stdout (the README's "A renderer's conventions").
    Json,
}

/// `--threads`, `--progress`, `-q`, `-v`.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct RunArgs {
    /// Worker threads: 0 (or absent) uses every core, a negative number all but that many
    /// (as husk -j and kick -t). Frames are the same bits at any count.
    #[arg(short = 'j', long, value_name = "N", allow_negative_numbers = true)]
    pub threads: Option<i32>,
    /// Machine-readable progress: `json` prints one JSON object a line on stdout (frame,
    /// stage, percent, elapsed, eta) for Deadline, Tractor or OpenCue; the messages stay on
    /// stderr.
    #[arg(long, value_name = "FORMAT")]
    pub progress: Option<ProgressFormat>,
    /// Quiet: print errors only.
    #[arg(short, long, conflicts_with = "verbose")]
    pub quiet: bool,
    /// Verbose: every frame's details (skipped frames too), the overrides and the threads.
    #[arg(short, long)]
    pub verbose: bool,
}

/// Most threads `--threads` may ask for.
pub const MAX_THREADS: i32 = 1024;

impl RunArgs {
    /// The number of worker threads asked for (0: rayon's default, every core or
    /// `RAYON_NUM_THREADS`), `None` without `--threads`.
    pub fn thread_count(&self) -> anyhow::Result<Option<usize>> {
        let Some(n) = self.threads else {
            return Ok(None);
        };
        anyhow::ensure!(
            n <= MAX_THREADS,
            "--threads {n}: at most {MAX_THREADS} threads"
        );
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        Ok(Some(match n {
            0 => 0,
            n if n > 0 => n as usize,
            n => cores.saturating_sub(n.unsigned_abs() as usize).max(1),
        }))
    }

    /// Run `f` on the thread count asked for: the process's pool set to it (every parallel
    /// loop of the run uses it), or, when the pool was made before (a front end calling the
    /// CLI twice in one process), a pool of its own for `f`.
    pub fn install<T: Send>(&self, f: impl FnOnce() -> T + Send) -> anyhow::Result<T> {
        let Some(n) = self.thread_count()? else {
            return Ok(f());
        };
        if rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .is_ok()
            || (n != 0 && rayon::current_num_threads() == n)
        {
            return Ok(f());
        }
        let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build()?;
        Ok(pool.install(f))
    }

    /// The reporter of a command whose work has `total` steps (frames).
    pub fn report(&self, total: u64) -> Report {
        Report {
            level: if self.quiet {
                Level::Quiet
            } else if self.verbose {
                Level::Verbose
            } else {
                Level::Normal
            },
            json: self.progress == Some(ProgressFormat::Json),
            start: Instant::now(),
            total,
            done: 0,
            busy_seconds: 0.0,
            busy_steps: 0,
        }
    }
}

/// How much a command says on stderr.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Level {
    /// Errors only (`-q`).
    Quiet,
    /// The default: what was done, a line per rendered frame.
    Normal,
    /// Every frame's details (`-v`).
    Verbose,
}

/// A command's messages (stderr, by [`Level`]) and machine progress (`--progress json`, stdout).
#[derive(Debug)]
pub struct Report {
    /// How much to say.
    pub level: Level,
    json: bool,
    start: Instant,
    total: u64,
    done: u64,
    /// Seconds and count of the steps that did work (not skipped), for the eta.
    busy_seconds: f64,
    busy_steps: u64,
}

impl Report {
    /// A message of the normal level.
    pub fn info(&self, msg: impl std::fmt::Display) {
        if self.level >= Level::Normal {
            eprintln!("{msg}");
        }
    }

    /// A message of the verbose level.
    pub fn detail(&self, msg: impl std::fmt::Display) {
        if self.level >= Level::Verbose {
            eprintln!("{msg}");
        }
    }

    /// A terminal progress bar of the steps, hidden when quiet or when a machine reads the
    /// progress.
    pub fn bar(&self, label: &str) -> indicatif::ProgressBar {
        if self.level == Level::Quiet || self.json {
            indicatif::ProgressBar::hidden()
        } else {
            nephele::progress::bar(label, self.total)
        }
    }

    /// A stage without a frame began or ended (`start`, `prepare`, `done`).
    pub fn stage(&self, stage: &str) {
        let percent = if stage == "done" {
            100.0
        } else {
            self.percent()
        };
        self.emit(stage, None, percent, None);
    }

    /// One step (frame `frame`) finished, after `seconds` of work (`skipped`: it was up to date).
    pub fn step(&mut self, frame: u32, seconds: f64, skipped: bool) {
        self.done = (self.done + 1).min(self.total);
        if !skipped {
            self.busy_seconds += seconds;
            self.busy_steps += 1;
        }
        self.emit(
            "frame",
            Some(frame),
            self.percent(),
            Some((seconds, skipped)),
        );
    }

    /// The command failed with `message`: a last `error` line for a machine reading
    /// `--progress json` (the message is also on stderr, as always).
    pub fn error(&self, message: &str) {
        if !self.json {
            return;
        }
        let line = serde_json::json!({ "stage": "error", "message": message });
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    }

    fn percent(&self) -> f64 {
        if self.total == 0 {
            100.0
        } else {
            100.0 * self.done as f64 / self.total as f64
        }
    }

    /// Seconds left: the mean of the steps that did work times the steps left (`None` before
    /// one has).
    fn eta(&self) -> Option<f64> {
        let left = self.total - self.done;
        if left == 0 {
            return Some(0.0);
        }
        (self.busy_steps > 0).then(|| self.busy_seconds / self.busy_steps as f64 * left as f64)
    }

    fn emit(&self, stage: &str, frame: Option<u32>, percent: f64, step: Option<(f64, bool)>) {
        if !self.json {
            return;
        }
        let round = |x: f64| (x * 1000.0).round() / 1000.0;
        let mut line = serde_json::json!({
            "stage": stage,
            "frame": frame,
            "done": self.done,
            "total": self.total,
            "percent": round(percent),
            "elapsed": round(self.start.elapsed().as_secs_f64()),
            "eta": self.eta().map(round),
        });
        if let Some((seconds, skipped)) = step {
            line["seconds"] = round(seconds).into();
            line["skipped"] = skipped.into();
        }
        // One write a line, flushed, so a farm manager reading the pipe sees it at once.
        let mut out = std::io::stdout().lock();
        let _ = writeln!(out, "{line}");
        let _ = out.flush();
    }
}
