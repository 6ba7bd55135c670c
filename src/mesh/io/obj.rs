//! Wavefront OBJ reader: `v x y z [w | r g b]` and `f` with `v`, `v/vt`, `v//vn`, `v/vt/vn`
//! corners (1-based, or negative = relative to the vertices defined so far). Every other
//! statement (`vt`, `vn`, `o`, `g`, `usemtl`, `l`...) is ignored.

use std::path::Path;

use super::text::{lines, parse_f64, parse_i64, show, split_ws};
use super::{MeshBuilder, parse_error};
use crate::mesh::{Mesh, MeshError};

/// Parse an OBJ file held in memory.
pub(super) fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let mut builder = MeshBuilder::default();
    // Reused across faces: no allocation per face.
    let mut poly: Vec<u32> = Vec::new();
    // Largest positive index seen and its line: positive indices may legally point forward,
    // so they are range-checked once all vertices are known.
    let mut max_index: Option<(u32, usize)> = None;
    for (line_no, line) in lines(bytes) {
        let line = match line.iter().position(|&c| c == b'#') {
            Some(i) => &line[..i],
            None => line,
        };
        let mut tokens = split_ws(line);
        match tokens.next() {
            Some(b"v") => {
                let p = parse_vertex(&mut tokens).map_err(|m| parse_error(path, line_no, m))?;
                if builder.vertex_count() >= u32::MAX as usize {
                    return Err(parse_error(path, line_no, "more than 2^32-1 vertices"));
                }
                builder
                    .push_vertex(p)
                    .map_err(|m| parse_error(path, line_no, m))?;
            }
            Some(b"f") => {
                poly.clear();
                for corner in tokens {
                    let index = parse_corner(corner, builder.vertex_count())
                        .map_err(|m| parse_error(path, line_no, m))?;
                    if max_index.is_none_or(|(m, _)| index > m) {
                        max_index = Some((index, line_no));
                    }
                    poly.push(index);
                }
                builder
                    .push_polygon(&poly)
                    .map_err(|m| parse_error(path, line_no, m))?;
            }
            _ => {}
        }
    }
    if let Some((index, line_no)) = max_index
        && index as usize >= builder.vertex_count()
    {
        return Err(parse_error(
            path,
            line_no,
            format!(
                "face refers to vertex {} but the file defines only {} vertices",
                index as u64 + 1,
                builder.vertex_count()
            ),
        ));
    }
    Ok(builder.finish())
}

/// The three coordinates of a `v` statement (a fourth `w` or colour components are ignored).
fn parse_vertex<'a>(tokens: &mut impl Iterator<Item = &'a [u8]>) -> Result<[f64; 3], String> {
    let mut p = [0.0; 3];
    for (axis, c) in p.iter_mut().enumerate() {
        let t = tokens
            .next()
            .ok_or_else(|| format!("vertex has {axis} coordinates; 'v' needs x y z"))?;
        *c = parse_f64(t)?;
    }
    Ok(p)
}

/// The 0-based vertex index of one face corner `v[/vt][/vn]`, given the number of vertices
/// defined so far (for negative, relative indices).
fn parse_corner(corner: &[u8], defined: usize) -> Result<u32, String> {
    let v = corner.split(|&c| c == b'/').next().unwrap_or_default();
    if v.is_empty() {
        return Err(format!(
            "face corner '{}' has no vertex index",
            show(corner)
        ));
    }
    let k = parse_i64(v).map_err(|e| format!("face corner: {e}"))?;
    let index = match k {
        0 => return Err("face index 0 is invalid (OBJ indices start at 1)".into()),
        k if k > 0 => k - 1,
        k => {
            let i = defined as i64 + k;
            if i < 0 {
                return Err(format!(
                    "relative face index {k} reaches before the first vertex ({defined} defined so far)"
                ));
            }
            i
        }
    };
    u32::try_from(index).map_err(|_| format!("face index {k} is out of range"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse_str(s: &str) -> Result<Mesh, MeshError> {
        parse(s.as_bytes(), Path::new("t.obj"))
    }

    #[test]
    fn corner_forms_and_relative_indices() {
        let m = parse_str(
            "# quad\nv 0 0 0\nv 1 0 0 1.0\nv 1 1 0 0.5 0.5 0.5\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
             f 1/1/1 2//1 3/1 4\nf -4 -2 -1\n",
        )
        .unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 3]]);
    }

    #[test]
    fn bad_indices_name_the_line() {
        let e = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.obj:4:") && e.contains("vertex 4"), "{e}");
        let e = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n").unwrap_err();
        assert!(e.to_string().contains(":4:"), "{e}");
        let e = parse_str("v 0 0 0\nv 1 0 0\nf -1 -2 -3\nv 0 1 0\n").unwrap_err();
        assert!(e.to_string().contains(":3:"), "{e}");
        let e = parse_str("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n").unwrap_err();
        assert!(e.to_string().contains("at least 3"), "{e}");
        let e = parse_str("v 0 nan 0\n").unwrap_err();
        assert!(e.to_string().contains(":1:"), "{e}");
    }
}
