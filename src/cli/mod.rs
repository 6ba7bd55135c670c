//! The command-line shell: argument parsing and one thin `run` per command over the library;
//! [`main`] is the `nephele` program (the binary's and the Python wheel's).

pub mod codec;
pub mod common;
pub mod eval;
pub mod farm;
pub mod fit;
pub mod mesh;
pub mod prepare;
pub mod preview;
pub mod render;
pub mod usd;
pub mod view;

use clap::{Parser, Subcommand};

/// nephele: ellipsoidal-blob approximation of meshes and target-shaped cloud animation.
#[derive(Debug, Parser)]
#[command(name = "nephele", version, about, long_about = None)]
pub struct Cli {
    /// The command to run.
    #[command(subcommand)]
    pub command: Command,
}

/// The commands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit a blob model to a mesh (OBJ, PLY, OFF, STL or builtin:NAME).
    Fit(fit::Args),
    /// Measure a model's error against a mesh (Metro method), bytes and data reduction.
    Eval(eval::Args),
    /// Polygonize a model's blob surface to OBJ or PLY.
    Mesh(mesh::Args),
    /// Render a shot from a scene file to EXR and/or PNG frames (resumable).
    Render(render::Args),
    /// Render a fast low-resolution turntable of a model or mesh (frames and a GIF).
    Preview(preview::Args),
    /// Encode a model to the compact binary codec.
    Encode(codec::EncodeArgs),
    /// Decode a binary model back to a RON model file.
    Decode(codec::DecodeArgs),
    /// Fit and cache a scene's target once, before a farm renders its frames.
    Prepare(prepare::Args),
    /// Write (and with --submit, submit) a farm's jobs: prepare, then one task per frame chunk.
    Farm(farm::Args),
    /// Write a scene's shot as a USD stage: animated camera, sun, sky and the frame VDBs.
    Usd(usd::Args),
    /// Serve a live look-development page for a scene on 127.0.0.1 (re-renders on save).
    View(view::Args),
}

/// The `nephele` command: parse `args` (the program's name first), run the command, print the
/// error chain (each cause once) on stderr. Returns the exit code: 0, or 1 on an error (clap
/// prints `--help`, `--version` and usage errors itself and exits the process).
pub fn main<I, T>(args: I) -> u8
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = Cli::parse_from(args);
    let report = cli.command.run_args().map(|r| r.report(0));
    match run(cli) {
        Ok(()) => 0,
        Err(e) => {
            let message = error_message(&e);
            eprintln!("error: {message}");
            // A farm manager reading `--progress json` learns why the task failed there too.
            if let Some(report) = report {
                report.error(&message);
            }
            1
        }
    }
}

impl Command {
    /// The shared run arguments (`-j`, `--progress`, `-q`, `-v`) of the commands that take them.
    fn run_args(&self) -> Option<&common::RunArgs> {
        match self {
            Command::Render(a) => Some(&a.run_args),
            Command::Preview(a) => Some(&a.run_args),
            Command::Prepare(a) => Some(&a.run_args),
            _ => None,
        }
    }
}

/// Run the parsed command.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Fit(a) => fit::run(a),
        Command::Eval(a) => eval::run(a),
        Command::Mesh(a) => mesh::run(a),
        Command::Render(a) => render::run(a),
        Command::Preview(a) => preview::run(a),
        Command::Encode(a) => codec::run_encode(a),
        Command::Decode(a) => codec::run_decode(a),
        Command::Prepare(a) => prepare::run(a),
        Command::Farm(a) => farm::run(a),
        Command::Usd(a) => usd::run(a),
        Command::View(a) => view::run(a),
    }
}

/// The error and its causes as one line, `outer: cause: …`, each cause said once
/// ([`nephele::error_chain::message`], also the Python binding's exception text).
pub fn error_message(e: &anyhow::Error) -> String {
    nephele::error_chain::message(e.as_ref())
}

/// Load a mesh and print its warnings on stderr.
pub fn load_mesh(source: &str) -> anyhow::Result<nephele::mesh::LoadedMesh> {
    let loaded = nephele::mesh::load(source)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    Ok(loaded)
}
