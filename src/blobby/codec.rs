//! Compact binary blob codec (docs/ARCHITECTURE.md, Evaluation and codec): a lossless f32 form (10 numbers a blob) and a
//! quantized form under 20 bytes a blob, each behind a magic number and a version.
//!
//! In: a [`BlobModel`]. Out: bytes, and back (errors name the file, the byte offset and the blob).
//!
//! # What a blob needs
//! A blob's field is `f(x) = B² (1 − |diag(1/r) Rᵀ (x − c)|²)²` inside its support, with the
//! *influence radii* `r = s·√(1+A)`: it depends on `c`, `R`, `r` and `B²` only — `s` and `A`
//! are not separately identifiable. The codec therefore stores centre (3), rotation (3),
//! influence radii (3) and `B` (1), and decoding picks `A` by a fixed convention
//! ([`canonical_a`]): the semi-axes `s` become the blob's *isolated iso-surface*
//! (`B² (1 − u)² = t`, i.e. `u = 1 − √t/|B|`, `A = 1/u − 1`), clamped to `A ∈ [10⁻³, 10³]`,
//! and `A = 1` when `|B| ≤ √t` (the blob alone never reaches the threshold). For a blob that
//! was never optimised (`B = (1+A)/A`) this recovers `A` and `s` exactly.
//!
//! # Layout (little-endian)
//! ```text
//! header   "NPHB" | version u8 | encoding u8 (0 lossless, 1 quantized)
//!          | layout u8 (0 general, 1 isotropic) | primitive u8 (0 ellipsoid, 1 sphere)
//!          | blob count u32 | threshold f32 | source bounds 6×f32 (min, max)
//!          | source vertices u32 | source faces u32 | seed u64 | mesh name u16 length + UTF-8
//! quantized header only: centre box 6×f32 (min, max) | ln r range 2×f32 | max |B| f32
//! blobs    lossless general    c 3×f32 | q.xyz 3×f32 (unit quaternion, w ≥ 0) | r 3×f32 | B f32
//!          lossless isotropic  c 3×f32 | r f32 | B f32
//!          quantized general   c 3×u16 | rotation 40 bits | ln r 3×u16 | |B| u16   (19 bytes)
//!          quantized isotropic c 3×u16 | ln r u16 | |B| u16                        (10 bytes)
//! ```
//! The isotropic layout (no rotation, one radius) is used when every blob's three influence
//! radii are equal in f32 — the spherical baseline costs 5 numbers a blob, as in the paper.
//!
//! # Guarantees
//! *Lossless*: decoding then re-encoding gives identical bytes, and the decoded field equals
//! the f64 model's within f32 precision (every stored number is the f32 rounding of the model's).
//! *Quantized*: centres to 1/65535 of the centres' bounding box, radii to a relative
//! `ln(r_max/r_min)/65535`, `B` to `max|B|/65535`, rotations to 12 bits a component
//! (smallest-three); `nephele eval` reports the resulting extra error.
//! Decoding never panics and never allocates from a claimed count before checking it against the
//! data length.

mod quantized;
mod wire;

use std::path::Path;

use glam::{DQuat, DVec3};

use super::{Blob, BlobModel, ModelError, SourceInfo, model_file::MODEL_VERSION};
use crate::decompose::Primitive;
use crate::geometry::Aabb;
use wire::{Reader, Writer};

/// The four bytes every encoded model starts with.
pub const MAGIC: [u8; 4] = *b"NPHB";
/// Codec version written by this build; larger versions are refused.
pub const CODEC_VERSION: u8 = 1;
/// Bytes a blob in the lossless general layout (10 × f32).
pub const LOSSLESS_BLOB_BYTES: usize = 40;
/// Bytes a blob in the lossless isotropic layout (5 × f32).
pub const LOSSLESS_SPHERE_BYTES: usize = 20;
/// Bytes a blob in the quantized general layout.
pub const QUANTIZED_BLOB_BYTES: usize = 19;
/// Bytes a blob in the quantized isotropic layout.
pub const QUANTIZED_SPHERE_BYTES: usize = 10;

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
    bytes.starts_with(&MAGIC)
}

/// A blob reduced to what its field depends on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Packed {
    pub center: DVec3,
    /// Unit quaternion with `w ≥ 0`.
    pub rotation: DQuat,
    /// Influence radii `s·√(1+A)` (zero for a blob with a zero semi-axis).
    pub radii: DVec3,
    pub b: f64,
}

