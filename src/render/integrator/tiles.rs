//! The tile driver: a frame's [`TILE`]-pixel tiles in parallel, each row of tiles writing
//! straight into its band of the frame's buffers (beauty, passes, ID-matte ranks), only the
//! tiles and pixels inside the film's window ([`render_film`]).

use glam::Vec3A;
use rayon::prelude::*;

use crate::render::Frame;
use crate::render::camera::{CameraRays, Frustum};
use crate::render::integrator::PixelResult;
use crate::render::integrator::march::{MotionSum, ScreenMotion};
use crate::render::output::cryptomatte::{Coverage, IdMattes, RANKS, Rank};
use crate::render::output::film::{Film, Region};
use crate::render::settings::RenderSettings;

/// Tile side in pixels.
pub(crate) const TILE: u32 = 16;

/// One row of tiles: the frame's buffers for its [`TILE`] rows of pixels (full width), which
/// its tiles' pixels are written straight into (no per-tile results held for the whole frame:
/// at 1920×1080 they had been 166 MB beside the frame's 41).
struct Band<'a> {
    /// The band's first row.
    y0: u32,
    rgb: &'a mut [[f32; 3]],
    alpha: &'a mut [f32],
    depth: &'a mut [f32],
    /// The render passes' rows, when the film asks for passes.
    passes: Option<PassRows<'a>>,
    /// The ID-matte ranks, when it asks for mattes.
    ranks: Option<&'a mut [[Rank; RANKS]]>,
    /// The motion vectors, when it asks for them.
    motion: Option<&'a mut [[f32; 2]]>,
    /// The `holdout` layer's rows, when the shot has holdouts.
    holdout: Option<&'a mut [f32]>,
    /// The `shadow` layer's rows, with the shadow pass.
    shadow: Option<&'a mut [f32]>,
    /// The `shadow_total` layer's rows, with the shadow pass.
    shadow_total: Option<&'a mut [[f32; 3]]>,
}

/// What a pixel gives the tile driver: its result, the number of rays (the mattes' and
/// motion's weights) and its `shadow_total` (1 without the shadow pass). A `(result, rays)`
/// pair is a pixel without the pass.
pub(crate) struct PixelOut {
    pub(crate) result: PixelResult,
    pub(crate) rays: u32,
    pub(crate) shadow_total: Vec3A,
}

impl From<(PixelResult, u32)> for PixelOut {
    #[inline]
    fn from((result, rays): (PixelResult, u32)) -> PixelOut {
        PixelOut {
            result,
            rays,
            shadow_total: Vec3A::ONE,
        }
    }
}

/// One band's rows of the frame's render passes ([`crate::render::Passes`]).
struct PassRows<'a> {
    sun: &'a mut [[f32; 3]],
    sky: &'a mut [[f32; 3]],
    multiple: &'a mut [[f32; 3]],
}

impl Band<'_> {
    /// Store pixel `i` of the band (row-major within it).
    #[inline]
    fn store(&mut self, i: usize, p: &PixelResult, shadow_total: Vec3A) {
        self.rgb[i] = p.rgb.to_array();
        self.alpha[i] = 1.0 - p.transmittance;
        self.depth[i] = p.depth;
        if let Some(rows) = &mut self.passes {
            rows.sun[i] = p.passes.sun.to_array();
            rows.sky[i] = p.passes.sky.to_array();
            rows.multiple[i] = p.passes.multiple.to_array();
        }
        if let Some(h) = &mut self.holdout {
            h[i] = p.holdout;
        }
        if let Some(s) = &mut self.shadow {
            s[i] = p.shadow;
        }
        if let Some(s) = &mut self.shadow_total {
            s[i] = shadow_total.to_array();
        }
    }
}

