//! `nephele mesh`.

/// Arguments of `nephele mesh`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `nephele mesh`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("'nephele mesh' is not implemented yet")
}
