//! Frame files: linear HDR OpenEXR (RGBA, plus depth) and tone-mapped sRGB PNG over the sky.
//! Both are written atomically.

use std::path::Path;

use super::{Frame, RenderSettings};

/// Write `frame` as an OpenEXR file with R, G, B, A (and Z depth) channels, atomically.
pub fn write_exr(path: &Path, frame: &Frame) -> std::io::Result<()> {
    let _ = (path, frame);
    todo!("render helper")
}

/// Write `frame` composited over the sky, exposed and tone-mapped to 8-bit sRGB, atomically.
pub fn write_png(path: &Path, frame: &Frame, settings: &RenderSettings) -> std::io::Result<()> {
    let _ = (path, frame, settings);
    todo!("render helper")
}
