//! `nephele view`: serve the live look-development page of a scene ([`nephele::view`]).

use std::path::PathBuf;

/// Arguments of `nephele view`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scene file (RON); see scenes/README.md. Fixed for the server's life.
    pub scene: PathBuf,
    /// Port on 127.0.0.1 (default: a free one; the URL is printed).
    #[arg(long, default_value_t = 0)]
    pub port: u16,
    /// Folder of the view's fit cache (default: $XDG_CACHE_HOME/nephele/view, else
    /// ~/.cache/nephele/view). The view never writes into the shot's output folder unless its
    /// "render the shot" button is pressed.
    #[arg(long)]
    pub cache: Option<PathBuf>,
    /// `--set KEY=VALUE` and `--size WxH`, applied at every reload of the scene.
    #[command(flatten)]
    pub scene_args: super::common::SceneArgs,
    /// Worker threads for the page's renders (as `render --threads`).
    #[arg(short = 'j', long, value_name = "N", allow_negative_numbers = true)]
    pub threads: Option<i32>,
    /// Quiet: print the URL on stdout only.
    #[arg(short, long)]
    pub quiet: bool,
}

/// Run `nephele view` (until the process is stopped).
pub fn run(args: Args) -> anyhow::Result<()> {
    let options = nephele::view::ViewOptions {
        scene: args.scene,
        port: args.port,
        cache: args
            .cache
            .unwrap_or_else(nephele::view::ViewOptions::default_cache),
        overrides: args.scene_args.overrides(),
    };
    // The thread count by the render command's rule (`RunArgs::thread_count`).
    let run = super::common::RunArgs {
        threads: args.threads,
        progress: None,
        quiet: args.quiet,
        verbose: false,
    };
    let quiet = args.quiet;
    run.install(move || serve(options, quiet))?
}

fn serve(options: nephele::view::ViewOptions, quiet: bool) -> anyhow::Result<()> {
    nephele::view::serve(options, &mut |url| {
        use std::io::Write;
        // The URL alone on stdout's first line (scripts and tests read it), then flushed.
        println!("{url}");
        let _ = std::io::stdout().flush();
        if !quiet {
            eprintln!("nephele view: open {url} (Ctrl-C stops)");
        }
    })
}
