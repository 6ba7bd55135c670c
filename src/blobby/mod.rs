//! The ellipsoidal blobby model (paper §4; docs/ARCHITECTURE.md): blobs, the summed local polynomial
//! field, its optimisation, the model file, the compact codec and polygonization.
//!
//! A blob has centre `c`, rotation `R`, semi-axes `s` and parameters `A > 0`, `B > 0`. With
//! `ρ(x) = |diag(1/s)·Rᵀ(x−c)|`:
//!
//! ```text
//! f(x) = B² (1 − ρ²/(1+A))²   if ρ² < 1+A, else 0        F(x) = Σ f_i(x) − t,  t = 1
//! ```
//!
//! `F > 0` inside, `F = 0` on the surface. An isolated blob with `B = (1+A)/A` reproduces its
//! ellipsoid exactly.

pub mod codec;
pub mod field;
pub mod fit;
pub mod model_file;
pub mod optimise;
pub mod polygonize;
pub mod rows;

use std::path::Path;

use glam::{DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::decompose::Primitive;
use crate::file_error::FileError;
use crate::geometry::{Aabb, Ellipsoid};

pub use field::BlobField;
pub use model_file::{ModelError, save_model};
pub use rows::{BLOB_COLUMNS, BlobFault, check_blobs};

/// The iso-level `t` of the paper (Eq. 1); the surface is `Σ f_i = t`.
pub const THRESHOLD: f64 = 1.0;

/// One ellipsoidal blob.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Blob {
    /// Centre `c`.
    pub center: DVec3,
    /// Rotation `R` from the blob's local frame to the world.
    pub rotation: DQuat,
    /// Ellipsoid semi-axes `s` (the decomposed ellipsoid; the support is `√(1+A)·s`).
    pub semi_axes: DVec3,
    /// `A > 0`: support radius factor, support = ellipsoid scaled by `√(1+A)`.
    pub a: f64,
    /// `B`: field strength (`B²` at the centre). `B = 0` switches the blob off.
    pub b: f64,
}

impl Blob {
    /// A blob whose isolated iso-surface is exactly `e`, with support parameter `a`.
    pub fn from_ellipsoid(e: &Ellipsoid, a: f64) -> Blob {
        Blob {
            center: e.center,
            rotation: e.rotation,
            semi_axes: e.semi_axes,
            a,
            b: (1.0 + a) / a,
        }
    }

    /// The ellipsoid `ρ = 1`.
    pub fn ellipsoid(&self) -> Ellipsoid {
        Ellipsoid {
            center: self.center,
            rotation: self.rotation,
            semi_axes: self.semi_axes,
        }
    }

    /// The support ellipsoid `ρ² = 1 + A`, outside which the field is zero.
    pub fn support(&self) -> Ellipsoid {
        Ellipsoid {
            semi_axes: self.semi_axes * (1.0 + self.a).sqrt(),
            ..self.ellipsoid()
        }
    }

    /// Axis-aligned bounds of the support.
    pub fn support_bounds(&self) -> Aabb {
        self.ellipsoid().bounds_scaled((1.0 + self.a).sqrt())
    }

    /// The blob's own field `f(x)` (no threshold).
    pub fn value(&self, x: DVec3) -> f64 {
        let u = self.ellipsoid().radius_squared(x) / (1.0 + self.a);
        if u < 1.0 {
            let k = 1.0 - u;
            self.b * self.b * k * k
        } else {
            0.0
        }
    }

    /// True when the blob contributes anything (positive `B` and semi-axes).
    pub fn is_live(&self) -> bool {
        self.b.abs() > 0.0 && self.semi_axes.min_element() > 0.0
    }

    /// Equivalent radius of the blob's ellipsoid: the radius of the sphere of equal volume,
    /// `∛|s_x s_y s_z|`.
    pub fn equivalent_radius(&self) -> f64 {
        self.semi_axes.element_product().abs().cbrt()
    }
}

/// Where a model came from: the source mesh's name, bounds and counts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SourceInfo {
    /// Path or `builtin:NAME` of the fitted mesh.
    pub mesh: String,
    /// Bounding box of the source mesh (its diagonal is the unit of relative errors).
    pub bounds: Aabb,
    /// Vertex count of the source mesh.
    pub vertices: usize,
    /// Triangle count of the source mesh.
    pub faces: usize,
}

