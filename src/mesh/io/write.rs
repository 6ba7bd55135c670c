//! Mesh writers: OBJ (text `v`/`f`, shortest round-trip decimals, so f64 positions survive
//! exactly) and PLY (binary little endian, f32 `x y z`, `uchar int` index lists). Files are
//! written atomically.

use std::io::{self, Write};
use std::path::Path;

use super::MeshFormat;
use crate::atomic::write_atomically;
use crate::mesh::{Mesh, MeshError};

/// Write a mesh as OBJ or PLY (binary little endian) by extension, atomically.
/// `.off`/`.stl` and unknown extensions give [`MeshError::UnknownFormat`].
pub fn write_mesh(path: &Path, mesh: &Mesh) -> Result<(), MeshError> {
    let result = match MeshFormat::from_path(path)? {
        MeshFormat::Obj => write_atomically(path, |w| write_obj(w, mesh)),
        MeshFormat::Ply => write_atomically(path, |w| write_ply(w, mesh)),
        MeshFormat::Off | MeshFormat::Stl => {
            return Err(MeshError::UnknownFormat {
                path: path.to_path_buf(),
            });
        }
    };
    result.map_err(|source| MeshError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// OBJ text: one `v x y z` line per vertex, one 1-based `f a b c` line per triangle.
fn write_obj(w: &mut impl Write, mesh: &Mesh) -> io::Result<()> {
    writeln!(w, "# written by nephele")?;
    writeln!(
        w,
        "# {} vertices, {} triangles",
        mesh.positions.len(),
        mesh.triangles.len()
    )?;
    for p in &mesh.positions {
        // `{}` on f64 prints the shortest string that parses back to the same value.
        writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for [a, b, c] in &mesh.triangles {
        writeln!(w, "f {} {} {}", *a as u64 + 1, *b as u64 + 1, *c as u64 + 1)?;
    }
    Ok(())
}

/// Binary little-endian PLY with f32 positions and `uchar`-counted `int` index lists.
fn write_ply(w: &mut impl Write, mesh: &Mesh) -> io::Result<()> {
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment written by nephele\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mesh.positions.len(),
        mesh.triangles.len()
    )?;
    for p in &mesh.positions {
        for c in [p.x, p.y, p.z] {
            w.write_all(&(c as f32).to_le_bytes())?;
        }
    }
    for t in &mesh.triangles {
        let mut rec = [0u8; 13];
        rec[0] = 3;
        for (k, &v) in t.iter().enumerate() {
            // PLY's `int` is signed: indices above 2^31-1 cannot be written in it.
            let v =
                i32::try_from(v).map_err(|_| io::Error::other("vertex index exceeds 2^31-1"))?;
            rec[1 + 4 * k..5 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
        w.write_all(&rec)?;
    }
    Ok(())
}
