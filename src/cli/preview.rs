//! `nephele preview`: a fast low-resolution turntable of a model or a mesh.
//!
//! In: a model file (`.ron` or the binary codec) or a mesh (OBJ/PLY/OFF/STL or `builtin:NAME`,
//! fitted quickly first). Out: `turntable_0001.png …` and an animated `turntable.gif` in the
//! output folder, and the time per frame on stderr.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use glam::Vec3;
use nephele::blobby::BlobModel;
use nephele::geometry::Aabb;
use nephele::pipeline::{self, FitConfig};
use nephele::render::{self, Camera, CloudMaterial, Quality, RenderSettings, Sky, Sun, output};
use nephele::scene::transform::{TargetTransform, Up};

use super::common::{Report, RunArgs};

/// Arguments of `nephele preview`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A model (.ron or encoded) or a mesh (.obj, .ply, .off, .stl, builtin:NAME) to fit first.
    pub input: String,
    /// Output folder (default `renders/preview-<name>`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Number of turntable frames (one full turn).
    #[arg(long, default_value_t = 36)]
    pub frames: u32,
    /// Size of the frames in pixels: WIDTHxHEIGHT, or one number for a square.
    #[arg(long, value_name = "WxH", default_value = "256", value_parser = parse_frame_size)]
    pub size: (u32, u32),
    /// Blobs of the quick fit (meshes only).
    #[arg(long, default_value_t = 150)]
    pub blobs: usize,
    /// Seed of the quick fit and of the render noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Frames per second of the GIF.
    #[arg(long, default_value_t = 12)]
    pub fps: u32,
    /// The model's up axis, turned to the turntable's up as a scene's `transform.up` does:
    /// x, y, z, -x, -y or -z (a scanned Z-up mesh such as horse.ply needs `--up z`).
    #[arg(long, default_value = "y", value_parser = parse_up)]
    pub up: Up,
    /// `--threads`, `--progress`, `-q`, `-v`.
    #[command(flatten)]
    pub run_args: RunArgs,
}

/// `WxH` (the scene's `--size` rule) or `N` (a square).
fn parse_frame_size(s: &str) -> Result<(u32, u32), String> {
    match s.trim().parse::<u32>() {
        Ok(n) => Ok((n, n)),
        Err(_) => nephele::scene::file::overrides::parse_size(s),
    }
}

fn parse_up(s: &str) -> Result<Up, String> {
    Up::from_name(s)
        .ok_or_else(|| format!("'{s}' is not an axis (use one of {})", Up::NAMES.join(", ")))
}

/// Vertical field of view of the turntable camera, degrees.
const FOV_DEG: f32 = 30.0;
/// Camera elevation above the model's centre, degrees.
const ELEVATION_DEG: f32 = 15.0;

/// Run `nephele preview` on the threads `--threads` asks for.
pub fn run(args: Args) -> anyhow::Result<()> {
    let run_args = args.run_args.clone();
    run_args.install(|| preview(args))?
}

fn preview(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.frames >= 1, "--frames must be at least 1");
    let (width, height) = args.size;
    anyhow::ensure!(
        (8..=4096).contains(&width) && (8..=4096).contains(&height),
        "--size must be between 8 and 4096 pixels a side, got {width}x{height}"
    );
    anyhow::ensure!(args.fps >= 1, "--fps must be at least 1");
    let mut report = args.run_args.report(u64::from(args.frames));
    report.stage("start");
    let mut model = load_or_fit(&args, &report)?;
    TargetTransform {
        up: args.up,
        ..TargetTransform::default()
    }
    .apply(&mut model.blobs);
    let dir = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("renders/preview-{}", short_name(&args.input))));
    let blobs = &model.blobs;
    let bounds = blobs
        .iter()
        .filter(|b| b.is_live())
        .fold(Aabb::EMPTY, |acc, b| acc.union(b.ellipsoid().bounds()));
    anyhow::ensure!(
        !bounds.is_empty(),
        "{}: the model has no live blob",
        args.input
    );
    let diag = model.source.bounds.diagonal();
    let length_scale = if diag.is_finite() && diag > 0.0 {
        diag
    } else {
        bounds.diagonal()
    };

    let bar = report.bar("preview");
    let mut images = Vec::with_capacity(args.frames as usize);
    let mut times = Vec::with_capacity(args.frames as usize);
    // One cloud seen from around it: the frames after the first reuse its light grid.
    let mut renderer = render::FrameRenderer::new();
    for k in 0..args.frames {
        let settings = turntable_settings(&args, bounds, length_scale as f32, k);
        let start = Instant::now();
        let frame = renderer.render(&settings, blobs, &render::FrameOptions::default());
        times.push(start.elapsed().as_secs_f64());
        let path = dir.join(format!("turntable_{:04}.png", k + 1));
        output::write_png(&path, frame, &settings)
            .with_context(|| format!("writing {}", path.display()))?;
        images.push(output::tonemapped(frame, &settings));
        bar.inc(1);
        report.step(k + 1, times[times.len() - 1], false);
        report.detail(format!(
            "frame {:>4}/{}: {:.3} s",
            k + 1,
            args.frames,
            times[times.len() - 1]
        ));
    }
    bar.finish_and_clear();
    let gif = dir.join("turntable.gif");
    write_gif(&gif, images, args.fps).with_context(|| format!("writing {}", gif.display()))?;
    let mean = times.iter().sum::<f64>() / times.len() as f64;
    times.sort_by(f64::total_cmp);
    report.stage("done");
    report.info(format!(
        "{}: {} frames of {width}x{height} ({} live blobs), {:.3} s/frame mean, {:.3} s median",
        dir.display(),
        args.frames,
        model.live_count(),
        mean,
        times[times.len() / 2]
    ));
    Ok(())
}

