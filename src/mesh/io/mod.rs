//! Mesh file formats: OBJ, PLY (ASCII, binary little/big endian), OFF, STL (ASCII, binary).
//!
//! In: a path (format chosen by extension) or a byte slice plus a [`MeshFormat`].
//! Out: an indexed [`Mesh`] not yet checked for area or orientation (polygons fan-triangulated,
//! bit-identical positions welded, degenerate triangles and unreferenced vertices dropped) or a
//! [`MeshError`] naming the file and the 1-based line (text) or element number (binary).
//!
//! Readers take the whole file as one byte slice, never panic on any input, and never allocate
//! from a header's claimed count before checking it against the bytes that are actually there:
//! every record has a minimum size, so a count that cannot fit in the file is refused up front.

mod build;
mod obj;
mod off;
mod ply;
mod ply_header;
mod stl;
mod text;
mod write;

use std::path::{Path, PathBuf};

use super::{Mesh, MeshError};

pub use write::write_mesh;

use build::{MeshBuilder, clean_up};

/// The mesh file formats nephele reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum MeshFormat {
    /// Wavefront OBJ (text).
    Obj,
    /// Stanford PLY (ASCII, binary little endian, binary big endian).
    Ply,
    /// Object File Format (text; `OFF`, `COFF`, `NOFF`... headers).
    Off,
    /// Stereolithography (ASCII or binary, detected from the content).
    Stl,
}

impl MeshFormat {
    /// The format named by `path`'s extension (case-insensitive), or
    /// [`MeshError::UnknownFormat`].
    pub fn from_path(path: &Path) -> Result<MeshFormat, MeshError> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "obj" => Ok(MeshFormat::Obj),
            "ply" => Ok(MeshFormat::Ply),
            "off" => Ok(MeshFormat::Off),
            "stl" => Ok(MeshFormat::Stl),
            _ => Err(MeshError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }
}

/// Read a mesh, choosing the format by extension (case-insensitive); see [`parse_mesh_bytes`]
/// for what the result guarantees. It is not yet validated for area or oriented:
/// [`super::load`] does that.
pub fn read_mesh(path: &Path) -> Result<Mesh, MeshError> {
    let format = MeshFormat::from_path(path)?;
    let bytes =
        crate::input::read(path, crate::input::Limit::Mesh).map_err(|source| MeshError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    parse_mesh_bytes(&bytes, format, path)
}

/// Parse a whole mesh file held in memory. `path` only names the source in errors.
///
/// Returns an error for empty input and for a file that yields no triangle. Otherwise the mesh
/// is indexed and clean but not yet checked for area or orientation: finite coordinates,
/// in-range indices, bit-identical positions welded into one vertex (so STL and seam-split
/// files come out connected), no degenerate (repeated-index) triangle, no unreferenced vertex;
/// the remaining vertices keep their file order.
/// Never panics, whatever the bytes.
pub fn parse_mesh_bytes(bytes: &[u8], format: MeshFormat, path: &Path) -> Result<Mesh, MeshError> {
    if bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(invalid(path, "file is empty".into()));
    }
    let mesh = match format {
        MeshFormat::Obj => obj::parse(bytes, path)?,
        MeshFormat::Ply => ply::parse(bytes, path)?,
        MeshFormat::Off => off::parse(bytes, path)?,
        MeshFormat::Stl => stl::parse(bytes, path)?,
    };
    let vertices_in_file = mesh.positions.len();
    let mesh = clean_up(mesh);
    if mesh.triangles.is_empty() {
        return Err(invalid(
            path,
            format!("no usable triangle ({vertices_in_file} vertices, 0 non-degenerate faces)"),
        ));
    }
    Ok(mesh)
}

/// A [`MeshError::Parse`] at `line` (1-based line, or element number for binary data).
pub(crate) fn parse_error(path: &Path, line: usize, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        path: path.to_path_buf(),
        line,
        message: message.into(),
    }
}

/// A [`MeshError::Invalid`] about the whole file.
pub(crate) fn invalid(path: &Path, message: String) -> MeshError {
    MeshError::Invalid {
        path: PathBuf::from(path),
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn format_from_extension_is_case_insensitive() {
        assert_eq!(
            MeshFormat::from_path(Path::new("a/B.PlY")).unwrap(),
            MeshFormat::Ply
        );
        assert_eq!(
            MeshFormat::from_path(Path::new("x.Stl")).unwrap(),
            MeshFormat::Stl
        );
        assert!(matches!(
            MeshFormat::from_path(Path::new("x.glb")),
            Err(MeshError::UnknownFormat { .. })
        ));
        assert!(MeshFormat::from_path(Path::new("noext")).is_err());
    }
}
