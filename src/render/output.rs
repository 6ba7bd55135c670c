//! Frame files: linear HDR OpenEXR (RGBA, plus depth) and tone-mapped sRGB PNG over the sky.
//! Both are written atomically.
//!
//! EXR: channels `R, G, B` hold the cloud's radiance **premultiplied** by its coverage, `A` the
//! coverage `1 − T`, `Z` the mean distance along the ray (infinity where empty), all f32,
//! linear, no exposure. Compositing over a background `bg` is `rgb + (1 − A)·bg`; over the
//! scene's sky, that is exactly what the PNG shows before exposure and tone mapping.
//!
//! PNG: `(rgb + (1 − A)·sky(dir)) · 2^exposure`, ACES filmic curve (Narkowicz 2015 fit), sRGB
//! transfer, 8-bit RGB.

use std::io::Cursor;
use std::path::Path;

use glam::Vec3;

use super::camera::CameraRays;
use super::{Frame, RenderSettings};

/// Write `frame` as an OpenEXR file with R, G, B, A (and Z depth) channels, atomically.
pub fn write_exr(path: &Path, frame: &Frame) -> std::io::Result<()> {
    crate::atomic::write_bytes_atomically(path, &encode_exr(frame)?)
}

/// The EXR file's bytes (see the module doc for the channels).
pub fn encode_exr(frame: &Frame) -> std::io::Result<Vec<u8>> {
    use exr::prelude::*;
    let size = (frame.width as usize, frame.height as usize);
    let chan = |name: &str, v: Vec<f32>| AnyChannel::new(name, FlatSamples::F32(v));
    let rgb = |c: usize| frame.rgb.iter().map(|p| p[c]).collect::<Vec<f32>>();
    let channels = AnyChannels::sort(SmallVec::from_vec(vec![
        chan("R", rgb(0)),
        chan("G", rgb(1)),
        chan("B", rgb(2)),
        chan("A", frame.alpha.clone()),
        chan("Z", frame.depth.clone()),
    ]));
    let layer = Layer::new(
        size,
        LayerAttributes::named("nephele"),
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    let mut bytes = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| std::io::Error::other(format!("EXR encoding failed: {e}")))?;
    Ok(bytes.into_inner())
}

/// Write `frame` composited over the sky, exposed and tone-mapped to 8-bit sRGB, atomically.
pub fn write_png(path: &Path, frame: &Frame, settings: &RenderSettings) -> std::io::Result<()> {
    let img = tonemapped(frame, settings);
    let mut bytes = Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)
        .map_err(|e| std::io::Error::other(format!("PNG encoding failed: {e}")))?;
    crate::atomic::write_bytes_atomically(path, bytes.get_ref())
}

/// The frame over the sky, exposed, tone-mapped and sRGB-encoded (what [`write_png`] writes).
pub fn tonemapped(frame: &Frame, settings: &RenderSettings) -> image::RgbImage {
    let cam = CameraRays::new(&settings.camera, frame.width, frame.height);
    let gain = settings.exposure.exp2();
    let dome = super::shading::SkyDome::new(&settings.sky, &settings.sun);
    image::RgbImage::from_fn(frame.width, frame.height, |x, y| {
        let i = (y * frame.width + x) as usize;
        let dir = Vec3::from(cam.pixel_ray(x, y).dir);
        let sky = dome.radiance(dir);
        let c = (Vec3::from(frame.rgb[i]) + sky * (1.0 - frame.alpha[i])) * gain;
        let m = |v: f32| (srgb_encode(aces(v)) * 255.0 + 0.5) as u8;
        image::Rgb([m(c.x), m(c.y), m(c.z)])
    })
}

/// ACES filmic tone curve (Narkowicz 2015 fit), `[0, ∞) → [0, 1]`.
#[inline]
pub fn aces(x: f32) -> f32 {
    let x = x.max(0.0);
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// sRGB transfer function for linear `v ∈ [0, 1]`.
#[inline]
pub fn srgb_encode(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}