impl Packed {
    fn from_blob(blob: &Blob) -> Packed {
        let mut q = blob.rotation;
        // Only renormalise quaternions that are visibly off unit length: re-encoding a decoded
        // quaternion (unit within f32 rounding) must not move its f32 components.
        if (q.length_squared() - 1.0).abs() > 1e-6 {
            q = q.normalize();
        }
        if q.w < 0.0 {
            q = -q;
        }
        Packed {
            center: blob.center,
            rotation: q,
            radii: blob.semi_axes * (1.0 + blob.a).sqrt(),
            b: blob.b,
        }
    }

    fn to_blob(self, threshold: f64) -> Blob {
        let a = canonical_a(self.b, threshold);
        Blob {
            center: self.center,
            rotation: self.rotation,
            semi_axes: self.radii / (1.0 + a).sqrt(),
            a,
            b: self.b,
        }
    }
}

/// The `A` decoding assigns to a blob of strength `b` at iso-level `threshold` (see the module
/// header): the isolated iso-surface convention, clamped to `[10⁻³, 10³]`, or 1 when the blob
/// alone never reaches the threshold.
pub fn canonical_a(b: f64, threshold: f64) -> f64 {
    let u = 1.0 - threshold.sqrt() / b.abs();
    if u.is_finite() && u > 0.0 {
        (1.0 / u - 1.0).clamp(1e-3, 1e3)
    } else {
        1.0
    }
}

/// True when every blob's three influence radii round to the same f32.
fn is_isotropic(blobs: &[Packed]) -> bool {
    blobs.iter().all(|p| {
        let r = p.radii.as_vec3();
        r.x == r.y && r.y == r.z
    })
}

/// Encode a model. Never fails: non-finite values are written as they are (and refused on
/// decoding); counts above `u32::MAX` saturate.
pub fn encode(model: &BlobModel, encoding: Encoding) -> Vec<u8> {
    let packed: Vec<Packed> = model.blobs.iter().map(Packed::from_blob).collect();
    let isotropic = is_isotropic(&packed);
    let mut w = Writer::default();
    w.bytes(&MAGIC);
    w.u8(CODEC_VERSION);
    w.u8(match encoding {
        Encoding::Lossless => 0,
        Encoding::Quantized => 1,
    });
    w.u8(isotropic as u8);
    w.u8(match model.primitive {
        Primitive::Ellipsoid => 0,
        Primitive::Sphere => 1,
    });
    w.u32(clamp_u32(model.blobs.len()));
    w.f32(model.threshold);
    let b = &model.source.bounds;
    w.vec3(b.min);
    w.vec3(b.max);
    w.u32(clamp_u32(model.source.vertices));
    w.u32(clamp_u32(model.source.faces));
    w.u64(model.seed);
    w.name(&model.source.mesh);
    match encoding {
        Encoding::Lossless => {
            for p in &packed {
                w.vec3(p.center);
                if !isotropic {
                    w.vec3(p.rotation.xyz());
                }
                if isotropic {
                    w.f32(p.radii.x);
                } else {
                    w.vec3(p.radii);
                }
                w.f32(p.b);
            }
        }
        Encoding::Quantized => quantized::write(&mut w, &packed, isotropic),
    }
    w.finish()
}

fn clamp_u32(n: usize) -> u32 {
    u32::try_from(n).unwrap_or(u32::MAX)
}

