//! `nephele view SCENE.ron`: a live look-development page on a loopback web server.
//!
//! The page (`page.html`, shipped inside the binary) shows the current frame of the shot,
//! refining from the preview size to `Final` at the scene's size, with exposure and the EXR's
//! layers to choose; a timeline scrubs the shot (frames rendered on demand and cached, a
//! flipbook at the shot's fps once they exist); per-frame statistics are plotted; an A/B wipe
//! compares with the picture before the last save. The scene file and every file it names are
//! watched ([`watch`]): a save re-renders, a bad edit shows its located error and keeps the last
//! good picture ([`session`]).
//!
//! The view is a thin shell: every frame is [`crate::scene::Shot::render_frame`] and every
//! beauty picture [`crate::render::output::tonemapped`], the calls `nephele render` makes. It
//! never writes into the shot's output folder unless the page's "render the shot" button asks
//! (fits are cached in the view's own folder, [`ViewOptions::cache`]).
//!
//! Security ([`http`]): bound to 127.0.0.1 only; a request whose `Host` is not the loopback
//! name and port is refused (DNS rebinding), and so is a `POST` from another origin; only the
//! page's fixed routes exist (no path from a request reaches the file system); the scene path
//! is fixed at start.

pub mod http;
pub mod layers;
pub mod session;
pub mod watch;

use std::path::PathBuf;

/// How to run the view.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// The scene file (fixed for the server's life).
    pub scene: PathBuf,
    /// Port on 127.0.0.1; 0 picks a free one.
    pub port: u16,
    /// Folder of the view's own fit cache (never the shot's output folder); fits already
    /// cached in the output folder are copied from there.
    pub cache: PathBuf,
    /// `--set`/`--size` overrides applied to every load of the scene (as `nephele render`
    /// applies them).
    pub overrides: Vec<crate::scene::file::overrides::Override>,
}

impl ViewOptions {
    /// The default cache folder: `$XDG_CACHE_HOME/nephele/view`, else `~/.cache/nephele/view`,
    /// else the system's temporary folder's `nephele-view`.
    pub fn default_cache() -> PathBuf {
        if let Some(x) = std::env::var_os("XDG_CACHE_HOME").filter(|x| !x.is_empty()) {
            return PathBuf::from(x).join("nephele").join("view");
        }
        if let Some(h) = std::env::var_os("HOME").filter(|h| !h.is_empty()) {
            return PathBuf::from(h).join(".cache").join("nephele").join("view");
        }
        std::env::temp_dir().join("nephele-view")
    }
}

/// Start the view: load the scene (a scene that does not load is shown on the page with its
/// error, as a bad edit is), start watching its files, bind the server and call `on_ready` with
/// the page's URL; then serve until the process ends. Fails when the scene file does not exist
/// or the port cannot be bound.
pub fn serve(options: ViewOptions, on_ready: &mut dyn FnMut(&str)) -> anyhow::Result<()> {
    use anyhow::Context;
    if !options.scene.is_file() {
        anyhow::bail!("{}: no such scene file", options.scene.display());
    }
    std::fs::create_dir_all(&options.cache).with_context(|| {
        format!(
            "creating the view's cache folder {}",
            options.cache.display()
        )
    })?;
    let server = http::bind(options.port)?;
    let port = server.port;
    let session = session::Session::start(
        options.scene.clone(),
        options.cache.clone(),
        options.overrides.clone(),
    );
    watch::spawn(session.clone());
    on_ready(&format!("http://127.0.0.1:{port}/"));
    server.run(session);
    Ok(())
}
