//! `builtin:waving-tube`: a deforming shape generated in code, for deforming targets (a
//! [`crate::mesh::sequence::MeshSequence`]) without any file: a closed, round-ended tube
//! standing on +Y whose centre line waves in the XY plane (facing a camera on +Z), one period
//! over [`WAVING_FRAMES`] frames, with one topology (the same vertices in the same order) in
//! every frame.
//!
//! The centre line is parametrised by arc length `s ∈ [0, L]` from a fixed base: its tangent
//! turns from +Y by `θ(s, k) = AMPLITUDE · (s/L) · sin(2πk/N − π·s/L)` (a wave running up the
//! tube, stronger towards the tip, like a tentacle or a stalk in a current), so its length is
//! kept in every frame (a bend, not a stretch). Rings are circles of radius `r(u)`,
//! `u = s/L`, that close at two poles (`r = R·(1 + b·cos 2πmu)·√(1 − (2u − 1)⁴)`: six bulges
//! like a caterpillar's segments, so that the fit places blobs along it that the wave must
//! carry apart, and round ends). Frame 0 is
//! the rest frame (the one a shot fits); the shape is shifted so that the rest frame's box is
//! centred on the origin.

use std::f64::consts::{PI, TAU};

use glam::DVec3;

use crate::mesh::Mesh;

/// Frames of the deformation (one period of the wave; frame `N` would equal frame 0).
pub const WAVING_FRAMES: usize = 48;

/// Length of the centre line.
const LENGTH: f64 = 2.2;
/// Radius of the tube at its middle.
const RADIUS: f64 = 0.3;
/// Largest turn of the tangent (radians) at the tip.
const AMPLITUDE: f64 = 1.1;
/// Rings between the two poles.
const RINGS: usize = 72;
/// Vertices around each ring.
const SIDES: usize = 24;
/// Integration steps of the centre line per ring.
const SUBSTEPS: usize = 8;

/// The angle of the tangent from +Y at arc-length fraction `u` in frame `k`.
fn turn(u: f64, k: f64) -> f64 {
    AMPLITUDE * u * (TAU * k / WAVING_FRAMES as f64 - PI * u).sin()
}

/// Bulges along the tube (segments, as a caterpillar's or a tentacle's).
const SEGMENTS: f64 = 6.0;
/// Depth of the bulges, as a fraction of the radius.
const BULGE: f64 = 0.22;

/// The tube's radius at arc-length fraction `u`.
fn radius(u: f64) -> f64 {
    let segments = 1.0 + BULGE * (TAU * SEGMENTS * u).cos();
    RADIUS * segments * (1.0 - (2.0 * u - 1.0).powi(4)).max(0.0).sqrt()
}

/// The centre line's points and tangent angles at the `RINGS + 2` stations (the two poles and
/// the rings), base at the origin, for frame `k` (any real `k`: the wave is smooth in time).
fn centre_line(k: f64) -> Vec<(f64, DVec3, f64)> {
    let stations = RINGS + 2;
    let mut out = Vec::with_capacity(stations);
    let mut p = DVec3::ZERO;
    let h = 1.0 / ((stations - 1) * SUBSTEPS) as f64;
    for i in 0..stations {
        let u = i as f64 / (stations - 1) as f64;
        out.push((u, p, turn(u, k)));
        if i + 1 < stations {
            // Midpoint rule along the arc: the tangent is (sin θ, cos θ, 0).
            for j in 0..SUBSTEPS {
                let um = u + (j as f64 + 0.5) * h;
                let th = turn(um, k);
                p += DVec3::new(th.sin(), th.cos(), 0.0) * (LENGTH * h);
            }
        }
    }
    out
}

/// The shift that centres the rest frame's box on the origin (the same in every frame).
fn shift() -> DVec3 {
    let rest = positions(0.0, DVec3::ZERO);
    let b = crate::geometry::Aabb::from_points(&rest);
    -b.center()
}

/// Vertex positions of frame `k` moved by `offset`: the bottom pole, the rings bottom to top
/// (`SIDES` each), the top pole.
fn positions(k: f64, offset: DVec3) -> Vec<DVec3> {
    let line = centre_line(k);
    let mut out = Vec::with_capacity(RINGS * SIDES + 2);
    out.push(line[0].1 + offset);
    for &(u, c, th) in &line[1..=RINGS] {
        // Normal in the plane of the bend and the binormal −Z, so that (normal, binormal)
        // turns counter-clockwise about the tangent (the side triangles wind outward).
        let n = DVec3::new(th.cos(), -th.sin(), 0.0);
        let b = DVec3::NEG_Z;
        let r = radius(u);
        for j in 0..SIDES {
            let phi = TAU * j as f64 / SIDES as f64;
            out.push(c + offset + r * (phi.cos() * n + phi.sin() * b));
        }
    }
    out.push(line[RINGS + 1].1 + offset);
    out
}

/// The triangles shared by every frame (outward).
fn triangles() -> Vec<[u32; 3]> {
    let id = |i: usize, j: usize| (1 + i * SIDES + j % SIDES) as u32;
    let (bottom, top) = (0u32, (1 + RINGS * SIDES) as u32);
    let mut t = Vec::with_capacity(2 * RINGS * SIDES);
    for j in 0..SIDES {
        t.push([bottom, id(0, j + 1), id(0, j)]);
    }
    for i in 0..RINGS - 1 {
        for j in 0..SIDES {
            let (a, b, c, d) = (id(i, j), id(i, j + 1), id(i + 1, j + 1), id(i + 1, j));
            t.push([a, b, c]);
            t.push([a, c, d]);
        }
    }
    for j in 0..SIDES {
        t.push([top, id(RINGS - 1, j), id(RINGS - 1, j + 1)]);
    }
    t
}

/// Frame `k` (0-based; frame 0 is the rest frame) of the waving tube: a closed, outward mesh
/// about 2.3 units tall, the same vertices and triangles in every frame.
pub fn waving_tube(k: usize) -> Mesh {
    Mesh {
        positions: positions(k as f64, shift()),
        triangles: triangles(),
    }
}

/// All [`WAVING_FRAMES`] frames' vertex positions and the shared triangles.
pub fn waving_tube_frames() -> (Vec<Vec<DVec3>>, Vec<[u32; 3]>) {
    let offset = shift();
    let frames = (0..WAVING_FRAMES)
        .map(|k| positions(k as f64, offset))
        .collect();
    (frames, triangles())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_frame_is_closed_outward_and_keeps_its_length() {
        let (frames, tris) = waving_tube_frames();
        let rest_volume = waving_tube(0).signed_volume();
        assert!(rest_volume > 0.0, "outward: {rest_volume}");
        for (k, p) in frames.iter().enumerate() {
            let m = Mesh {
                positions: p.clone(),
                triangles: tris.clone(),
            };
            assert_eq!(m.boundary_edge_count(), 0);
            // A bend keeps the volume (to the rings' discretisation).
            let v = m.signed_volume();
            assert!(
                (v / rest_volume - 1.0).abs() < 0.02,
                "frame {k}: {v} vs {rest_volume}"
            );
        }
        // It moves: the tip travels far between the extremes of the wave.
        let top = 1 + RINGS * SIDES;
        let reach = frames
            .iter()
            .map(|p| (p[top] - frames[0][top]).length())
            .fold(0.0, f64::max);
        assert!(reach > 0.8, "tip travel {reach}");
    }
}
