//! A false-colour picture of an EXR frame's Cryptomatte layer (the `CryptoObject` ID mattes of
//! `render --passes`), for a look without a compositor: each matte in a colour made from its
//! id's bits (as the spec's preview channels are), the ranks mixed by coverage over black.
//!
//! ```text
//! cargo run --release --example cryptomatte_view -- FRAME.exr OUT.png
//! ```

use anyhow::{Context, bail};
use exr::prelude::*;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [input, output] = args.as_slice() else {
        bail!("usage: cryptomatte_view FRAME.exr OUT.png");
    };
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(input)
        .with_context(|| format!("reading {input}"))?;
    let layer = &image.layer_data;
    let (w, h) = (layer.size.0, layer.size.1);
    let channel = |name: &str| -> anyhow::Result<&[f32]> {
        let c = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name == *name)
            .with_context(|| format!("{input}: no channel {name} (render with --passes)"))?;
        match &c.sample_data {
            FlatSamples::F32(v) => Ok(v),
            _ => bail!("{input}: {name} is not f32"),
        }
    };
    // (id, coverage) channel pairs, rank by rank.
    let mut ranks = Vec::new();
    for set in 0.. {
        let name = |c: &str| format!("CryptoObject{set:02}.{c}");
        if set > 0 && channel(&name("R")).is_err() {
            break;
        }
        ranks.push((channel(&name("R"))?, channel(&name("G"))?));
        ranks.push((channel(&name("B"))?, channel(&name("A"))?));
    }
    let picture = image::RgbImage::from_fn(w as u32, h as u32, |x, y| {
        let i = y as usize * w + x as usize;
        let mut rgb = [0.0f32; 3];
        for (id, coverage) in &ranks {
            let bits = id[i].to_bits();
            for (k, v) in rgb.iter_mut().enumerate() {
                let byte = (bits >> (16 - 8 * k)) & 0xff;
                *v += coverage[i] * (0.25 + 0.75 * byte as f32 / 255.0);
            }
        }
        image::Rgb(rgb.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
    });
    picture
        .save(output)
        .with_context(|| format!("writing {output}"))?;
    Ok(())
}
