//! Frame files: linear HDR OpenEXR (RGBA, plus depth) and tone-mapped sRGB PNG over the sky.
//! Both are written atomically.
//!
//! EXR: channels `R, G, B` hold the cloud's radiance **premultiplied** by its coverage, `A` the
//! coverage `1 − T`, `Z` the mean distance along the ray (infinity where empty), all f32,
//! linear, no exposure (f32 also for the ID mattes, whose ids are float bit patterns). A frame
//! rendered with passes adds the layers `sun.R/G/B`, `sky.R/G/B`
//! and `multiple.R/G/B` (single-part, scanline: the layout Nuke reads as layers), which sum to
//! `R, G, B`. A frame rendered with motion vectors ([`Frame::motion`]) adds `forward.u` and
//! `forward.v`: each pixel's forward motion over one frame in pixels, u to the right, v up
//! (Nuke's `forward` layer, which its `motion` layer and VectorBlur read), 0 where there is no
//! cloud. Compositing over a background `bg` is `rgb + (1 − A)·bg`; over the
//! scene's sky, that is exactly what the PNG shows before exposure and tone mapping.
//!
//! EXR metadata ([`FrameMetadata`], written by [`write_exr_with`]): the OpenEXR standard
//! attributes `worldToCamera` and `worldToNDC` (m44f, row-vector convention `p' = p·M` as in
//! Imath) so a compositor can re-project, and the strings `nephele/scene`, `nephele/frame`,
//! `nephele/seed`, `nephele/version`. Camera space is OpenEXR's: left-handed, +x right, +y up,
//! +z the view direction, origin at the eye. NDC: `(0, 0)` the top-left and `(1, 1)` the
//! bottom-right corner of the image after the homogeneous divide (`z` is `1/depth`, not a
//! depth). Header attributes are sorted by name, so a frame is byte-identical across runs.
//!
//! PNG: `(rgb + (1 − A)·sky(dir)) · 2^exposure`, ACES filmic curve (Narkowicz 2015 fit), sRGB
//! transfer, 8-bit RGB.
//!
//! A region render ([`Frame::region`]): the EXR's data window is the region and its display
//! window the full frame (only the region's pixels are stored); the PNG is full size, RGBA,
//! transparent outside the region.
//!
//! Holdouts ([`Frame::holdout`]): the channel `holdout.A`, each pixel's share covered by a
//! holdout (the plate's geometry; the beauty is already 0 behind it). The shadow pass
//! ([`Frame::shadow`]): `shadow.R/G/B` (equal), the sun's transmittance through the cloud from
//! the surface the pixel sees, 1 elsewhere: what a compositor multiplies a plate lit by the
//! sun alone by; and [`Frame::shadow_total`]: `shadow_total.R/G/B`, the light of the sun and
//! the sky together that the cloud lets through (the catcher for a plate lit by both).
//!
//! ID mattes ([`Frame::mattes`]): channels `CryptoObject00.R/G/B/A`, … and the
//! `cryptomatte/<key>/…` header attributes of [`crate::render::output::cryptomatte`].

pub(crate) mod color;
pub mod cryptomatte;
pub(crate) mod film;

pub use color::{ColorSpace, RgbConverter};

use std::io::Cursor;
use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;

use crate::render::camera::CameraRays;
use crate::render::frame::Frame;
use crate::render::settings::RenderSettings;

/// Write `frame` as an OpenEXR file with R, G, B, A (and Z depth) channels, atomically.
pub fn write_exr(path: &Path, frame: &Frame) -> std::io::Result<()> {
    crate::atomic::write_bytes_atomically(path, &encode_exr(frame)?)
}

/// [`write_exr`] with the camera and provenance attributes of `meta`.
pub fn write_exr_with(path: &Path, frame: &Frame, meta: &FrameMetadata) -> std::io::Result<()> {
    crate::atomic::write_bytes_atomically(path, &encode_exr_with(frame, Some(meta))?)
}

/// The EXR file's bytes (see the module doc for the channels).
pub(crate) fn encode_exr(frame: &Frame) -> std::io::Result<Vec<u8>> {
    encode_exr_with(frame, None)
}

