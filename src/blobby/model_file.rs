//! The RON model file: versioned, human-readable, and an exact round trip (f64 values are
//! printed in their shortest exact form, so a model reads back to the identical field).

use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::BlobModel;
use crate::file_error::FileError;

/// Version written by this build; files with a larger version are refused.
pub const MODEL_VERSION: u32 = 1;

/// Errors reading or writing a model file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// The file could not be read or written, or its RON text does not parse (at its
    /// `line:column`).
    #[error(transparent)]
    File(#[from] FileError),
    /// The file was written by a newer nephele.
    #[error(
        "{path}: model file version {found} is newer than this nephele supports ({supported}); upgrade nephele or refit the model"
    )]
    Version {
        /// File concerned.
        path: PathBuf,
        /// Version in the file.
        found: u32,
        /// Newest version this build reads.
        supported: u32,
    },
    /// The content parsed but is not a usable model.
    #[error("{path}: {message}")]
    Invalid {
        /// File concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

/// Turn a RON span error into a located [`ModelError::File`].
pub(crate) fn ron_error(path: &Path, e: &ron::error::SpannedError) -> ModelError {
    ModelError::File(FileError::ron(path, e))
}

/// Serialize a model to RON text.
pub fn to_ron(model: &BlobModel) -> String {
    let config = ron::ser::PrettyConfig::new()
        .depth_limit(3)
        .struct_names(true)
        .new_line("\n");
    ron::ser::to_string_pretty(model, config).expect("a BlobModel always serializes")
}

/// Parse RON text (the file name only labels errors). Checks the version first, so a future
/// file gets a version error rather than an unknown-field error.
pub fn from_ron(path: &Path, text: &str) -> Result<BlobModel, ModelError> {
    #[derive(Deserialize)]
    #[serde(rename = "BlobModel")]
    struct Probe {
        version: u32,
    }
    if let Ok(p) = ron::from_str::<Probe>(text)
        && p.version > MODEL_VERSION
    {
        return Err(ModelError::Version {
            path: path.to_path_buf(),
            found: p.version,
            supported: MODEL_VERSION,
        });
    }
    let model: BlobModel = ron::from_str(text).map_err(|e| ron_error(path, &e))?;
    validate(path, &model)?;
    Ok(model)
}

fn validate(path: &Path, model: &BlobModel) -> Result<(), ModelError> {
    let invalid = |message: String| ModelError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    if model.blobs.is_empty() {
        return Err(invalid("model has no blobs".into()));
    }
    if !(model.threshold.is_finite() && model.threshold > 0.0) {
        return Err(invalid(format!(
            "threshold must be positive, got {}",
            model.threshold
        )));
    }
    super::check_blobs(&model.blobs).map_err(|fault| invalid(fault.to_string()))
}

/// Write a model file atomically.
pub fn save_model(path: &Path, model: &BlobModel) -> Result<(), ModelError> {
    crate::atomic::write_bytes_atomically(path, to_ron(model).as_bytes()).map_err(|source| {
        ModelError::File(FileError::Io {
            path: path.to_path_buf(),
            source,
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blobby::{Blob, SourceInfo};
    use crate::decompose::Primitive;
    use crate::geometry::Aabb;
    use glam::{DQuat, DVec3};

    pub(crate) fn sample_model() -> BlobModel {
        let blobs = (0..7)
            .map(|i| {
                let t = i as f64 * 0.731;
                Blob {
                    center: DVec3::new(t.sin(), t.cos() / 3.0, t * 0.1),
                    rotation: DQuat::from_euler(glam::EulerRot::XYZ, t, t * t, 0.1),
                    semi_axes: DVec3::new(0.3 + t / 7.0, 0.2, 0.1 * std::f64::consts::PI),
                    a: 1.0 / 3.0 + t,
                    b: 0.1 + t * t,
                }
            })
            .collect();
        BlobModel {
            version: MODEL_VERSION,
            primitive: Primitive::Ellipsoid,
            threshold: 1.0,
            source: SourceInfo {
                mesh: "builtin:test".into(),
                bounds: Aabb {
                    min: DVec3::splat(-1.0),
                    max: DVec3::splat(1.0 / 3.0),
                },
                vertices: 10,
                faces: 16,
            },
            seed: 7,
            blobs,
        }
    }

    #[test]
    fn ron_round_trip_is_exact() {
        let m = sample_model();
        let text = to_ron(&m);
        let back = from_ron(Path::new("m.ron"), &text).unwrap();
        assert_eq!(m, back);
        let (f, g) = (m.field(), back.field());
        for i in 0..200 {
            let x = DVec3::new(
                (i as f64 * 0.1).sin(),
                (i as f64 * 0.07).cos() * 0.3,
                i as f64 * 0.004,
            );
            assert_eq!(f.value(x).to_bits(), g.value(x).to_bits());
        }
    }

    #[test]
    fn future_version_and_unknown_field_are_located_errors() {
        let m = sample_model();
        let text = to_ron(&m).replacen("version: 1", "version: 99", 1);
        let e = from_ron(Path::new("m.ron"), &text).unwrap_err();
        assert!(matches!(e, ModelError::Version { found: 99, .. }), "{e}");
        let text = to_ron(&m).replacen("seed:", "colour: 3,\n    seed:", 1);
        let e = from_ron(Path::new("m.ron"), &text).unwrap_err().to_string();
        assert!(e.starts_with("m.ron:") && e.contains("colour"), "{e}");
    }
}
