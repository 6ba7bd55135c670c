//! Memory a frame needs, checked before any work: a shot too large for the machine gets a
//! clear error with the size it would need instead of running until it is killed.
//!
//! In: image size and quality preset. Out: the estimate in bytes, and [`check`] against the
//! memory the operating system reports as available (Linux `/proc/meminfo`; where that cannot
//! be read, only the estimate's own sanity bound applies).

use crate::render::settings::{Quality, QualityPreset};

/// Bytes held per pixel while a frame is rendered and written: the frame (RGB, alpha, depth:
/// 20; the tiles write straight into it), the tone-mapped PNG and its encoding (6), the EXR's
/// channel copies and encoding (40), rounded up.
pub(crate) const BYTES_PER_PIXEL: u64 = 70;

/// Bytes per node of the light grid: the sun's light-aligned grid over the supports' light-space
/// box (depth and transmittance, and the extinction while the sky is built, on up to 1.7× as
/// many nodes: 21), a 27th of a coarse sky node (26 `u16` depths, extinction and up to 7
/// `u16` sweep buffers: 70 / 27), rounded up.
pub(crate) const BYTES_PER_GRID_NODE: u64 = 24;

/// Estimated peak bytes to render and write one `width × height` frame at `quality`.
pub(crate) fn frame_bytes(width: u32, height: u32, quality: &Quality) -> u64 {
    let grid = (quality.shadow_grid as u64 + 3).pow(3);
    width as u64 * height as u64 * BYTES_PER_PIXEL + grid * BYTES_PER_GRID_NODE
}

/// Memory available to this process in bytes, when the system says (Linux `MemAvailable`).
pub(crate) fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Human-readable size (`1.5 GB`).
pub(crate) fn format_bytes(b: u64) -> String {
    let b = b as f64;
    if b >= 1e12 {
        format!("{:.1} TB", b / 1e12)
    } else if b >= 1e9 {
        format!("{:.1} GB", b / 1e9)
    } else {
        format!("{:.0} MB", (b / 1e6).ceil())
    }
}

/// `Ok` unless a `width × height` frame has more pixels than a `u32` index can address; checked
/// when a scene is loaded, whatever machine loads it.
pub(crate) fn check_size(width: u32, height: u32, preset: QualityPreset) -> Result<(), String> {
    let pixels = width as u64 * height as u64;
    if pixels > u32::MAX as u64 {
        return Err(format!(
            "{width}×{height} is {pixels} pixels (at most {} per frame) and would need about {} \
             of memory: lower shot.width/height",
            u32::MAX,
            format_bytes(frame_bytes(width, height, &Quality::preset(preset)))
        ));
    }
    Ok(())
}

/// `Ok` when a `width × height` frame at `quality` fits in the memory available on this
/// machine; otherwise the message says what it needs and what there is. Checked where the
/// frames are rendered (a farm's head node that only loads the scene may have far less).
pub(crate) fn check_available(width: u32, height: u32, quality: &Quality) -> Result<(), String> {
    let need = frame_bytes(width, height, quality);
    match available_bytes() {
        Some(have) if need > have => Err(format!(
            "{width}×{height} needs about {} of memory per frame, {} is available on this \
             machine: lower shot.width/height, or render on a machine with more memory",
            format_bytes(need),
            format_bytes(have)
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_frames_are_refused_with_their_size() {
        let e = check_size(100_000, 100_000, QualityPreset::Final).unwrap_err();
        assert!(e.contains("700.3 GB"), "{e}");
        assert!(check_size(640, 360, QualityPreset::Final).is_ok());
        let final_ = Quality::preset(QualityPreset::Final);
        assert!(check_available(640, 360, &final_).is_ok());
        // 60 000 × 60 000 needs 252 GB: more than any test machine has.
        let e = check_available(60_000, 60_000, &final_).unwrap_err();
        assert!(e.contains("is available on this machine"), "{e}");
        assert_eq!(format_bytes(2_500_000_000), "2.5 GB");
    }
}