/// What a frame's EXR header says about where it came from, besides its pixels.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameMetadata {
    /// `worldToCamera` (row-major m44f, row-vector convention).
    pub world_to_camera: [f32; 16],
    /// `worldToNDC` (row-major m44f, row-vector convention).
    pub world_to_ndc: [f32; 16],
    /// The RGB space the file holds: the renderer's Rec.709 values are converted to it, and
    /// its `chromaticities` are written.
    pub color_space: ColorSpace,
    /// `framesPerSecond` (a rational, [`fps_rational`]).
    pub frames_per_second: Option<(i32, u32)>,
    /// `nephele/…` strings: `(key without the prefix, value)`.
    pub strings: Vec<(String, String)>,
}

impl FrameMetadata {
    /// The matrices of `camera` for a `width × height` image, as the renderer casts its rays
    /// ([`CameraRays`]), and the provenance strings.
    pub fn new(
        camera: &crate::render::camera::Camera,
        width: u32,
        height: u32,
        strings: Vec<(String, String)>,
    ) -> FrameMetadata {
        let (world_to_camera, world_to_ndc) =
            CameraFrame::new(camera, width, height).exr_matrices();
        FrameMetadata {
            world_to_camera: world_to_camera.map(|v| v as f32),
            world_to_ndc: world_to_ndc.map(|v| v as f32),
            color_space: ColorSpace::Rec709,
            frames_per_second: None,
            strings,
        }
    }
}

/// A frame rate as OpenEXR's rational `framesPerSecond`: whole rates as `n/1`, rates of a few
/// decimals exactly (`12.5` → `25/2`), NTSC rates as `n·1000/1001` (`23.976` → `24000/1001`,
/// `29.97` → `30000/1001`), anything else to a thousandth.
pub fn fps_rational(fps: f64) -> (i32, u32) {
    let exact = |den: u32| {
        let num = fps * den as f64;
        ((num - num.round()).abs() < 1e-9 * num.abs().max(1.0)).then(|| (num.round() as i32, den))
    };
    if let Some(r) = exact(1) {
        return r;
    }
    // 23.976 is written for 24000/1001 (23.97602…), 29.97 for 30000/1001.
    let ntsc = fps * 1.001;
    if (ntsc - ntsc.round()).abs() < 1e-3 {
        return ((ntsc.round() * 1000.0) as i32, 1001);
    }
    [2u32, 4, 5, 8, 10, 20, 25, 50, 100, 1000]
        .into_iter()
        .find_map(exact)
        .unwrap_or(((fps * 1000.0).round() as i32, 1000))
}

/// The camera of a frame as the renderer casts its rays: eye, orthonormal axes, the
/// image-plane half extents at distance 1 and the image centre's place on that plane (zero but
/// for a shifted lens).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    /// Eye position.
    pub eye: glam::DVec3,
    /// Unit axis toward the image's right edge.
    pub right: glam::DVec3,
    /// Unit axis toward the image's top edge.
    pub up: glam::DVec3,
    /// Unit view direction.
    pub forward: glam::DVec3,
    /// `tan` of half the horizontal field of view.
    pub tan_half_h: f64,
    /// `tan` of half the vertical field of view.
    pub tan_half_v: f64,
    /// The image centre on the plane at distance 1, along `right` and `up`: the lens shift
    /// ([`crate::render::Camera::shift`]) in these units; `[0, 0]` for a centred camera.
    pub center: [f64; 2],
}

impl CameraFrame {
    /// The frame of `camera` for a `width × height` image, read off the renderer's own rays
    /// ([`CameraRays`]): the centre ray is the view direction, and the rays through the right
    /// and top edge midpoints give the right and up axes with their image-plane scales.
    pub fn new(camera: &crate::render::camera::Camera, width: u32, height: u32) -> CameraFrame {
        let rays = CameraRays::new(camera, width, height);
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        let forward = glam::DVec3::from(Vec3::from(rays.forward));
        // A ray d through the image plane at distance 1 along f is d/(d·f) = f + offset.
        let offset = |px: f32, py: f32| {
            let d = glam::DVec3::from(Vec3::from(rays.dir(px, py)));
            d / d.dot(forward) - forward
        };
        let (right_edge, top_edge) = (offset(w, 0.5 * h), offset(0.5 * w, 0.0));
        // A centred camera's edges are read as they always were (its centre is exactly zero);
        // a shifted one's are measured from the image centre.
        let centre = if camera.shift == glam::Vec2::ZERO {
            glam::DVec3::ZERO
        } else {
            offset(0.5 * w, 0.5 * h)
        };
        let (right_half, up_half) = (right_edge - centre, top_edge - centre);
        let (right, up) = (right_half.normalize(), up_half.normalize());
        CameraFrame {
            eye: glam::DVec3::from(Vec3::from(rays.position)),
            right,
            up,
            forward,
            tan_half_h: right_half.length(),
            tan_half_v: up_half.length(),
            center: [centre.dot(right), centre.dot(up)],
        }
    }