/// Render the frame's tiles that meet `film`'s window in parallel, each row of tiles writing
/// into its own part of the frame. Per thread `scratch()` once; per tile `begin_tile(scratch,
/// frustum)` with the whole tile's frustum (so a region's pixels see what the full frame's
/// do); per pixel of the window `pixel(scratch, (x, y), coverage, motion)`, which returns the
/// pixel and the number of rays whose matte weights it added to `coverage` and whose motion
/// to `motion` (summed through `screen`; the vectors are 0 without it), and with the shadow
/// pass its `shadow_total` ([`PixelOut`]). Pixels outside the window stay empty (no cloud).
pub(crate) fn render_film<S: Send, P: Into<PixelOut>>(
    settings: &RenderSettings,
    film: &Film,
    cam: &CameraRays,
    screen: Option<&ScreenMotion<'_>>,
    scratch: impl Fn() -> S + Sync + Send,
    begin_tile: impl Fn(&mut S, &Frustum, &Region) + Sync + Send,
    pixel: impl Fn(&mut S, (u32, u32), &mut Coverage<'_>, &mut MotionSum<'_>) -> P + Sync + Send,
) -> Frame {
    let (w, h) = (settings.width, settings.height);
    let window = film.window(w, h);
    let of_blob = film.mattes.as_ref().map_or(&[][..], |m| &m.of_blob[..]);
    let n = (w * h) as usize;
    let shadow_pass = settings.surfaces.as_ref().is_some_and(|s| s.shadow_pass());
    let mut frame = Frame {
        width: w,
        height: h,
        rgb: vec![[0.0; 3]; n],
        alpha: vec![0.0; n],
        depth: vec![f32::INFINITY; n],
        passes: film
            .passes
            .then(|| Box::new(crate::render::Passes::zeros(n))),
        mattes: film
            .mattes
            .as_ref()
            .map(|m| Box::new(IdMattes::empty(m, n))),
        motion: film.motion.then(|| vec![[0.0; 2]; n]),
        holdout: settings
            .surfaces
            .as_ref()
            .is_some_and(|s| s.has_holdouts())
            .then(|| vec![0.0; n]),
        shadow: shadow_pass.then(|| vec![1.0; n]),
        shadow_total: shadow_pass.then(|| vec![[1.0; 3]; n]),
        region: film.region,
    };
    let band_px = (w * TILE) as usize;
    let bands = h.div_ceil(TILE) as usize;
    let Frame {
        rgb,
        alpha,
        depth,
        passes,
        mattes,
        motion,
        holdout,
        shadow,
        shadow_total,
        ..
    } = &mut frame;
    let holdout = optional_rows(holdout, band_px, bands);
    let shadow = optional_rows(shadow, band_px, bands);
    let shadow_total = optional_rows(shadow_total, band_px, bands);
    let passes: Vec<Option<PassRows>> = match passes {
        Some(p) => {
            let crate::render::Passes { sun, sky, multiple } = &mut **p;
            sun.chunks_mut(band_px)
                .zip(sky.chunks_mut(band_px))
                .zip(multiple.chunks_mut(band_px))
                .map(|((sun, sky), multiple)| Some(PassRows { sun, sky, multiple }))
                .collect()
        }
        None => (0..bands).map(|_| None).collect(),
    };
    let ranks: Vec<Option<&mut [[Rank; RANKS]]>> = match mattes {
        Some(m) => m.ranks.chunks_mut(band_px).map(Some).collect(),
        None => (0..bands).map(|_| None).collect(),
    };
    let motion: Vec<Option<&mut [[f32; 2]]>> = match motion {
        Some(m) => m.chunks_mut(band_px).map(Some).collect(),
        None => (0..bands).map(|_| None).collect(),
    };
    let bands: Vec<Band> = rgb
        .chunks_mut(band_px)
        .zip(alpha.chunks_mut(band_px))
        .zip(depth.chunks_mut(band_px))
        .zip(passes.into_iter().zip(ranks).zip(motion))
        .zip(holdout.into_iter().zip(shadow).zip(shadow_total))
        .enumerate()
        .map(
            |(
                k,
                (
                    (((rgb, alpha), depth), ((passes, ranks), motion)),
                    ((holdout, shadow), shadow_total),
                ),
            )| Band {
                y0: k as u32 * TILE,
                rgb,
                alpha,
                depth,
                passes,
                ranks,
                motion,
                holdout,
                shadow,
                shadow_total,
            },
        )
        .collect();
    let tx = w.div_ceil(TILE);
    bands
        .into_par_iter()
        .for_each_init(scratch, |scratch, mut band| {
            let y0 = band.y0;
            for t in 0..tx {
                let whole = Region {
                    x0: t * TILE,
                    y0,
                    x1: ((t + 1) * TILE).min(w),
                    y1: (y0 + TILE).min(h),
                };
                let Some(part) = window.intersect(&whole) else {
                    continue;
                };
                begin_tile(
                    scratch,
                    &cam.frustum(whole.x0, whole.y0, whole.x1, whole.y1),
                    &whole,
                );
                for y in part.y0..part.y1 {
                    for x in part.x0..part.x1 {
                        let mut coverage = Coverage::new(of_blob);
                        let mut motion = MotionSum::new(screen);
                        let out: PixelOut =
                            pixel(scratch, (x, y), &mut coverage, &mut motion).into();
                        let rays = out.rays;
                        let i = ((y - y0) * w + x) as usize;
                        band.store(i, &out.result, out.shadow_total);
                        if let Some(r) = &mut band.ranks {
                            r[i] = coverage.ranks(rays);
                        }
                        if let Some(m) = &mut band.motion {
                            m[i] = motion.vector(rays, band.alpha[i]);
                        }
                    }
                }
            }
        });
    frame
}

/// The bands' rows of an optional layer (`None` per band without it).
fn optional_rows<T>(v: &mut Option<Vec<T>>, band_px: usize, bands: usize) -> Vec<Option<&mut [T]>> {
    match v {
        Some(v) => v.chunks_mut(band_px).map(Some).collect(),
        None => (0..bands).map(|_| None).collect(),
    }
}
