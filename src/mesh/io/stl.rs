//! STL reader, binary and ASCII, detected from the content. STL stores each triangle with its
//! own three corners; they are read as separate vertices and welded afterwards by
//! [`super::parse_mesh_bytes`] (bit-identical positions become one vertex), so closed meshes
//! come out closed.
//!
//! Binary: an 80-byte header, a u32 triangle count, then 50 bytes a triangle (normal, three
//! corners as f32 little endian, a u16 attribute). ASCII: `solid`, then `facet normal ..`,
//! `outer loop`, `vertex x y z` (three or more), `endloop`, `endfacet`, ..., `endsolid`.

use std::path::Path;

use super::text::{lines, parse_f64, show, split_ws};
use super::{MeshBuilder, invalid, parse_error};
use crate::mesh::{Mesh, MeshError};

/// Bytes in a binary STL header (80-byte comment + u32 count) and in one triangle record.
const HEADER_BYTES: usize = 84;
const RECORD_BYTES: usize = 50;

/// Parse an STL file held in memory, ASCII or binary.
pub(super) fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    if is_ascii(bytes) {
        parse_ascii(bytes, path)
    } else {
        parse_binary(bytes, path)
    }
}

/// Binary when the size matches the count exactly; else ASCII when the file starts with
/// `solid` and its second line starts with `facet` or `endsolid` (binary headers often begin
/// with "solid" too, so the keyword alone proves nothing).
fn is_ascii(bytes: &[u8]) -> bool {
    if let Some(n) = bytes.get(80..84) {
        let n = u32::from_le_bytes([n[0], n[1], n[2], n[3]]) as u64;
        if HEADER_BYTES as u64 + RECORD_BYTES as u64 * n == bytes.len() as u64 {
            return false;
        }
    }
    let mut tokens = lines(bytes).flat_map(|(_, l)| split_ws(l));
    if tokens.next() != Some(b"solid") {
        return false;
    }
    // The solid's name may be several words: look at the first token of the next non-blank line.
    lines(bytes)
        .skip(1)
        .find_map(|(_, l)| split_ws(l).next())
        .is_some_and(|t| t == b"facet" || t == b"endsolid")
}

/// Add corner `p` (f32 coordinates) as a new vertex; [`super::clean_up`] welds duplicates.
fn corner(builder: &mut MeshBuilder, p: [f32; 3]) -> Result<u32, String> {
    let i = u32::try_from(builder.vertex_count()).map_err(|_| "more than 2^32-1 corners")?;
    builder.push_vertex(p.map(f64::from))?;
    Ok(i)
}

fn parse_binary(bytes: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let Some(count) = bytes.get(80..84) else {
        return Err(invalid(
            path,
            format!(
                "not an STL file: {} bytes is shorter than a binary STL header (84) and it is not ASCII STL ('solid' then 'facet')",
                bytes.len()
            ),
        ));
    };
    let n = u32::from_le_bytes([count[0], count[1], count[2], count[3]]) as usize;
    let held = (bytes.len() - HEADER_BYTES) / RECORD_BYTES;
    let extra = (bytes.len() - HEADER_BYTES) % RECORD_BYTES;
    if n != held || extra != 0 {
        return Err(invalid(
            path,
            format!(
                "binary STL header claims {n} triangles, but the file's {} bytes hold {held} (+{extra} bytes): truncated or corrupt file",
                bytes.len()
            ),
        ));
    }
    // `n` was just checked against the file length: at most (len - 84) / 50 triangles.
    let mut builder = MeshBuilder::with_capacity(3 * n, n);
    for (t, rec) in bytes[HEADER_BYTES..].chunks_exact(RECORD_BYTES).enumerate() {
        let f = |o: usize| f32::from_le_bytes([rec[o], rec[o + 1], rec[o + 2], rec[o + 3]]);
        let mut tri = [0u32; 3];
        for (k, v) in tri.iter_mut().enumerate() {
            let o = 12 + 12 * k;
            *v = corner(&mut builder, [f(o), f(o + 4), f(o + 8)])
                .map_err(|m| parse_error(path, t + 1, format!("binary triangle {}: {m}", t + 1)))?;
        }
        builder
            .push_polygon(&tri)
            .map_err(|m| parse_error(path, t + 1, m))?;
    }
    Ok(builder.finish())
}