/// A fitted blobby model. `blobs` are kept in the decomposition's selection order (the first is
/// the largest), which the diffusion animation relies on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BlobModel {
    /// File format version (see [`model_file::MODEL_VERSION`]).
    pub version: u32,
    /// Ellipsoids or the spherical baseline.
    pub primitive: Primitive,
    /// Iso-level `t`.
    pub threshold: f64,
    /// The fitted mesh.
    pub source: SourceInfo,
    /// Seed the fit was run with.
    pub seed: u64,
    /// Blobs in selection order.
    pub blobs: Vec<Blob>,
}

/// Bounding box of the live blobs' ellipsoids (`ρ = 1`): the box of the shape they stand for.
pub fn ellipsoid_bounds(blobs: &[Blob]) -> Aabb {
    blobs
        .iter()
        .filter(|b| b.is_live())
        .fold(Aabb::EMPTY, |acc, b| acc.union(b.ellipsoid().bounds()))
}

impl BlobModel {
    /// A model made in code rather than fitted (a builtin shape, a test cloud): ellipsoid
    /// `blobs` at iso-level `threshold`, its source named `mesh` with the blobs' ellipsoid box
    /// ([`ellipsoid_bounds`]) and no vertex or face counts.
    pub fn from_blobs(mesh: &str, threshold: f64, seed: u64, blobs: Vec<Blob>) -> BlobModel {
        BlobModel {
            version: model_file::MODEL_VERSION,
            primitive: Primitive::Ellipsoid,
            threshold,
            source: SourceInfo {
                mesh: mesh.into(),
                bounds: ellipsoid_bounds(&blobs),
                vertices: 0,
                faces: 0,
            },
            seed,
            blobs,
        }
    }

    /// The summed field of all blobs, with a spatial index.
    pub fn field(&self) -> BlobField {
        BlobField::new(&self.blobs, self.threshold)
    }

    /// Number of blobs with `B ≠ 0`.
    pub fn live_count(&self) -> usize {
        self.blobs.iter().filter(|b| b.is_live()).count()
    }
}

/// Read a model file in either form: the binary [`codec`] (detected by its magic number) or
/// RON text ([`model_file`]). It lives above both so that the RON file need not know the codec
/// (the codec uses the model file's version and errors).
pub fn load_model(path: &Path) -> Result<BlobModel, ModelError> {
    let bytes = crate::input::read(path, crate::input::Limit::Model).map_err(|source| {
        ModelError::File(FileError::Io {
            path: path.to_path_buf(),
            source,
        })
    })?;
    if codec::is_encoded(&bytes) {
        return codec::decode(path, &bytes);
    }
    let text = std::str::from_utf8(&bytes).map_err(|e| ModelError::Invalid {
        path: path.to_path_buf(),
        message: format!("not a RON model file nor an encoded blob file ({e})"),
    })?;
    model_file::from_ron(path, text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn isolated_blob_reproduces_its_ellipsoid() {
        let e = Ellipsoid {
            center: DVec3::new(0.3, -1.0, 2.0),
            rotation: DQuat::from_euler(glam::EulerRot::XYZ, 0.3, 1.1, -0.4),
            semi_axes: DVec3::new(2.0, 0.5, 1.0),
        };
        for a in [0.3, 1.0, 2.5] {
            let blob = Blob::from_ellipsoid(&e, a);
            for i in 0..50 {
                let t = i as f64 * 0.37;
                let dir = DVec3::new(
                    t.cos() * (2.0 * t).sin(),
                    (2.0 * t).cos(),
                    t.sin() * (2.0 * t).sin(),
                );
                let local = dir.normalize() * e.semi_axes;
                let on = e.center + e.rotation * local;
                let f = blob.value(on) - THRESHOLD;
                assert!(f.abs() < 1e-12, "F = {f} on the ellipsoid (a = {a})");
                assert!(blob.value(e.center + e.rotation * (local * 0.9)) > THRESHOLD);
                assert!(blob.value(e.center + e.rotation * (local * 1.1)) < THRESHOLD);
            }
        }
    }
}
