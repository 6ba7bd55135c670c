//! Stanford PLY reader (ASCII, binary little endian, binary big endian).
//!
//! Uses `x`, `y`, `z` of the `vertex` element (any scalar type) and the `vertex_indices` (or
//! `vertex_index`) list of the `face` element (any count and index types). Every other
//! property and element is read past and ignored. Errors give the element name and its 1-based
//! record number; the error's `line` is the text line (ASCII) or that record number (binary).

use std::path::Path;

use super::ply_header::{Element, Encoding, Header, PropertyKind, Scalar, parse_header};
use super::text::{Tokens, parse_f64, parse_i64};
use super::{MeshBuilder, invalid, parse_error};
use crate::mesh::{Mesh, MeshError};

/// What the reader does with one property's value(s).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Role {
    /// Vertex coordinate 0, 1 or 2.
    Coord(usize),
    /// The face's vertex index list.
    Indices,
    /// Read past it.
    Skip,
}

/// Parse a PLY file held in memory.
pub(super) fn parse(bytes: &[u8], path: &Path) -> Result<Mesh, MeshError> {
    let header = parse_header(bytes, path)?;
    let (vertex_el, face_el) = find_elements(&header, path)?;
    let vertex_count = header.elements[vertex_el].count;
    if vertex_count > u32::MAX as usize {
        return Err(invalid(
            path,
            format!("{vertex_count} vertices: more than 2^32-1"),
        ));
    }
    let roles = roles(&header);
    // Counts were checked against the body size by `parse_header`.
    let mut builder = MeshBuilder::with_capacity(vertex_count, header.elements[face_el].count);
    let body = &bytes[header.body_start..];
    let mut reader = Reader {
        vertex_el,
        face_el,
        vertex_count,
        poly: Vec::new(),
        builder: &mut builder,
    };
    match header.encoding {
        Encoding::Ascii => {
            let mut src = AsciiSource(Tokens::new(body, header.body_line, false));
            reader.read_body(&header, &roles, &mut src, path)?;
        }
        enc => {
            let big_endian = enc == Encoding::BinaryBigEndian;
            let mut src = BinarySource {
                data: body,
                pos: 0,
                big_endian,
            };
            reader.read_body(&header, &roles, &mut src, path)?;
        }
    }
    Ok(builder.finish())
}

/// Indices of the `vertex` and `face` elements, checking they carry x/y/z and an index list.
fn find_elements(header: &Header, path: &Path) -> Result<(usize, usize), MeshError> {
    let find = |name: &str| header.elements.iter().position(|e| e.name == name);
    let vertex =
        find("vertex").ok_or_else(|| invalid(path, "PLY file has no 'vertex' element".into()))?;
    let face = find("face").ok_or_else(|| {
        invalid(
            path,
            "PLY file has no 'face' element (a point cloud is not a mesh)".into(),
        )
    })?;
    for axis in ["x", "y", "z"] {
        let p = header.elements[vertex]
            .properties
            .iter()
            .find(|p| p.name == axis)
            .ok_or_else(|| {
                invalid(
                    path,
                    format!("PLY 'vertex' element has no '{axis}' property"),
                )
            })?;
        if !matches!(p.kind, PropertyKind::Scalar(_)) {
            return Err(invalid(
                path,
                format!("PLY vertex property '{axis}' is a list"),
            ));
        }
    }
    let list = header.elements[face]
        .properties
        .iter()
        .find(|p| index_list_name(&p.name))
        .ok_or_else(|| {
            invalid(
                path,
                "PLY 'face' element has no 'vertex_indices' (or 'vertex_index') property".into(),
            )
        })?;
    if !matches!(list.kind, PropertyKind::List { .. }) {
        return Err(invalid(
            path,
            format!("PLY face property '{}' is not a list", list.name),
        ));
    }
    Ok((vertex, face))
}

fn index_list_name(name: &str) -> bool {
    name == "vertex_indices" || name == "vertex_index"
}

