//! OFF reader: an `OFF` header (or `COFF`, `NOFF`, `CNOFF`, `STOFF`...; optional), then
//! `nv nf ne` (possibly on the header line), `nv` vertex lines `x y z [...]` and `nf` face
//! lines `n i1 .. in [colour]`. `#` starts a comment. Anything after the used values of a
//! vertex or face line (normals, colours, texture coordinates) is ignored.

use std::path::Path;

use super::text::{Tokens, parse_f64, parse_u32, show};
use super::{MeshBuilder, invalid, parse_error};
use crate::mesh::{Mesh, MeshError};

/// Parse an OFF file held in memory.
pub(super) fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let mut t = Tokens::new(bytes, 1, true);
    let eof = |t: &Tokens, what: &str| {
        parse_error(path, t.line(), format!("file ends early: expected {what}"))
    };

    // Header keyword: optional letters before "OFF"; a file may also start with the counts.
    let mut first = t.next_token().ok_or_else(|| eof(&t, "'OFF'"))?;
    if first.0.ends_with(b"OFF") {
        let prefix = &first.0[..first.0.len() - 3];
        if !prefix.iter().all(|c| b"STCN".contains(c)) {
            return Err(parse_error(
                path,
                first.1,
                format!(
                    "unsupported OFF variant '{}' (only 3D OFF, COFF, NOFF, STOFF...)",
                    show(first.0)
                ),
            ));
        }
        first = t
            .next_token()
            .ok_or_else(|| eof(&t, "vertex and face counts"))?;
    }
    let count = |tok: (&[u8], usize), what: &str| {
        parse_u32(tok.0, what).map_err(|m| parse_error(path, tok.1, m))
    };
    let nv = count(first, "vertex count")? as usize;
    let nf_tok = t.next_token().ok_or_else(|| eof(&t, "the face count"))?;
    let nf = count(nf_tok, "face count")? as usize;
    // Edge count: present in valid files, unused.
    let ne_tok = t.next_token().ok_or_else(|| eof(&t, "the edge count"))?;
    count(ne_tok, "edge count")?;
    t.skip_line();

    // A vertex line holds at least "x y z" (6 bytes with separators), a face at least its
    // count (2 bytes; a too-short face then gets its own located error).
    let needed = nv as u64 * 6 + nf as u64 * 2;
    if needed > t.remaining() as u64 + 1 {
        return Err(invalid(
            path,
            format!(
                "OFF header claims {nv} vertices and {nf} faces, which cannot fit in the {} bytes that follow: truncated file or bad counts",
                t.remaining()
            ),
        ));
    }
    let mut builder = MeshBuilder::with_capacity(nv, nf);
    for i in 0..nv {
        let mut p = [0.0; 3];
        for c in &mut p {
            let (tok, line) = t
                .next_token()
                .ok_or_else(|| eof(&t, &format!("vertex {} of {nv}", i + 1)))?;
            *c = parse_f64(tok)
                .map_err(|m| parse_error(path, line, format!("vertex {}: {m}", i + 1)))?;
        }
        let line = t.line();
        builder
            .push_vertex(p)
            .map_err(|m| parse_error(path, line, format!("vertex {}: {m}", i + 1)))?;
        t.skip_line();
    }
    let mut poly: Vec<u32> = Vec::new();
    for i in 0..nf {
        let (tok, line) = t
            .next_token()
            .ok_or_else(|| eof(&t, &format!("face {} of {nf}", i + 1)))?;
        let err = |m: String| parse_error(path, line, format!("face {}: {m}", i + 1));
        let n = parse_u32(tok, "vertex count").map_err(err)? as usize;
        // Each index needs at least two bytes: refuse lengths that cannot be in the file.
        if n.saturating_mul(2) > t.remaining() + 1 {
            return Err(err(format!(
                "claims {n} vertices, more than the rest of the file holds"
            )));
        }
        poly.clear();
        for _ in 0..n {
            let (tok, l) = t.next_token().ok_or_else(|| eof(&t, "more face indices"))?;
            if l != line {
                return Err(err(format!(
                    "has {} indices on its line, header says {n}",
                    poly.len()
                )));
            }
            let v = parse_u32(tok, "vertex index").map_err(err)?;
            if v as usize >= nv {
                return Err(err(format!(
                    "vertex index {v} is out of range (the file has {nv} vertices, indices start at 0)"
                )));
            }
            poly.push(v);
        }
        builder.push_polygon(&poly).map_err(err)?;
        t.skip_line();
    }
    Ok(builder.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn variants_comments_and_colours() {
        let text = "# c\nCOFF 4 2 0 # counts here\n0 0 0 255 0 0\n1 0 0 1 1 1\n0 1 0 1 1 1\n\
                    0 0 1 1 1 1\n4 0 1 2 3 0.5 0.5 0.5\n3 0 2 1\n";
        let m = parse(text.as_bytes(), Path::new("t.off")).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 1]]);
    }

    #[test]
    fn errors() {
        let e = parse(
            b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n",
            Path::new("t.off"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("t.off:6:") && e.contains("face 1"), "{e}");
        let e = parse(
            b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n",
            Path::new("t.off"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("t.off:"), "{e}");
        let e = parse(b"OFF\n2000000000 2000000000 0\n0 0 0\n", Path::new("t.off"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("cannot fit"), "{e}");
        let e = parse(b"4OFF\n1 1 0\n", Path::new("t.off"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("4OFF"), "{e}");
    }
}