fn parse_ascii(bytes: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    // A facet takes well over 100 bytes of text: a cheap upper bound for reserving.
    let mut builder = MeshBuilder::with_capacity(bytes.len() / 32, bytes.len() / 100);
    let mut poly: Vec<u32> = Vec::new();
    let mut in_facet = false;
    let mut facet_line = 0;
    for (line_no, line) in lines(bytes) {
        let err = |m: String| parse_error(path, line_no, m);
        let mut tokens = split_ws(line);
        match tokens.next() {
            None | Some(b"solid" | b"endsolid" | b"outer" | b"endloop") => {}
            Some(b"facet") => {
                if in_facet {
                    return Err(err("'facet' inside a facet (missing 'endfacet')".into()));
                }
                in_facet = true;
                facet_line = line_no;
                poly.clear();
            }
            Some(b"vertex") => {
                if !in_facet {
                    return Err(err("'vertex' outside a facet".into()));
                }
                let mut p = [0f32; 3];
                for c in &mut p {
                    let t = tokens
                        .next()
                        .ok_or_else(|| err("'vertex' needs x y z".into()))?;
                    // Parsed as f64 then narrowed, so welding matches binary STL's f32 precision.
                    *c = parse_f64(t).map_err(err)? as f32;
                }
                poly.push(corner(&mut builder, p).map_err(err)?);
            }
            Some(b"endfacet") => {
                if !in_facet {
                    return Err(err("'endfacet' without 'facet'".into()));
                }
                in_facet = false;
                builder
                    .push_polygon(&poly)
                    .map_err(|m| parse_error(path, facet_line, m))?;
            }
            Some(other) => {
                return Err(err(format!("unexpected '{}' in ASCII STL", show(other))));
            }
        }
    }
    if in_facet {
        return Err(parse_error(
            path,
            facet_line,
            "facet is never closed ('endfacet' missing)",
        ));
    }
    Ok(builder.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binary(tris: &[[[f32; 3]; 3]], claimed: u32) -> Vec<u8> {
        let mut b = b"solid looks like ascii but is binary".to_vec();
        b.resize(80, b' ');
        b.extend_from_slice(&claimed.to_le_bytes());
        for t in tris {
            b.extend_from_slice(&[0u8; 12]);
            for c in t.iter().flatten() {
                b.extend_from_slice(&c.to_le_bytes());
            }
            b.extend_from_slice(&[0, 0]);
        }
        b
    }

    #[test]
    fn binary_welds_and_detects_lies() {
        let tris = [
            [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-0.0, 0.0, 1.0]],
        ];
        let m = super::super::clean_up(parse(&binary(&tris, 2), Path::new("t.stl")).unwrap());
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [1, 2, 3]]);
        let e = parse(&binary(&tris, 3), Path::new("t.stl"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("claims 3") && e.contains("t.stl"), "{e}");
        let e = parse(&binary(&[], 2_000_000_000), Path::new("t.stl")).unwrap_err();
        assert!(e.to_string().contains("claims 2000000000"), "{e}");
    }

    #[test]
    fn ascii_facets_and_errors() {
        let s = "solid my part\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   \
                 vertex 0 1 0\n  endloop\n endfacet\nendsolid my part\n";
        let m = parse(s.as_bytes(), Path::new("t.stl")).unwrap();
        assert_eq!((m.positions.len(), m.triangles.len()), (3, 1));
        let bad = s.replace("vertex 1 0 0", "vertex 1 x 0");
        let e = parse(bad.as_bytes(), Path::new("t.stl"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.stl:5:"), "{e}");
    }
}
