//! PLY header: format line, elements with their counts, scalar and list properties.
//!
//! In: the whole file. Out: a [`Header`] whose element counts are known to fit in the bytes
//! after `end_header` (each record has a minimum size), so readers may reserve from them.

use std::path::Path;

use super::text::{lines, show, split_ws};
use super::{invalid, parse_error};
use crate::mesh::MeshError;

/// How the body after `end_header` is encoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Encoding {
    /// Whitespace-separated decimal values.
    Ascii,
    /// Packed little-endian values.
    BinaryLittleEndian,
    /// Packed big-endian values.
    BinaryBigEndian,
}

/// A PLY scalar type (both the classic and the sized names are accepted).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Scalar {
    /// `char` / `int8`.
    I8,
    /// `uchar` / `uint8`.
    U8,
    /// `short` / `int16`.
    I16,
    /// `ushort` / `uint16`.
    U16,
    /// `int` / `int32`.
    I32,
    /// `uint` / `uint32`.
    U32,
    /// `float` / `float32`.
    F32,
    /// `double` / `float64`.
    F64,
}

impl Scalar {
    fn from_name(name: &[u8]) -> Option<Scalar> {
        Some(match name {
            b"char" | b"int8" => Scalar::I8,
            b"uchar" | b"uint8" => Scalar::U8,
            b"short" | b"int16" => Scalar::I16,
            b"ushort" | b"uint16" => Scalar::U16,
            b"int" | b"int32" => Scalar::I32,
            b"uint" | b"uint32" => Scalar::U32,
            b"float" | b"float32" => Scalar::F32,
            b"double" | b"float64" => Scalar::F64,
            _ => return None,
        })
    }

    /// Size in bytes in the binary encodings.
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    /// True for the integer types (valid list counts).
    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// The type of one property.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum PropertyKind {
    /// One value.
    Scalar(Scalar),
    /// A count followed by that many items.
    List {
        /// Type of the count.
        count: Scalar,
        /// Type of each item.
        item: Scalar,
    },
}

/// One `property` line.
#[derive(Clone, Debug)]
pub(super) struct Property {
    /// Property name (`x`, `vertex_indices`...).
    pub(super) name: String,
    /// Its type.
    pub(super) kind: PropertyKind,
}

/// One `element` line and its properties.
#[derive(Clone, Debug)]
pub(super) struct Element {
    /// Element name (`vertex`, `face`...).
    pub(super) name: String,
    /// Number of records, checked against the body size.
    pub(super) count: usize,
    /// Properties in record order.
    pub(super) properties: Vec<Property>,
}

impl Element {
    /// Smallest number of bytes one record can take: binary sizes with empty lists, or two
    /// bytes (a digit and a separator) per value in ASCII.
    fn min_record_bytes(&self, encoding: Encoding) -> u64 {
        let sum: u64 = self
            .properties
            .iter()
            .map(|p| match (encoding, p.kind) {
                (Encoding::Ascii, _) => 2,
                (_, PropertyKind::Scalar(s)) => s.size() as u64,
                (_, PropertyKind::List { count, .. }) => count.size() as u64,
            })
            .sum();
        // A property-less element still costs something, so its count stays bounded.
        sum.max(1)
    }
}

/// A parsed PLY header.
#[derive(Clone, Debug)]
pub(super) struct Header {
    /// Body encoding.
    pub(super) encoding: Encoding,
    /// Elements in file order.
    pub(super) elements: Vec<Element>,
    /// Byte offset of the body (just after the `end_header` line).
    pub(super) body_start: usize,
    /// 1-based line number of the body's first line (meaningful for ASCII).
    pub(super) body_line: usize,
}

