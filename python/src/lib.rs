//! Python bindings of nephele (module `nephele._nephele`, re-exported by the `nephele` package).
//!
//! Everything goes through the library's public API, the way the command line does: a scene is
//! parsed and validated by `nephele::scene::scene_from_str` (so its errors are the CLI's, with
//! file, line and field), a shot is a `nephele::scene::Shot`, `render_all` is the shot's own
//! resumable run (`Shot::run_until`), and `frames_iter` renders frames in memory through one
//! `nephele::render::FrameRenderer` as that run does (its reuse: holds and still clouds). Long
//! work runs with the GIL released; Python callbacks are called back under it. The rules both
//! the CLI and the binding follow (the error chain, the output folder check, format names, the
//! colour conversion, the Cryptomatte ids and manifest, the blob rows and their checks) live in
//! the library; this crate only converts.
//!
//! One module a concern: [`errors`] (the exceptions), [`args`] (arguments read into the
//! library's types), [`arrays`] (numpy in and out), [`model`] (`Model`, `fit`), [`scene`]
//! (`Scene`), [`shot`] (`Shot`, `FrameIter`), [`layers`] (a frame's EXR layers as arrays), [`cli`] (the wheel's
//! `nephele` command).

mod args;
mod arrays;
mod cli;
mod errors;
mod layers;
mod model;
mod scene;
mod shot;

use pyo3::prelude::*;

/// The library's version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _nephele(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_class::<model::Model>()?;
    m.add_class::<scene::Scene>()?;
    m.add_class::<shot::Shot>()?;
    m.add_class::<shot::FrameIter>()?;
    m.add_function(wrap_pyfunction!(model::fit, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    m.add_function(wrap_pyfunction!(cli::main, m)?)?;
    Ok(())
}