/// The role of every property of every element (first match wins for duplicates).
fn roles(header: &Header) -> Vec<Vec<Role>> {
    header
        .elements
        .iter()
        .map(|e| {
            let mut seen = [false; 4];
            e.properties
                .iter()
                .map(|p| {
                    let slot = match (e.name.as_str(), p.name.as_str()) {
                        ("vertex", "x") => Some((0, Role::Coord(0))),
                        ("vertex", "y") => Some((1, Role::Coord(1))),
                        ("vertex", "z") => Some((2, Role::Coord(2))),
                        ("face", n) if index_list_name(n) => Some((3, Role::Indices)),
                        _ => None,
                    };
                    match slot {
                        Some((i, role)) if !seen[i] => {
                            seen[i] = true;
                            role
                        }
                        _ => Role::Skip,
                    }
                })
                .collect()
        })
        .collect()
}

/// Where values come from: ASCII tokens or packed binary.
trait Source {
    /// The next value of type `ty`, converted to f64 (exact for every PLY integer type).
    fn scalar(&mut self, ty: Scalar) -> Result<f64, String>;
    /// Read past `n` values of type `ty`.
    fn skip(&mut self, n: usize, ty: Scalar) -> Result<(), String>;
    /// True when `n` values of type `ty` can still be present.
    fn can_hold(&self, n: usize, ty: Scalar) -> bool;
    /// The error `line` for record `index` (0-based) about to be read.
    fn record_line(&mut self, index: usize) -> usize;
    /// How errors name the data ("binary " or "").
    fn kind(&self) -> &'static str;
}

/// Packed values in a byte slice.
struct BinarySource<'a> {
    data: &'a [u8],
    pos: usize,
    big_endian: bool,
}

impl BinarySource<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let bytes = self
            .data
            .get(self.pos..self.pos + N)
            .ok_or("truncated data: the file ends inside this record")?;
        self.pos += N;
        let mut a: [u8; N] = bytes.try_into().unwrap_or([0; N]);
        if self.big_endian {
            a.reverse();
        }
        Ok(a)
    }
}

impl Source for BinarySource<'_> {
    #[inline]
    fn scalar(&mut self, ty: Scalar) -> Result<f64, String> {
        // Bytes are put in little-endian order by `take`.
        Ok(match ty {
            Scalar::I8 => i8::from_le_bytes(self.take()?) as f64,
            Scalar::U8 => u8::from_le_bytes(self.take()?) as f64,
            Scalar::I16 => i16::from_le_bytes(self.take()?) as f64,
            Scalar::U16 => u16::from_le_bytes(self.take()?) as f64,
            Scalar::I32 => i32::from_le_bytes(self.take()?) as f64,
            Scalar::U32 => u32::from_le_bytes(self.take()?) as f64,
            Scalar::F32 => f32::from_le_bytes(self.take()?) as f64,
            Scalar::F64 => f64::from_le_bytes(self.take()?),
        })
    }

    fn skip(&mut self, n: usize, ty: Scalar) -> Result<(), String> {
        if !self.can_hold(n, ty) {
            return Err("truncated data: the file ends inside this record".into());
        }
        self.pos += n * ty.size();
        Ok(())
    }

    fn can_hold(&self, n: usize, ty: Scalar) -> bool {
        n.checked_mul(ty.size())
            .is_some_and(|b| b <= self.data.len() - self.pos)
    }

    fn record_line(&mut self, index: usize) -> usize {
        index + 1
    }

    fn kind(&self) -> &'static str {
        "binary "
    }
}

/// Whitespace-separated decimal values.
struct AsciiSource<'a>(Tokens<'a>);

impl Source for AsciiSource<'_> {
    fn scalar(&mut self, ty: Scalar) -> Result<f64, String> {
        let (t, _) = self
            .0
            .next_token()
            .ok_or("the file ends inside this record (missing values)")?;
        if ty.is_integer() {
            let v = parse_i64(t)?;
            Ok(v as f64)
        } else {
            parse_f64(t)
        }
    }

    fn skip(&mut self, n: usize, _ty: Scalar) -> Result<(), String> {
        for _ in 0..n {
            self.0
                .next_token()
                .ok_or("the file ends inside this record (missing values)")?;
        }
        Ok(())
    }

    fn can_hold(&self, n: usize, _ty: Scalar) -> bool {
        n.checked_mul(2)
            .is_some_and(|b| b <= self.0.remaining() + 1)
    }

    fn record_line(&mut self, _index: usize) -> usize {
        self.0.skip_blank();
        self.0.line()
    }

    fn kind(&self) -> &'static str {
        ""
    }
}

