//! Mesh file formats: OBJ, PLY (ASCII, binary little/big endian), OFF, STL (ASCII, binary).
//!
//! Readers never panic and never allocate from a header's claimed size before checking it
//! against the file's length; errors name the file and the line or element.

use std::path::Path;

use super::{Mesh, MeshError};

/// Read a mesh, choosing the format by extension (case-insensitive). Polygons are fan-triangulated.
/// The result is not yet validated or oriented: [`super::load`] does that.
pub fn read_mesh(path: &Path) -> Result<Mesh, MeshError> {
    let _ = path;
    todo!("mesh io helper")
}

/// Write a mesh as OBJ or PLY (binary little endian) by extension, atomically.
pub fn write_mesh(path: &Path, mesh: &Mesh) -> Result<(), MeshError> {
    let _ = (path, mesh);
    todo!("mesh io helper")
}
