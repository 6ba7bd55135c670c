//! The pixel sampler: where a pixel's rays go and their march jitters, drawn from the pixel's
//! own generator (`item_rng(seed, Stream::Render, pixel)`), so every pixel is the same at any
//! thread count and in every frame (no shimmer in holds).

use rand::RngExt;

use crate::render::camera::{CameraRays, Ray};

/// Ray `k` of pixel `(x, y)` with `samples` rays on a `side × side` stratified grid (the pixel
/// centre when `samples == 1`) and its march jitter, drawn from the pixel's generator in the
/// order [`render_medium`] draws them.
#[inline]
pub(crate) fn pixel_sample(
    cam: &CameraRays,
    (x, y): (u32, u32),
    k: u32,
    (samples, side): (u32, u32),
    rng: &mut impl rand::Rng,
) -> (Ray, f32) {
    if samples == 1 {
        return (cam.pixel_ray(x, y), rng.random());
    }
    let (cx, cy) = ((k % side) as f32, (k / side % side) as f32);
    let (u, v, jitter): (f32, f32, f32) = (rng.random(), rng.random(), rng.random());
    let ray = cam.ray(
        x as f32 + (cx + u) / side as f32,
        y as f32 + (cy + v) / side as f32,
    );
    (ray, jitter)
}
