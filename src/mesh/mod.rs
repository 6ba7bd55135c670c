//! Triangle meshes: the in-memory type, loading (files and `builtin:` shapes), orientation repair,
//! surface sampling and quadric simplification.
//!
//! In: a path or `builtin:NAME`. Out: a validated [`Mesh`] (finite positions, in-range indices,
//! outward orientation) plus the warnings raised while loading.

pub mod builtin;
pub mod io;
pub mod marching_cubes;
pub mod sample;
pub mod sequence;
pub mod simplify;
pub mod winding;

use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::geometry::Aabb;

/// Everything that can go wrong when reading or validating a mesh.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// The file's content is malformed at a known place.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// File concerned.
        path: PathBuf,
        /// 1-based line (text formats) or element number (binary formats).
        line: usize,
        /// What is wrong and, where possible, what would fix it.
        message: String,
    },
    /// The file parsed but the mesh is unusable (empty, NaN coordinates, bad indices...).
    #[error("{path}: {message}")]
    Invalid {
        /// File concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The extension is not one of .obj, .ply, .off, .stl.
    #[error("{path}: unknown mesh format (expected .obj, .ply, .off or .stl, or builtin:NAME)")]
    UnknownFormat {
        /// File concerned.
        path: PathBuf,
    },
    /// `builtin:NAME` with an unknown name.
    #[error("unknown builtin shape '{name}' (known: {known})")]
    UnknownBuiltin {
        /// The name asked for.
        name: String,
        /// Comma-separated list of valid names.
        known: String,
    },
}

/// An indexed triangle mesh in f64, in the file's own units.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Triangles as counter-clockwise (seen from outside) vertex index triples.
    pub triangles: Vec<[u32; 3]>,
}

/// A mesh as loaded, with the notes a user should see (orientation fixed, open boundary...).
#[derive(Clone, Debug)]
pub struct LoadedMesh {
    /// The validated, outward-oriented mesh.
    pub mesh: Mesh,
    /// Human-readable warnings raised while loading (already prefixed with the source name).
    pub warnings: Vec<String>,
    /// The name it was loaded from (a path or `builtin:NAME`).
    pub source: String,
}

impl Mesh {
    /// Bounding box of the vertices.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.positions)
    }

    /// The three corners of triangle `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Signed volume (divergence theorem); positive when faces wind outward.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                a.dot(b.cross(c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.corners(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Reverse every triangle's winding.
    pub fn flip_orientation(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Unit vertex normals, the area-weighted average of incident face normals (zero for
    /// isolated vertices). This is the one smooth normal field used by sampling and seeding.
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut n = vec![DVec3::ZERO; self.positions.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = self.corners(t);
            // Cross product length is twice the area: area weighting for free.
            let face = (b - a).cross(c - a);
            for &v in tri {
                n[v as usize] += face;
            }
        }
        n.iter().map(|v| v.normalize_or_zero()).collect()
    }

    /// Number of edges used by exactly one triangle (0 for a closed mesh).
    pub fn boundary_edge_count(&self) -> usize {
        let mut edges: Vec<(u32, u32)> = self
            .triangles
            .iter()
            .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
            .map(|(a, b)| (a.min(b), a.max(b)))
            .collect();
        edges.sort_unstable();
        let mut count = 0;
        let mut i = 0;
        while i < edges.len() {
            let mut j = i + 1;
            while j < edges.len() && edges[j] == edges[i] {
                j += 1;
            }
            if j - i == 1 {
                count += 1;
            }
            i = j;
        }
        count
    }

    /// Check that the mesh is usable: non-empty, finite coordinates, in-range indices,
    /// non-zero area. `path` only names the source in the error.
    pub fn validate(&self, path: &Path) -> Result<(), MeshError> {
        let invalid = |message: String| MeshError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        if self.positions.is_empty() || self.triangles.is_empty() {
            return Err(invalid(format!(
                "mesh is empty ({} vertices, {} triangles)",
                self.positions.len(),
                self.triangles.len()
            )));
        }
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(invalid(format!(
                "vertex {} has a non-finite coordinate {:?}",
                i + 1,
                self.positions[i]
            )));
        }
        let n = self.positions.len() as u32;
        if let Some(t) = self
            .triangles
            .iter()
            .position(|t| t.iter().any(|&v| v >= n))
        {
            return Err(invalid(format!(
                "triangle {} references vertex {:?} but there are only {} vertices",
                t + 1,
                self.triangles[t],
                n
            )));
        }
        let d = self.bounds().diagonal();
        if self.area().is_nan() || self.area() <= 1e-12 * d * d || d == 0.0 {
            return Err(invalid("mesh has zero surface area".into()));
        }
        Ok(())
    }
}

/// Load a mesh from a file (OBJ, PLY, OFF, STL by extension) or a `builtin:NAME` shape;
/// validate it and make it outward-oriented. Open meshes load with a warning.
pub fn load(source: &str) -> Result<LoadedMesh, MeshError> {
    let mesh = if let Some(name) = source.strip_prefix("builtin:") {
        builtin::builtin(name)?
    } else {
        io::read_mesh(Path::new(source))?
    };
    prepare(mesh, source)
}

/// A mesh already in memory (e.g. a deforming target's rest frame) made ready as [`load`]
/// makes a file's: validated and outward-oriented, with the same warnings. `source` names it.
pub fn prepare(mut mesh: Mesh, source: &str) -> Result<LoadedMesh, MeshError> {
    let path = PathBuf::from(source);
    mesh.validate(&path)?;
    let mut warnings = Vec::new();
    let open_edges = mesh.boundary_edge_count();
    if open_edges > 0 {
        warnings.push(format!(
            "{source}: mesh is open ({open_edges} boundary edges); the fit takes the solid its winding number describes (holes closed smoothly); `eval` measures it one-sided, mesh -> model"
        ));
    }
    // Closed: the signed volume (the integral of the winding number, cheap). Open: the
    // winding number across the faces (the signed volume then depends on the origin).
    let (inward, why) = if open_edges == 0 {
        (mesh.signed_volume() < 0.0, "negative signed volume")
    } else {
        let w = winding::orientation(&mesh, &winding::WindingNumber::new(&mesh), 4096);
        (w < 0.0, "negative winding number behind the faces")
    };
    if inward {
        mesh.flip_orientation();
        warnings.push(format!(
            "{source}: faces were wound inward ({why}); flipped them"
        ));
    }
    Ok(LoadedMesh {
        mesh,
        warnings,
        source: source.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit tetrahedron, outward.
    pub(crate) fn tetra() -> Mesh {
        Mesh {
            positions: vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        }
    }

    #[test]
    fn tetra_volume_and_closure() {
        let m = tetra();
        assert!((m.signed_volume() - 1.0 / 6.0).abs() < 1e-12);
        assert_eq!(m.boundary_edge_count(), 0);
        let mut f = m.clone();
        f.flip_orientation();
        assert!((f.signed_volume() + 1.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn validate_rejects_bad_index_and_nan() {
        let mut m = tetra();
        m.triangles[1][2] = 9;
        let e = m.validate(Path::new("x.obj")).unwrap_err().to_string();
        assert!(e.contains("triangle 2") && e.contains("x.obj"), "{e}");
        let mut m = tetra();
        m.positions[2].y = f64::NAN;
        let e = m.validate(Path::new("x.obj")).unwrap_err().to_string();
        assert!(e.contains("vertex 3"), "{e}");
    }
}
