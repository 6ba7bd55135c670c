//! `nephele preview`.

/// Arguments of `nephele preview`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `nephele preview`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("'nephele preview' is not implemented yet")
}
