//! Procedural shapes generated in code (`builtin:NAME`), so every scene runs on a fresh clone.

use super::{Mesh, MeshError};

/// Names accepted by [`builtin`].
pub const NAMES: &[&str] = &["sphere", "ellipsoid", "torus-knot", "duck"];

/// Generate the named closed, outward-oriented shape. Shapes are centred near the origin,
/// +Y up, about 2 units across.
pub fn builtin(name: &str) -> Result<Mesh, MeshError> {
    let _ = name;
    todo!("builtin helper")
}