/// Parse the header of a PLY file and check every element count against the body size.
pub(super) fn parse_header(bytes: &[u8], path: &Path) -> Result<Header, MeshError> {
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    let mut offset = 0usize;
    let mut end = None;
    for (line_no, raw) in lines(bytes) {
        // `raw` may have lost a trailing '\r'; the next line starts after its '\n'.
        let next_offset = bytes[offset..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |i| offset + i + 1);
        offset = next_offset;
        let mut tokens = split_ws(raw);
        let keyword = tokens.next().unwrap_or_default();
        let err = |m: String| parse_error(path, line_no, m);
        if line_no == 1 {
            if keyword != b"ply" {
                return Err(err("not a PLY file: the first line must be 'ply'".into()));
            }
            continue;
        }
        match keyword {
            b"format" => {
                encoding = Some(match tokens.next().unwrap_or_default() {
                    b"ascii" => Encoding::Ascii,
                    b"binary_little_endian" => Encoding::BinaryLittleEndian,
                    b"binary_big_endian" => Encoding::BinaryBigEndian,
                    other => {
                        return Err(err(format!(
                            "unknown PLY format '{}' (expected ascii, binary_little_endian or binary_big_endian)",
                            show(other)
                        )));
                    }
                })
            }
            b"element" => elements.push(parse_element(&mut tokens).map_err(err)?),
            b"property" => {
                let property = parse_property(&mut tokens).map_err(err)?;
                let element = elements
                    .last_mut()
                    .ok_or_else(|| err("'property' before any 'element'".into()))?;
                element.properties.push(property);
            }
            b"comment" | b"obj_info" | b"" => {}
            b"end_header" => {
                end = Some(line_no);
                break;
            }
            other => {
                return Err(err(format!("unknown PLY header line '{}'", show(other))));
            }
        }
    }
    let Some(end_line) = end else {
        return Err(invalid(path, "PLY header has no 'end_header' line".into()));
    };
    let Some(encoding) = encoding else {
        return Err(invalid(path, "PLY header has no 'format' line".into()));
    };
    let header = Header {
        encoding,
        elements,
        body_start: offset,
        body_line: end_line + 1,
    };
    check_counts(&header, bytes.len() - offset, path)?;
    Ok(header)
}

/// `element NAME COUNT`.
fn parse_element<'a>(tokens: &mut impl Iterator<Item = &'a [u8]>) -> Result<Element, String> {
    let name = tokens.next().ok_or("'element' needs a name and a count")?;
    let count = tokens.next().ok_or("'element' needs a count")?;
    let count = std::str::from_utf8(count)
        .ok()
        .and_then(|c| c.parse::<usize>().ok())
        .ok_or_else(|| {
            format!(
                "element count '{}' is not a non-negative integer",
                show(count)
            )
        })?;
    Ok(Element {
        name: String::from_utf8_lossy(name).into_owned(),
        count,
        properties: Vec::new(),
    })
}

/// `property TYPE NAME` or `property list COUNT_TYPE ITEM_TYPE NAME`.
fn parse_property<'a>(tokens: &mut impl Iterator<Item = &'a [u8]>) -> Result<Property, String> {
    let scalar = |t: Option<&[u8]>| {
        let t = t.ok_or("incomplete 'property' line")?;
        Scalar::from_name(t).ok_or_else(|| {
            format!(
                "unknown PLY type '{}' (expected char, uchar, short, ushort, int, uint, float, double or int8..float64)",
                show(t)
            )
        })
    };
    let first = tokens.next().ok_or("'property' needs a type and a name")?;
    let kind = if first == b"list" {
        let count = scalar(tokens.next())?;
        if !count.is_integer() {
            return Err("a list's count type must be an integer type".into());
        }
        PropertyKind::List {
            count,
            item: scalar(tokens.next())?,
        }
    } else {
        PropertyKind::Scalar(scalar(Some(first))?)
    };
    let name = tokens.next().ok_or("'property' needs a name")?;
    Ok(Property {
        name: String::from_utf8_lossy(name).into_owned(),
        kind,
    })
}

/// Refuse element counts whose minimal records cannot fit in `body_len` bytes; the error names
/// the element that asks for the most bytes.
fn check_counts(header: &Header, body_len: usize, path: &Path) -> Result<(), MeshError> {
    let needs: Vec<(u128, &Element)> = header
        .elements
        .iter()
        .map(|e| {
            (
                e.count as u128 * e.min_record_bytes(header.encoding) as u128,
                e,
            )
        })
        .collect();
    let needed: u128 = needs.iter().map(|(n, _)| n).sum();
    // The last ASCII value needs no separator.
    let available = body_len as u128 + u128::from(header.encoding == Encoding::Ascii);
    match needs.iter().max_by_key(|(n, _)| *n) {
        Some((_, e)) if needed > available => Err(invalid(
            path,
            format!(
                "PLY header claims {} '{}' elements (at least {} bytes each; {needed} bytes for all elements), but only {body_len} bytes follow the header: truncated file or bad count",
                e.count,
                e.name,
                e.min_record_bytes(header.encoding),
            ),
        )),
        _ => Ok(()),
    }
}