/// The model named by `args.input`, or a quick fit of the mesh it names.
fn load_or_fit(args: &Args, report: &Report) -> anyhow::Result<BlobModel> {
    let path = Path::new(&args.input);
    if !args.input.starts_with("builtin:") && is_model_file(path) {
        return Ok(nephele::blobby::load_model(path)?);
    }
    let loaded = nephele::mesh::load(&args.input)?;
    for w in &loaded.warnings {
        report.info(format!("warning: {w}"));
    }
    let cfg = FitConfig {
        blobs: args.blobs,
        candidates: 800,
        samples: 20_000,
        seed: args.seed,
        ..FitConfig::default()
    };
    let start = Instant::now();
    let out = pipeline::fit(&cfg, &loaded)?;
    report.info(format!(
        "fitted {} blobs to {} in {:.2} s",
        out.model.blobs.len(),
        args.input,
        start.elapsed().as_secs_f64()
    ));
    Ok(out.model)
}

/// A `.ron` file or a file starting with the blob codec's magic number.
fn is_model_file(path: &Path) -> bool {
    if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ron"))
    {
        return true;
    }
    // Only the first bytes are sniffed (a device or FIFO is not a model); the model or mesh
    // reader then applies its own limit.
    let mut head = [0u8; 8];
    nephele::input::open(path, nephele::input::Limit::Mesh)
        .and_then(|(mut f, _)| std::io::Read::read(&mut f, &mut head))
        .is_ok_and(|n| nephele::blobby::codec::is_encoded(&head[..n]))
}

/// File stem, or the builtin's name.
fn short_name(input: &str) -> String {
    let name = input.strip_prefix("builtin:").unwrap_or(input);
    Path::new(name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "model".into())
}

/// Camera on a circle around the model (frame `k` of `args.frames`), framing its bounding
/// sphere; the sun comes from the viewer's upper left and turns with the camera, so the model
/// appears to spin under fixed studio light.
fn turntable_settings(args: &Args, bounds: Aabb, length_scale: f32, k: u32) -> RenderSettings {
    let center = bounds.center().as_vec3();
    let radius = (0.5 * bounds.diagonal()) as f32;
    let fov = FOV_DEG.to_radians();
    let distance = radius / (0.5 * fov).sin() * 1.02;
    let angle = std::f32::consts::TAU * k as f32 / args.frames as f32;
    let elev = ELEVATION_DEG.to_radians();
    let offset = Vec3::new(
        angle.sin() * elev.cos(),
        elev.sin(),
        angle.cos() * elev.cos(),
    );
    let position = center + offset * distance;
    let forward = (center - position).normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    RenderSettings {
        width: args.size.0,
        height: args.size.1,
        camera: Camera {
            position,
            look_at: center,
            up: Vec3::Y,
            fov_deg: FOV_DEG,
            shift: glam::Vec2::ZERO,
        },
        sun: Sun {
            direction: right * 0.7 - up * 0.6 + forward * 0.3,
            ..Sun::default()
        },
        sky: Sky::default(),
        cloud: CloudMaterial::default(),
        exposure: 0.0,
        length_scale,
        seed: args.seed,
        time: 0.0,
        quality: Quality::preview(),
        base: None,
        surfaces: None,
    }
}

/// Write the frames as a looping GIF, atomically.
fn write_gif(path: &Path, frames: Vec<image::RgbImage>, fps: u32) -> anyhow::Result<()> {
    use image::codecs::gif::{GifEncoder, Repeat};
    let mut bytes = Vec::new();
    {
        let mut enc = GifEncoder::new_with_speed(&mut bytes, 20);
        enc.set_repeat(Repeat::Infinite)?;
        let delay = image::Delay::from_numer_denom_ms(1000, fps);
        enc.encode_frames(frames.into_iter().map(|f| {
            let rgba = image::DynamicImage::ImageRgb8(f).into_rgba8();
            image::Frame::from_parts(rgba, 0, 0, delay)
        }))?;
    }
    nephele::atomic::write_bytes_atomically(path, &bytes)?;
    Ok(())
}
