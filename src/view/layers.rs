//! The pictures of a rendered frame the page shows: the beauty exactly as `nephele render`
//! writes its PNG ([`tonemapped`], the scene's exposure plus the page's offset), and the EXR's
//! other layers made visible: alpha and depth as grey, the passes exposed and tone-mapped like
//! the beauty (over black: a pass has no sky), the Cryptomatte mattes as colours.

use crate::render::output::cryptomatte::name_id;
use crate::render::output::{aces, srgb_encode, tonemapped};

use super::session::Rendered;

/// A layer of the frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Layer {
    /// The frame over the sky, exposed, tone-mapped, sRGB (the PNG `render` writes).
    Beauty,
    /// Coverage `1 − transmittance`, as grey.
    Alpha,
    /// Distance from the eye, near bright, far dark, nothing black (spread over the frame's
    /// own nearest to farthest).
    Depth,
    /// Sunlight scattered once (pass `sun`).
    Sun,
    /// Sky light scattered once (pass `sky`).
    Sky,
    /// Multiple scattering (pass `multiple`).
    Multiple,
    /// The object mattes (`CryptoObject`), each matte a colour, mixed by coverage.
    Cryptomatte,
}

impl Layer {
    /// The layer a request names.
    pub fn parse(s: &str) -> Option<Layer> {
        Some(match s {
            "beauty" => Layer::Beauty,
            "alpha" => Layer::Alpha,
            "depth" => Layer::Depth,
            "sun" => Layer::Sun,
            "sky" => Layer::Sky,
            "multiple" => Layer::Multiple,
            "cryptomatte" => Layer::Cryptomatte,
            _ => return None,
        })
    }

    /// True when the frame must be rendered with the passes (and mattes) for it.
    pub fn needs_passes(self) -> bool {
        matches!(
            self,
            Layer::Sun | Layer::Sky | Layer::Multiple | Layer::Cryptomatte
        )
    }
}

/// The picture of `layer` of `r` at exposure offset `ev` stops, 8-bit sRGB.
pub fn image(r: &Rendered, layer: Layer, ev: f32) -> Result<image::RgbImage, String> {
    let f = &r.frame;
    let (w, h) = (f.width, f.height);
    let grey = |v: &[f32]| {
        let bytes = v
            .iter()
            .flat_map(|&a| [(a.clamp(0.0, 1.0) * 255.0 + 0.5) as u8; 3])
            .collect();
        image::RgbImage::from_raw(w, h, bytes).expect("3 bytes a pixel")
    };
    let gain = (r.settings.exposure + ev).exp2();
    let exposed = |rgb: &[[f32; 3]]| {
        let m = |v: f32| (srgb_encode(aces(v * gain)) * 255.0 + 0.5) as u8;
        let bytes = rgb
            .iter()
            .flat_map(|c| [m(c[0]), m(c[1]), m(c[2])])
            .collect();
        image::RgbImage::from_raw(w, h, bytes).expect("3 bytes a pixel")
    };
    let passes = || {
        f.passes
            .as_deref()
            .ok_or_else(|| "the frame was rendered without its passes".to_string())
    };
    Ok(match layer {
        Layer::Beauty => {
            let mut settings = r.settings.clone();
            settings.exposure += ev;
            tonemapped(f, &settings)
        }
        Layer::Alpha => grey(&f.alpha),
        Layer::Depth => {
            let finite = f.depth.iter().filter(|d| d.is_finite());
            let near = finite.clone().fold(f32::INFINITY, |a, &d| a.min(d));
            let far = finite.fold(f32::NEG_INFINITY, |a, &d| a.max(d));
            let span = (far - near).max(1e-6);
            let shade: Vec<f32> = f
                .depth
                .iter()
                .map(|&d| {
                    if d.is_finite() {
                        1.0 - 0.8 * (d - near) / span
                    } else {
                        0.0
                    }
                })
                .collect();
            grey(&shade)
        }
        Layer::Sun => exposed(&passes()?.sun),
        Layer::Sky => exposed(&passes()?.sky),
        Layer::Multiple => exposed(&passes()?.multiple),
        Layer::Cryptomatte => {
            let mattes = f
                .mattes
                .as_deref()
                .ok_or_else(|| "the frame was rendered without its mattes".to_string())?;
            let colours: Vec<[f32; 3]> = mattes.names.iter().map(|n| matte_colour(n)).collect();
            let bytes = mattes
                .ranks
                .iter()
                .flat_map(|ranks| {
                    let mut c = [0.0f32; 3];
                    for rank in ranks {
                        if let Some(m) = mattes.named(*rank) {
                            for (c, k) in c.iter_mut().zip(colours[m]) {
                                *c += k * rank.coverage;
                            }
                        }
                    }
                    c.map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8)
                })
                .collect();
            image::RgbImage::from_raw(w, h, bytes).expect("3 bytes a pixel")
        }
    })
}

/// A matte's colour from its Cryptomatte id (the bits of the name's hash), bright enough to
/// tell apart on black — the same colour for the same name in every frame.
fn matte_colour(name: &str) -> [f32; 3] {
    let bits = name_id(name).to_bits();
    let channel = |shift: u32| 0.25 + 0.75 * ((bits >> shift) & 0xff) as f32 / 255.0;
    [channel(0), channel(8), channel(16)]
}

/// The PNG of [`image`], encoded for speed (the page asks again and again while scrubbing).
pub fn png(r: &Rendered, layer: Layer, ev: f32) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let img = image(r, layer, ev)?;
    let mut bytes = Vec::new();
    PngEncoder::new_with_quality(&mut bytes, CompressionType::Fast, FilterType::Sub)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| format!("PNG encoding failed: {e}"))?;
    Ok(bytes)
}
