//! `nephele render`.

/// Arguments of `nephele render`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `nephele render`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("'nephele render' is not implemented yet")
}
