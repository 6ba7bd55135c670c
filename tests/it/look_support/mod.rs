//! How a frame reads against its target (issue 21's measures): the silhouette IoU of the
//! rendered coverage (alpha > 0.5) with the target model's own silhouette (its blob surface
//! polygonized and projected through the frame's camera), and the outline excess, the contour
//! length of the mask over that of the same mask opened, closed and smoothed at 1/40 of its
//! extent (1.00 for a smooth outline; billows raise it).

#![allow(dead_code)]

use glam::Vec3A;
use nephele::blobby::{Blob, BlobField, THRESHOLD, polygonize::polygonize};
use nephele::render::CameraRays;
use nephele::render::RenderSettings;

/// A binary image, row-major.
#[derive(Clone, Debug)]
pub struct Mask {
    /// Width in pixels.
    pub w: usize,
    /// Height in pixels.
    pub h: usize,
    /// Pixel values.
    pub px: Vec<bool>,
}

impl Mask {
    /// Pixels whose alpha exceeds 0.5.
    pub fn from_alpha(alpha: &[f32], w: usize, h: usize) -> Mask {
        Mask {
            w,
            h,
            px: alpha.iter().map(|&a| a > 0.5).collect(),
        }
    }

    /// Share of the image covered.
    pub fn coverage(&self) -> f64 {
        self.px.iter().filter(|&&b| b).count() as f64 / self.px.len() as f64
    }

    /// Largest side of the bounding box of the set pixels (0 when empty).
    pub fn extent(&self) -> usize {
        let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
        for y in 0..self.h {
            for x in 0..self.w {
                if self.px[y * self.w + x] {
                    (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
                }
            }
        }
        if x0 == usize::MAX {
            0
        } else {
            (x1 - x0).max(y1 - y0) + 1
        }
    }
}

/// Intersection over union of two masks of the same size.
pub fn iou(a: &Mask, b: &Mask) -> f64 {
    let (mut i, mut u) = (0usize, 0usize);
    for (&p, &q) in a.px.iter().zip(&b.px) {
        i += (p && q) as usize;
        u += (p || q) as usize;
    }
    if u == 0 { 1.0 } else { i as f64 / u as f64 }
}

/// The target model's silhouette: the blob surface of `blobs` polygonized (`resolution` cells
/// along its longest side) and projected through the camera of `s`.
pub fn model_mask(s: &RenderSettings, blobs: &[Blob], resolution: usize) -> Mask {
    let field = BlobField::new(blobs, THRESHOLD);
    let mesh = polygonize(&field, resolution);
    project_mesh(s, &mesh)
}

/// Pixels whose centre is covered by the projection of `mesh` through the camera of `s`.
pub fn project_mesh(s: &RenderSettings, mesh: &nephele::mesh::Mesh) -> Mask {
    let (w, h) = (s.width as usize, s.height as usize);
    let cam = CameraRays::new(&s.camera, s.width, s.height);
    let centre = cam.dir(0.5 * w as f32, 0.5 * h as f32);
    let dx = cam.dir(0.5 * w as f32 + 1.0, 0.5 * h as f32) - centre;
    let dy = cam.dir(0.5 * w as f32, 0.5 * h as f32 + 1.0) - centre;
    let project = |p: glam::DVec3| {
        let v = Vec3A::from(p.as_vec3()) - cam.position;
        let v = v / v.dot(centre);
        let r = v - centre;
        (
            0.5 * w as f32 + r.dot(dx) / dx.length_squared(),
            0.5 * h as f32 + r.dot(dy) / dy.length_squared(),
        )
    };
    let pts: Vec<(f32, f32)> = mesh.positions.iter().map(|&p| project(p)).collect();
    let mut px = vec![false; w * h];
    let cross = |p: (f32, f32), q: (f32, f32), r: (f32, f32)| {
        (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0)
    };
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| pts[i as usize]);
        let (x0, x1) = (a.0.min(b.0).min(c.0), a.0.max(b.0).max(c.0));
        let (y0, y1) = (a.1.min(b.1).min(c.1), a.1.max(b.1).max(c.1));
        if x1 < 0.0 || y1 < 0.0 || x0 > w as f32 || y0 > h as f32 {
            continue;
        }
        let area = cross(a, b, c);
        for y in (y0.floor().max(0.0) as usize)..=(y1.ceil().min(h as f32 - 1.0) as usize) {
            for x in (x0.floor().max(0.0) as usize)..=(x1.ceil().min(w as f32 - 1.0) as usize) {
                let p = (x as f32 + 0.5, y as f32 + 0.5);
                let (u, v, z) = (cross(b, c, p), cross(c, a, p), cross(a, b, p));
                let inside = if area >= 0.0 {
                    u >= 0.0 && v >= 0.0 && z >= 0.0
                } else {
                    u <= 0.0 && v <= 0.0 && z <= 0.0
                };
                px[y * w + x] |= inside;
            }
        }
    }
    Mask { w, h, px }
}

