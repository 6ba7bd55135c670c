//! Compact binary blob codec (DESIGN.md §5): a lossless f32 form (10 floats a blob) and a
//! quantized form under 20 bytes a blob, each with a magic number and version.

use std::path::Path;

use super::{BlobModel, ModelError};

/// Which binary form to write.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// 10 × f32 a blob: centre, rotation (3 numbers), influence radii, B.
    Lossless,
    /// Bounding-box-relative fixed point with a compact rotation, under 20 bytes a blob.
    Quantized,
}

/// True when `bytes` start with the codec's magic number.
pub fn is_encoded(bytes: &[u8]) -> bool {
    let _ = bytes;
    false
}

/// Encode a model.
pub fn encode(model: &BlobModel, encoding: Encoding) -> Vec<u8> {
    let _ = (model, encoding);
    todo!("codec helper")
}

/// Decode an encoded model (`path` labels errors).
pub fn decode(path: &Path, bytes: &[u8]) -> Result<BlobModel, ModelError> {
    let _ = (path, bytes);
    todo!("codec helper")
}
