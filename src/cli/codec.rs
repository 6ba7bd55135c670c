//! `nephele encode` / `nephele decode`: RON model ⇄ compact binary codec.

use std::path::PathBuf;

use anyhow::Context;
use nephele::blobby::codec::{self, Encoding};
use nephele::blobby::{load_model, save_model};

/// Arguments of `nephele encode`.
#[derive(Debug, clap::Args)]
pub struct EncodeArgs {
    /// The model to encode (RON, or an encoded file to re-encode).
    pub model: PathBuf,
    /// Output file (e.g. model.blob).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Write the quantized form (under 20 bytes a blob; see `nephele eval` for its extra error)
    /// instead of the lossless f32 form.
    #[arg(long)]
    pub quantized: bool,
}

/// Arguments of `nephele decode`.
#[derive(Debug, clap::Args)]
pub struct DecodeArgs {
    /// The encoded model.
    pub input: PathBuf,
    /// Output RON model file.
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Run `nephele encode`.
pub fn run_encode(args: EncodeArgs) -> anyhow::Result<()> {
    let model = load_model(&args.model)?;
    let encoding = if args.quantized {
        Encoding::Quantized
    } else {
        Encoding::Lossless
    };
    let bytes = codec::encode(&model, encoding);
    nephele::atomic::write_bytes_atomically(&args.output, &bytes)
        .with_context(|| format!("writing {}", args.output.display()))?;
    let input = std::fs::metadata(&args.model).map(|m| m.len()).unwrap_or(0);
    eprintln!(
        "{}: {} blobs, {} bytes ({:?}, {:.1} bytes a blob; input {} bytes)",
        args.output.display(),
        model.blobs.len(),
        bytes.len(),
        encoding,
        bytes.len() as f64 / model.blobs.len().max(1) as f64,
        input
    );
    Ok(())
}

/// Run `nephele decode`.
pub fn run_decode(args: DecodeArgs) -> anyhow::Result<()> {
    let bytes = nephele::input::read(&args.input, nephele::input::Limit::Model)
        .with_context(|| format!("reading {}", args.input.display()))?;
    anyhow::ensure!(
        codec::is_encoded(&bytes),
        "{}: not an encoded blob model (missing the 'NPHB' magic number); RON models need no decoding",
        args.input.display()
    );
    let model = codec::decode(&args.input, &bytes)?;
    save_model(&args.output, &model)?;
    let written = std::fs::metadata(&args.output)
        .map(|m| m.len())
        .unwrap_or(0);
    eprintln!(
        "{}: {} blobs, {} bytes (from {} encoded bytes)",
        args.output.display(),
        model.blobs.len(),
        written,
        bytes.len()
    );
    Ok(())
}