/// Body-reading state shared by both encodings.
struct Reader<'b> {
    vertex_el: usize,
    face_el: usize,
    vertex_count: usize,
    /// Reused index buffer: no allocation per face.
    poly: Vec<u32>,
    builder: &'b mut MeshBuilder,
}

impl Reader<'_> {
    fn read_body(
        &mut self,
        header: &Header,
        roles: &[Vec<Role>],
        src: &mut impl Source,
        path: &Path,
    ) -> Result<(), MeshError> {
        for (ei, element) in header.elements.iter().enumerate() {
            for r in 0..element.count {
                let line = src.record_line(r);
                self.read_record(ei, element, &roles[ei], src)
                    .map_err(|m| {
                        let kind = src.kind();
                        parse_error(path, line, format!("{kind}{} {}: {m}", element.name, r + 1))
                    })?;
            }
        }
        Ok(())
    }

    /// One record of element `ei`; on error, a message without the location.
    fn read_record(
        &mut self,
        ei: usize,
        element: &Element,
        roles: &[Role],
        src: &mut impl Source,
    ) -> Result<(), String> {
        let mut p = [0.0f64; 3];
        self.poly.clear();
        for (prop, &role) in element.properties.iter().zip(roles) {
            match (prop.kind, role) {
                (PropertyKind::Scalar(ty), Role::Coord(axis)) => p[axis] = src.scalar(ty)?,
                (PropertyKind::Scalar(ty), _) => src.skip(1, ty)?,
                (PropertyKind::List { count, item }, role) => {
                    let n = src.scalar(count)?;
                    if n < 0.0 {
                        return Err(format!("negative list length {n} for '{}'", prop.name));
                    }
                    let n = n as usize;
                    if !src.can_hold(n, item) {
                        return Err(format!(
                            "list '{}' claims {n} items, more than the rest of the file holds (truncated or corrupt data)",
                            prop.name
                        ));
                    }
                    if role == Role::Indices {
                        self.read_indices(n, item, src)?;
                    } else {
                        src.skip(n, item)?;
                    }
                }
            }
        }
        if ei == self.vertex_el {
            self.builder.push_vertex(p)?;
        } else if ei == self.face_el {
            self.builder.push_polygon(&self.poly)?;
        }
        Ok(())
    }

    fn read_indices(&mut self, n: usize, ty: Scalar, src: &mut impl Source) -> Result<(), String> {
        for _ in 0..n {
            let v = src.scalar(ty)?;
            if !(v >= 0.0 && v < self.vertex_count as f64 && v.fract() == 0.0) {
                return Err(format!(
                    "vertex index {v} is out of range (the file has {} vertices, indices start at 0)",
                    self.vertex_count
                ));
            }
            self.poly.push(v as u32);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ascii_with_extra_properties_and_elements() {
        let text = "ply\r\nformat ascii 1.0\r\ncomment hi\r\nobj_info x\r\n\
            element vertex 4\r\nproperty float32 x\r\nproperty double y\r\nproperty list uchar int junk\r\nproperty int z\r\n\
            element edge 1\r\nproperty int a\r\nproperty int b\r\n\
            element face 2\r\nproperty uchar red\r\nproperty list uint8 uint vertex_index\r\nend_header\r\n\
            0 0 2 7 7 0\r\n1 0 0 0\r\n0 1 1 5 1\r\n0 0 0 1\r\n\
            0 1\r\n\
            9 3 0 1 2\r\n9 4 0 1 2 3\r\n";
        let m = parse(text.as_bytes(), Path::new("t.ply")).unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.positions[3].z, 1.0);
        assert_eq!(m.triangles, vec![[0, 1, 2], [0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn ascii_errors_name_line_and_element() {
        let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
            property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
        let bad = format!("{head}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
        let e = parse(bad.as_bytes(), Path::new("t.ply"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.ply:13:") && e.contains("face 1"), "{e}");
        let bad = format!("{head}0 0 0\n1 zz 0\n0 1 0\n3 0 1 2\n");
        let e = parse(bad.as_bytes(), Path::new("t.ply"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.ply:11:") && e.contains("vertex 2") && e.contains("zz"),
            "{e}"
        );
    }
}
