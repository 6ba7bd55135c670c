//! Mesh file formats: OBJ, PLY (ASCII, binary little/big endian), OFF, STL (ASCII, binary).
//!
//! In: a path (format chosen by extension) or a byte slice plus a [`MeshFormat`].
//! Out: an unvalidated [`Mesh`] (polygons fan-triangulated, degenerate triangles dropped) or a
//! [`MeshError`] naming the file and the 1-based line (text) or element number (binary).
//!
//! Readers take the whole file as one byte slice, never panic on any input, and never allocate
//! from a header's claimed count before checking it against the bytes that are actually there:
//! every record has a minimum size, so a count that cannot fit in the file is refused up front.

mod obj;
mod off;
mod ply;
mod ply_header;
mod stl;
mod text;
mod write;

use std::path::{Path, PathBuf};

use glam::DVec3;

use super::{Mesh, MeshError};

pub use write::write_mesh;

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

/// Read a mesh, choosing the format by extension (case-insensitive). Polygons are fan-triangulated.
/// The result is not yet validated or oriented: [`super::load`] does that.
pub fn read_mesh(path: &Path) -> Result<Mesh, MeshError> {
    let format = MeshFormat::from_path(path)?;
    let bytes = std::fs::read(path).map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_mesh_bytes(&bytes, format, path)
}

/// Parse a whole mesh file held in memory. `path` only names the source in errors.
///
/// Returns an error for empty input and for a file that yields no triangle; otherwise the mesh
/// has finite coordinates and in-range indices, but is not checked for area or orientation.
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
    if mesh.triangles.is_empty() {
        return Err(invalid(
            path,
            format!(
                "no usable triangle ({} vertices, 0 non-degenerate faces)",
                mesh.positions.len()
            ),
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

/// Accumulates vertices and polygons into a [`Mesh`]: fan triangulation, degenerate triangles
/// (a repeated index) dropped. Index range checks are the caller's job.
#[derive(Default)]
pub(crate) struct MeshBuilder {
    mesh: Mesh,
}

impl MeshBuilder {
    /// An empty builder with room for `vertices` and `triangles` (callers pass counts already
    /// checked against the file size).
    pub(crate) fn with_capacity(vertices: usize, triangles: usize) -> MeshBuilder {
        MeshBuilder {
            mesh: Mesh {
                positions: Vec::with_capacity(vertices),
                triangles: Vec::with_capacity(triangles),
            },
        }
    }

    /// Number of vertices pushed so far.
    pub(crate) fn vertex_count(&self) -> usize {
        self.mesh.positions.len()
    }

    /// Add a vertex; `Err` with a message when a coordinate is NaN or infinite.
    pub(crate) fn push_vertex(&mut self, p: [f64; 3]) -> Result<(), String> {
        if !p.iter().all(|c| c.is_finite()) {
            return Err(format!("non-finite vertex coordinate {p:?}"));
        }
        self.mesh.positions.push(DVec3::from_array(p));
        Ok(())
    }

    /// Add a polygon of at least three vertex indices as a triangle fan around its first
    /// vertex; `Err` with a message for fewer than three.
    pub(crate) fn push_polygon(&mut self, poly: &[u32]) -> Result<(), String> {
        if poly.len() < 3 {
            return Err(format!(
                "face has {} vertices; a face needs at least 3",
                poly.len()
            ));
        }
        let a = poly[0];
        for w in poly[1..].windows(2) {
            let (b, c) = (w[0], w[1]);
            // Degenerate (repeated index): no area, no orientation; drop it.
            if a != b && b != c && a != c {
                self.mesh.triangles.push([a, b, c]);
            }
        }
        Ok(())
    }

    /// The finished mesh.
    pub(crate) fn finish(self) -> Mesh {
        self.mesh
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

    #[test]
    fn fan_triangulation_drops_degenerates() {
        let mut b = MeshBuilder::default();
        b.push_polygon(&[0, 1, 2, 3, 4]).unwrap();
        b.push_polygon(&[5, 5, 6]).unwrap();
        assert!(b.push_polygon(&[1, 2]).is_err());
        assert_eq!(b.finish().triangles, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    }
}