    /// `(worldToCamera, worldToNDC)`, row-major with row vectors (see the module doc).
    pub fn exr_matrices(&self) -> ([f64; 16], [f64; 16]) {
        let mut view = [0.0; 16];
        for (col, axis) in [self.right, self.up, self.forward].into_iter().enumerate() {
            for row in 0..3 {
                view[row * 4 + col] = axis[row];
            }
            view[12 + col] = -self.eye.dot(axis);
        }
        view[15] = 1.0;
        // Camera → homogeneous NDC: X = x·a + z·(1/2 − cx·a), Y = −y·b + z·(1/2 + cy·b),
        // Z = 1, W = z, where (cx, cy) is the image centre (zero for a centred camera, so the
        // terms are exactly 1/2).
        let (a, b) = (0.5 / self.tan_half_h, 0.5 / self.tan_half_v);
        let [cx, cy] = self.center;
        let (sx, sy) = (0.5 - cx * a, 0.5 + cy * b);
        let proj = [
            a, 0.0, 0.0, 0.0, //
            0.0, -b, 0.0, 0.0, //
            sx, sy, 0.0, 1.0, //
            0.0, 0.0, 1.0, 0.0,
        ];
        let mut ndc = [0.0; 16];
        for r in 0..4 {
            for c in 0..4 {
                ndc[r * 4 + c] = (0..4).map(|k| view[r * 4 + k] * proj[k * 4 + c]).sum();
            }
        }
        (view, ndc)
    }
}

/// The output format named `name` (its extension, any case: `exr`, `png`, `vdb`, `vol`), or
/// the message saying what the formats are: how `nephele render --formats` and the Python
/// binding's `Scene.shot(formats=…)` read a format.
pub fn parse_format(name: &str) -> Result<crate::scene::Format, String> {
    use crate::scene::Format;
    Format::from_name(name).ok_or_else(|| {
        let names: Vec<&str> = Format::ALL.iter().map(|f| f.extension()).collect();
        let (last, rest) = names.split_last().expect("there are formats");
        format!(
            "'{name}' is not a format (use {} or {last})",
            rest.join(", ")
        )
    })
}

