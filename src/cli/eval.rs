//! `nephele eval`.

/// Arguments of `nephele eval`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `nephele eval`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("'nephele eval' is not implemented yet")
}
