//! Contact sheet: paste PNG frames side by side into one PNG (reproducible sheets for the
//! README and reviews).
//!
//! ```text
//! cargo run --release --example contact_sheet -- OUT.png [--cols N] FRAME.png...
//! ```
//!
//! Frames are pasted left to right, top to bottom, in the order given (`--cols`, default: all
//! in one row), with a 4-pixel dark gutter; every frame must have the first frame's size. The
//! sheet is written atomically.

use std::path::PathBuf;

use anyhow::{Context, bail};
use image::{Rgb, RgbImage};

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().context(
        "usage: contact_sheet OUT.png [--cols N] FRAME.png... (frames in reading order)",
    )?);
    let mut cols = None;
    let mut frames = Vec::new();
    while let Some(a) = args.next() {
        if a == "--cols" {
            let n: usize = args
                .next()
                .context("--cols needs a number")?
                .parse()
                .context("--cols needs a positive whole number")?;
            if n == 0 {
                bail!("--cols needs a positive whole number");
            }
            cols = Some(n);
        } else {
            frames.push(PathBuf::from(a));
        }
    }
    if frames.is_empty() {
        bail!("no frames given");
    }
    let images: Vec<RgbImage> = frames
        .iter()
        .map(|p| {
            image::open(p)
                .with_context(|| format!("reading {}", p.display()))
                .map(|i| i.to_rgb8())
        })
        .collect::<anyhow::Result<_>>()?;
    let (w, h) = images[0].dimensions();
    if let Some((p, _)) = frames
        .iter()
        .zip(&images)
        .find(|(_, i)| i.dimensions() != (w, h))
    {
        bail!("{} is not {w}×{h} like the first frame", p.display());
    }
    let cols = cols.unwrap_or(images.len()).min(images.len()) as u32;
    let rows = (images.len() as u32).div_ceil(cols);
    let gutter = 4;
    let mut sheet = RgbImage::from_pixel(
        cols * w + (cols + 1) * gutter,
        rows * h + (rows + 1) * gutter,
        Rgb([24, 24, 28]),
    );
    for (k, img) in images.iter().enumerate() {
        let (c, r) = (k as u32 % cols, k as u32 / cols);
        let (x0, y0) = (gutter + c * (w + gutter), gutter + r * (h + gutter));
        image::imageops::replace(&mut sheet, img, x0 as i64, y0 as i64);
    }
    let mut bytes = Vec::new();
    sheet
        .write_to(
            &mut std::io::Cursor::new(&mut bytes),
            image::ImageFormat::Png,
        )
        .context("encoding the sheet")?;
    nephele::atomic::write_bytes_atomically(&out, &bytes)
        .with_context(|| format!("writing {}", out.display()))?;
    eprintln!("{}: {} frames, {cols}×{rows}", out.display(), images.len());
    Ok(())
}