/// Offsets of a disc of radius `r` pixels.
fn disc(r: f64) -> Vec<(i64, i64)> {
    let k = r.ceil() as i64;
    let mut out = Vec::new();
    for y in -k..=k {
        for x in -k..=k {
            if ((x * x + y * y) as f64) <= r * r {
                out.push((x, y));
            }
        }
    }
    out
}

/// Dilation (`grow`) or erosion of `m` by the disc `d` (outside the image counts as empty).
fn morph(m: &Mask, d: &[(i64, i64)], grow: bool) -> Mask {
    let (w, h) = (m.w as i64, m.h as i64);
    let at = |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h && m.px[(y * w + x) as usize];
    let mut px = vec![false; m.px.len()];
    for y in 0..h {
        for x in 0..w {
            px[(y * w + x) as usize] = if grow {
                d.iter().any(|&(ox, oy)| at(x + ox, y + oy))
            } else {
                d.iter().all(|&(ox, oy)| at(x + ox, y + oy))
            };
        }
    }
    Mask { w: m.w, h: m.h, px }
}

/// Separable Gaussian blur (σ pixels) of the mask as 0/1 values.
fn blur(m: &Mask, sigma: f64) -> Vec<f64> {
    let k = (3.0 * sigma).ceil().max(1.0) as i64;
    let wts: Vec<f64> = (-k..=k)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let norm: f64 = wts.iter().sum();
    let (w, h) = (m.w as i64, m.h as i64);
    let src: Vec<f64> = m.px.iter().map(|&b| b as u8 as f64).collect();
    let mut tmp = vec![0.0; src.len()];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (j, i) in (-k..=k).enumerate() {
                let xx = x + i;
                if xx >= 0 && xx < w {
                    s += wts[j] * src[(y * w + xx) as usize];
                }
            }
            tmp[(y * w + x) as usize] = s / norm;
        }
    }
    let mut out = vec![0.0; src.len()];
    for y in 0..h {
        for x in 0..w {
            let mut s = 0.0;
            for (j, i) in (-k..=k).enumerate() {
                let yy = y + i;
                if yy >= 0 && yy < h {
                    s += wts[j] * tmp[(yy * w + x) as usize];
                }
            }
            out[(y * w + x) as usize] = s / norm;
        }
    }
    out
}

/// Length (pixels) of the 0.5 iso-contour of `v` (marching squares between pixel centres).
fn contour_length(v: &[f64], w: usize, h: usize) -> f64 {
    let at = |x: usize, y: usize| v[y * w + x] - 0.5;
    let cut = |a: f64, b: f64| a / (a - b);
    let mut len = 0.0;
    for y in 0..h.saturating_sub(1) {
        for x in 0..w.saturating_sub(1) {
            let c = [at(x, y), at(x + 1, y), at(x + 1, y + 1), at(x, y + 1)];
            let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
            let mut pts: Vec<(f64, f64)> = Vec::with_capacity(4);
            for e in 0..4 {
                let (a, b) = (c[e], c[(e + 1) % 4]);
                if (a > 0.0) != (b > 0.0) {
                    let s = cut(a, b);
                    let (p, q) = (corners[e], corners[(e + 1) % 4]);
                    pts.push((p.0 + s * (q.0 - p.0), p.1 + s * (q.1 - p.1)));
                }
            }
            let d = |p: (f64, f64), q: (f64, f64)| (p.0 - q.0).hypot(p.1 - q.1);
            match pts.len() {
                2 => len += d(pts[0], pts[1]),
                4 => len += d(pts[0], pts[1]) + d(pts[2], pts[3]),
                _ => {}
            }
        }
    }
    len
}

/// Outline excess of `m`: contour length over that of `m` opened, closed and smoothed at 1/40
/// of its extent (`None` when the mask is too small to measure).
pub fn outline_excess(m: &Mask) -> Option<f64> {
    let r = m.extent() as f64 / 40.0;
    if r < 1.0 {
        return None;
    }
    let d = disc(r);
    let opened = morph(&morph(m, &d, false), &d, true);
    let closed = morph(&morph(&opened, &d, true), &d, false);
    let smooth = blur(&closed, r);
    let raw: Vec<f64> = m.px.iter().map(|&b| b as u8 as f64).collect();
    let base = contour_length(&smooth, m.w, m.h);
    (base > 0.0).then(|| contour_length(&raw, m.w, m.h) / base)
}