/// The EXR file's bytes with the attributes of `meta`, if any.
pub fn encode_exr_with(frame: &Frame, meta: Option<&FrameMetadata>) -> std::io::Result<Vec<u8>> {
    use exr::prelude::*;
    // The data window: the region rendered, or the whole frame.
    let window = frame
        .region
        .unwrap_or(film::Region::full(frame.width, frame.height));
    let size = (window.width() as usize, window.height() as usize);
    let pixels: Vec<usize> = (window.y0..window.y1)
        .flat_map(|y| (window.x0..window.x1).map(move |x| (y * frame.width + x) as usize))
        .collect();
    let chan = |name: &str, v: Vec<f32>| AnyChannel::new(name, FlatSamples::F32(v));
    let space = meta.map_or(ColorSpace::Rec709, |m| m.color_space);
    let to_space = space.converter();
    let convert = |rgb: &[[f32; 3]], c: usize| {
        pixels
            .iter()
            .map(|&i| to_space.apply(rgb[i])[c])
            .collect::<Vec<f32>>()
    };
    let crop = |v: &[f32]| pixels.iter().map(|&i| v[i]).collect::<Vec<f32>>();
    let mut list = vec![
        chan("R", convert(&frame.rgb, 0)),
        chan("G", convert(&frame.rgb, 1)),
        chan("B", convert(&frame.rgb, 2)),
        chan("A", crop(&frame.alpha)),
        chan("Z", crop(&frame.depth)),
    ];
    if let Some(p) = &frame.passes {
        for (layer, rgb) in [("sun", &p.sun), ("sky", &p.sky), ("multiple", &p.multiple)] {
            for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
                list.push(chan(&format!("{layer}.{name}"), convert(rgb, c)));
            }
        }
    }
    if let Some(motion) = &frame.motion {
        for (c, name) in ["forward.u", "forward.v"].into_iter().enumerate() {
            list.push(chan(name, pixels.iter().map(|&i| motion[i][c]).collect()));
        }
    }
    if let Some(h) = &frame.holdout {
        list.push(chan("holdout.A", crop(h)));
    }
    if let Some(sh) = &frame.shadow {
        for name in ["R", "G", "B"] {
            list.push(chan(&format!("shadow.{name}"), crop(sh)));
        }
    }
    if let Some(st) = &frame.shadow_total {
        for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
            let v = pixels.iter().map(|&i| st[i][c]).collect();
            list.push(chan(&format!("shadow_total.{name}"), v));
        }
    }
    if let Some(m) = &frame.mattes {
        for (name, values) in m.channels(&pixels) {
            list.push(chan(&name, values));
        }
    }
    let channels = AnyChannels::sort(SmallVec::from_vec(list));
    let mut attributes = LayerAttributes::named("nephele");
    attributes.layer_position = Vec2(window.x0 as i32, window.y0 as i32);
    let text = |s: &str| exr::meta::attribute::AttributeValue::Text(latin1_text(s));
    if let Some(m) = &frame.mattes {
        for (key, value) in m.header() {
            attributes.other.insert(latin1_text(&key), text(&value));
        }
    }
    if let Some(meta) = meta {
        attributes.world_to_camera = Some(meta.world_to_camera);
        attributes.world_to_normalized_device = Some(meta.world_to_ndc);
        attributes.frames_per_second = meta.frames_per_second;
        for (key, value) in &meta.strings {
            attributes.other.insert(
                latin1_text(&format!("nephele/{key}")),
                exr::meta::attribute::AttributeValue::Text(latin1_text(value)),
            );
        }
    }
    let layer = Layer::new(size, attributes, Encoding::SMALL_LOSSLESS, channels);
    let mut image = Image::from_layer(layer);
    image.attributes.display_window =
        IntegerBounds::new((0, 0), (frame.width as usize, frame.height as usize));
    if meta.is_some() {
        let c = space.chromaticities();
        let xy = |[x, y]: [f64; 2]| Vec2(x as f32, y as f32);
        image.attributes.chromaticities = Some(exr::meta::attribute::Chromaticities {
            red: xy(c.red),
            green: xy(c.green),
            blue: xy(c.blue),
            white: xy(c.white),
        });
    }
    let mut bytes = Cursor::new(Vec::new());
    // exr's parallel writer makes a pool of every core of its own: a run held to fewer threads
    // (`--threads`) compresses on this one instead (the same bytes).
    let held = std::thread::available_parallelism()
        .is_ok_and(|cores| rayon::current_num_threads() < cores.get());
    let written = if held {
        image.write().non_parallel().to_buffered(&mut bytes)
    } else {
        image.write().to_buffered(&mut bytes)
    };
    written.map_err(|e| std::io::Error::other(format!("EXR encoding failed: {e}")))?;
    let mut bytes = bytes.into_inner();
    sort_header_attributes(&mut bytes)?;
    Ok(bytes)
}

/// `s` as EXR text (Latin-1); other characters become `?`.
fn latin1_text(s: &str) -> exr::meta::attribute::Text {
    let safe: String = s
        .chars()
        .map(|c| if (c as u32) < 256 { c } else { '?' })
        .collect();
    exr::meta::attribute::Text::new_or_panic(safe)
}