/// Decode an encoded model (`path` labels errors).
pub fn decode(path: &Path, bytes: &[u8]) -> Result<BlobModel, ModelError> {
    let mut r = Reader::new(path, bytes);
    if !is_encoded(bytes) {
        return Err(r.invalid(
            0,
            "not an encoded blob model (missing the 'NPHB' magic number)",
        ));
    }
    r.skip(MAGIC.len());
    let version = r.u8("version")?;
    if version > CODEC_VERSION {
        return Err(ModelError::Version {
            path: path.to_path_buf(),
            found: version.into(),
            supported: CODEC_VERSION.into(),
        });
    }
    if version == 0 {
        return Err(r.invalid(4, "codec version 0 does not exist"));
    }
    let encoding = match r.u8("encoding")? {
        0 => Encoding::Lossless,
        1 => Encoding::Quantized,
        e => return Err(r.invalid(5, &format!("unknown encoding {e} (expected 0 or 1)"))),
    };
    let isotropic = match r.u8("layout")? {
        0 => false,
        1 => true,
        l => return Err(r.invalid(6, &format!("unknown blob layout {l} (expected 0 or 1)"))),
    };
    let primitive = match r.u8("primitive")? {
        0 => Primitive::Ellipsoid,
        1 => Primitive::Sphere,
        p => return Err(r.invalid(7, &format!("unknown primitive {p} (expected 0 or 1)"))),
    };
    let count = r.u32("blob count")? as usize;
    if count == 0 {
        return Err(r.invalid(8, "the model has no blobs"));
    }
    let at = r.pos();
    let threshold = r.f32("threshold")?;
    if !(threshold.is_finite() && threshold > 0.0) {
        return Err(r.invalid(at, &format!("threshold must be positive, got {threshold}")));
    }
    let at = r.pos();
    let bounds = Aabb {
        min: r.vec3("source bounds")?,
        max: r.vec3("source bounds")?,
    };
    if !(bounds.min.is_finite() && bounds.max.is_finite()) {
        return Err(r.invalid(at, "source bounds are not finite"));
    }
    let vertices = r.u32("source vertex count")? as usize;
    let faces = r.u32("source face count")? as usize;
    let seed = r.u64("seed")?;
    let mesh = r.name("mesh name")?;
    let quant = match encoding {
        Encoding::Lossless => None,
        Encoding::Quantized => Some(quantized::Ranges::read(&mut r)?),
    };
    let blob_bytes = match (encoding, isotropic) {
        (Encoding::Lossless, false) => LOSSLESS_BLOB_BYTES,
        (Encoding::Lossless, true) => LOSSLESS_SPHERE_BYTES,
        (Encoding::Quantized, false) => QUANTIZED_BLOB_BYTES,
        (Encoding::Quantized, true) => QUANTIZED_SPHERE_BYTES,
    };
    r.expect_blobs(count, blob_bytes)?;
    // The length check above bounds `count` by the data actually present.
    let mut blobs = Vec::with_capacity(count);
    for i in 0..count {
        let at = r.pos();
        let p = match &quant {
            None => read_lossless(&mut r, isotropic)?,
            Some(q) => q.read_blob(&mut r, isotropic)?,
        };
        check_blob(&r, &p, i, count, at)?;
        blobs.push(p.to_blob(threshold));
    }
    Ok(BlobModel {
        version: MODEL_VERSION,
        primitive,
        threshold,
        source: SourceInfo {
            mesh,
            bounds,
            vertices,
            faces,
        },
        seed,
        blobs,
    })
}

fn read_lossless(r: &mut Reader, isotropic: bool) -> Result<Packed, ModelError> {
    let center = r.vec3("blob centre")?;
    let (rotation, radii) = if isotropic {
        (DQuat::IDENTITY, DVec3::splat(r.f32("blob radius")?))
    } else {
        let v = r.vec3("blob rotation")?;
        // Decoded exactly as stored (no renormalisation), so a re-encode is byte-identical.
        let w = (1.0 - v.length_squared()).max(0.0).sqrt();
        (DQuat::from_xyzw(v.x, v.y, v.z, w), r.vec3("blob radii")?)
    };
    let b = r.f32("blob strength B")?;
    Ok(Packed {
        center,
        rotation,
        radii,
        b,
    })
}

/// Refuse non-finite values, negative radii and rotations that are no unit quaternion.
fn check_blob(r: &Reader, p: &Packed, i: usize, n: usize, at: usize) -> Result<(), ModelError> {
    let what = if !(p.center.is_finite() && p.radii.is_finite() && p.b.is_finite()) {
        "a non-finite value"
    } else if p.radii.min_element() < 0.0 {
        "a negative radius"
    } else if p.rotation.xyz().length_squared() > 1.0 + 1e-5 {
        "a rotation that is no unit quaternion"
    } else {
        return Ok(());
    };
    Err(r.invalid(at, &format!("blob {} of {n} has {what}", i + 1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn canonical_a_recovers_an_unoptimised_blob() {
        for a in [0.01, 0.5, 1.0, 3.0, 50.0] {
            let b = (1.0 + a) / a;
            assert!(
                (canonical_a(b, 1.0) - a).abs() < 1e-9 * a.max(1.0),
                "a = {a}"
            );
        }
        assert_eq!(canonical_a(0.5, 1.0), 1.0);
        assert_eq!(canonical_a(0.0, 1.0), 1.0);
        assert_eq!(canonical_a(1.0 + 1e-9, 1.0), 1e3);
    }
}
