//! Procedural shapes generated in code (`builtin:NAME`), so every scene runs on a fresh clone.
//!
//! In: a name. Out: a closed, outward-oriented [`Mesh`], +Y up, centred near the origin, about
//! 2 units across. Exact solids are built directly (icosphere, swept tube); the toy figures are
//! smooth unions of ellipsoids polygonized by [`super::marching_cubes`].

mod decimate;
mod figures;
mod icosphere;
pub use icosphere::icosphere;
mod knot;
mod sdf;
mod waving;
pub use waving::{WAVING_FRAMES, waving_tube, waving_tube_frames};

use glam::DVec3;

use super::{Mesh, MeshError};

/// Names accepted by [`builtin`].
pub const NAMES: &[&str] = &[
    "sphere",
    "ellipsoid",
    "torus-knot",
    "duck",
    "bunny-toy",
    "waving-tube",
];

/// Names of the builtin shapes that deform over frames (a mesh sequence of one topology; see
/// [`crate::mesh::sequence`]); as a single mesh each is its rest frame.
pub const DEFORMING: &[&str] = &["waving-tube"];

/// Semi-axes of `builtin:ellipsoid` (x, y, z).
pub const ELLIPSOID_SEMI_AXES: DVec3 = DVec3::new(1.5, 1.0, 0.6);

/// Subdivision level of the icospheres: 20·4⁴ = 5120 triangles, volume within 0.5 % of the
/// smooth solid.
const ICOSPHERE_LEVEL: u32 = 4;

/// Generate the named closed, outward-oriented shape. Shapes are centred near the origin,
/// +Y up, about 2 units across:
///
/// - `sphere`: icosphere of radius 1 (vertices on the sphere);
/// - `ellipsoid`: the same icosphere scaled to semi-axes [`ELLIPSOID_SEMI_AXES`];
/// - `torus-knot`: a thin tube around a (2,3) torus knot (trefoil), genus 1;
/// - `duck`: a rubber duck facing +X (body, head, beak, tail, flat base);
/// - `bunny-toy`: a sitting toy rabbit facing +X (body, head, two long ears, tail, feet);
/// - `waving-tube`: a round-ended tube standing on +Y, the rest frame of a tube whose centre
///   line waves over [`WAVING_FRAMES`] frames ([`waving_tube_frames`]).
pub fn builtin(name: &str) -> Result<Mesh, MeshError> {
    match name {
        "sphere" => Ok(icosphere::icosphere(ICOSPHERE_LEVEL)),
        "ellipsoid" => {
            let mut m = icosphere::icosphere(ICOSPHERE_LEVEL);
            // A positive scale keeps the winding outward.
            for p in &mut m.positions {
                *p *= ELLIPSOID_SEMI_AXES;
            }
            Ok(m)
        }
        "torus-knot" => Ok(knot::torus_knot()),
        "duck" => Ok(figures::duck()),
        "bunny-toy" => Ok(figures::bunny_toy()),
        "waving-tube" => Ok(waving::waving_tube(0)),
        _ => Err(MeshError::UnknownBuiltin {
            name: name.to_string(),
            known: NAMES.join(", "),
        }),
    }
}
