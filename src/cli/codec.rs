//! `nephele encode` / `nephele decode`.

/// Arguments of `nephele encode`.
#[derive(Debug, clap::Args)]
pub struct EncodeArgs {}

/// Arguments of `nephele decode`.
#[derive(Debug, clap::Args)]
pub struct DecodeArgs {}

/// Run `nephele encode`.
pub fn run_encode(_args: EncodeArgs) -> anyhow::Result<()> {
    anyhow::bail!("'nephele encode' is not implemented yet")
}

/// Run `nephele decode`.
pub fn run_decode(_args: DecodeArgs) -> anyhow::Result<()> {
    anyhow::bail!("'nephele decode' is not implemented yet")
}