/// Sort a single-part EXR file's header attributes by name, in place. The `exr` crate keeps
/// custom attributes in a `HashMap`, whose order changes from run to run; the header's length
/// and so every offset after it stay the same.
fn sort_header_attributes(bytes: &mut [u8]) -> std::io::Result<()> {
    let bad = || std::io::Error::other("EXR header could not be parsed for sorting");
    const MULTIPART: u8 = 0x10; // bit 12 of the version field
    if bytes.len() < 8 || bytes[5] & MULTIPART != 0 {
        return Err(bad());
    }
    let mut at = 8;
    let mut attributes: Vec<(Vec<u8>, Vec<u8>)> = Vec::new();
    while *bytes.get(at).ok_or_else(bad)? != 0 {
        let start = at;
        let name_end = start
            + bytes[start..]
                .iter()
                .position(|&b| b == 0)
                .ok_or_else(bad)?;
        let type_end = name_end
            + 1
            + bytes[name_end + 1..]
                .iter()
                .position(|&b| b == 0)
                .ok_or_else(bad)?;
        let size_at = type_end + 1;
        let size = i32::from_le_bytes(
            bytes
                .get(size_at..size_at + 4)
                .ok_or_else(bad)?
                .try_into()
                .map_err(|_| bad())?,
        );
        let end = size_at + 4 + usize::try_from(size).map_err(|_| bad())?;
        let whole = bytes.get(start..end).ok_or_else(bad)?.to_vec();
        attributes.push((bytes[start..name_end].to_vec(), whole));
        at = end;
    }
    attributes.sort();
    let mut write = 8;
    for (_, whole) in attributes {
        bytes[write..write + whole.len()].copy_from_slice(&whole);
        write += whole.len();
    }
    Ok(())
}

/// Write `frame` composited over the sky, exposed and tone-mapped to 8-bit sRGB, atomically.
///
/// A region render ([`Frame::region`]) is written full size as RGBA, opaque inside the region
/// and transparent outside, so it lies over the full frame pixel for pixel.
pub fn write_png(path: &Path, frame: &Frame, settings: &RenderSettings) -> std::io::Result<()> {
    let img = tonemapped(frame, settings);
    let mut bytes = Cursor::new(Vec::new());
    let encoded = match frame.region {
        None => img.write_to(&mut bytes, image::ImageFormat::Png),
        Some(r) => image::RgbaImage::from_fn(frame.width, frame.height, |x, y| {
            let [red, green, blue] = img.get_pixel(x, y).0;
            image::Rgba([red, green, blue, if r.contains(x, y) { 255 } else { 0 }])
        })
        .write_to(&mut bytes, image::ImageFormat::Png),
    };
    encoded.map_err(|e| std::io::Error::other(format!("PNG encoding failed: {e}")))?;
    crate::atomic::write_bytes_atomically(path, bytes.get_ref())
}

/// The frame over the sky, exposed, tone-mapped and sRGB-encoded (what [`write_png`] writes);
/// rows in parallel (the sky's radiance and the curves per pixel had been 0.09 s of a 1080p
/// frame's PNG on one core).
pub fn tonemapped(frame: &Frame, settings: &RenderSettings) -> image::RgbImage {
    let cam = CameraRays::new(&settings.camera, frame.width, frame.height);
    let gain = settings.exposure.exp2();
    let dome = crate::render::light::sky_dome::SkyDome::new(&settings.sky, &settings.sun);
    let w = frame.width as usize;
    let mut bytes = vec![0u8; 3 * w * frame.height as usize];
    bytes
        .par_chunks_mut(3 * w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            for (x, px) in row.chunks_exact_mut(3).enumerate() {
                let i = y * w + x;
                let dir = Vec3::from(cam.pixel_ray(x as u32, y as u32).dir);
                let sky = dome.radiance(dir);
                let c = (Vec3::from(frame.rgb[i]) + sky * (1.0 - frame.alpha[i])) * gain;
                let m = |v: f32| (srgb_encode(aces(v)) * 255.0 + 0.5) as u8;
                px.copy_from_slice(&[m(c.x), m(c.y), m(c.z)]);
            }
        });
    image::RgbImage::from_raw(frame.width, frame.height, bytes).expect("3 bytes a pixel")
}

/// ACES filmic tone curve (Narkowicz 2015 fit), `[0, ∞) → [0, 1]`.
#[inline]
pub(crate) fn aces(x: f32) -> f32 {
    let x = x.max(0.0);
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// sRGB transfer function for linear `v ∈ [0, 1]`.
#[inline]
pub(crate) fn srgb_encode(v: f32) -> f32 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_rates_are_rationals() {
        assert_eq!(fps_rational(24.0), (24, 1));
        assert_eq!(fps_rational(23.976), (24000, 1001));
        assert_eq!(fps_rational(24000.0 / 1001.0), (24000, 1001));
        assert_eq!(fps_rational(29.97), (30000, 1001));
        assert_eq!(fps_rational(59.94), (60000, 1001));
        assert_eq!(fps_rational(12.5), (25, 2));
        assert_eq!(fps_rational(7.3), (73, 10));
    }
}
