//! The scene's target model: read from a model file, or fitted from a mesh and cached beside the
//! output as `target-<hash>.ron`, where the hash ([`fit_cache_key`]) covers the mesh (the bytes
//! of a mesh file, or the `builtin:` name), the whole fit configuration, the fit's algorithm
//! version ([`FIT_ALGORITHM_VERSION`]) and the model format version. A cache file that is
//! missing or unreadable is refitted; an unchanged one is reused.

use std::path::{Path, PathBuf};

use super::{Scene, SceneError, Target};
use crate::blobby::BlobModel;
use crate::blobby::model_file::MODEL_VERSION;
use crate::pipeline::{self, FIT_ALGORITHM_VERSION, FitConfig};

/// Where the target came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TargetOrigin {
    /// Read from the scene's model file.
    ModelFile(PathBuf),
    /// Fitted now and written to the cache file.
    Fitted(PathBuf),
    /// Read from an up-to-date cache file.
    Cached(PathBuf),
}

/// Load (or fit and cache in `cache_dir`) the scene's target model.
pub fn load_target(
    scene: &Scene,
    cache_dir: &Path,
) -> Result<(BlobModel, TargetOrigin), SceneError> {
    load_spec(scene, &scene.file.target, cache_dir)
}

/// Load (or fit and cache in `cache_dir`) the model `spec` of `scene` (its target, or a
/// morph's `from`). `Model("builtin:cumulus")` is the procedural cumulus.
pub fn load_spec(
    scene: &Scene,
    spec: &Target,
    cache_dir: &Path,
) -> Result<(BlobModel, TargetOrigin), SceneError> {
    let model_err = |source| SceneError::Model {
        scene: scene.path.clone(),
        source,
    };
    match spec {
        Target::Model(p) if p.starts_with("builtin:") => {
            let name = &p["builtin:".len()..];
            let m = crate::animate::cumulus::builtin_model(name).ok_or_else(|| {
                SceneError::Invalid {
                    path: scene.path.clone(),
                    field: "target".into(),
                    message: format!(
                        "no builtin model {p:?}; the builtin model is builtin:cumulus"
                    ),
                }
            })?;
            Ok((m, TargetOrigin::ModelFile(PathBuf::from(p))))
        }
        Target::Model(p) => {
            let path = PathBuf::from(p);
            let m = crate::blobby::load_model(&path).map_err(model_err)?;
            Ok((m, TargetOrigin::ModelFile(path)))
        }
        Target::Fit {
            mesh,
            blobs,
            candidates,
            samples,
            seed,
        } => {
            let identity: Vec<u8> = if mesh.starts_with("builtin:") {
                mesh.as_bytes().to_vec()
            } else {
                crate::input::read(Path::new(mesh), crate::input::Limit::Mesh).map_err(
                    |source| SceneError::Io {
                        path: PathBuf::from(mesh),
                        source,
                    },
                )?
            };
            let cfg = FitConfig {
                blobs: *blobs,
                candidates: *candidates,
                samples: *samples,
                seed: *seed,
                ..FitConfig::default()
            };
            let hash = fit_cache_key(&identity, &cfg);
            let cache = cache_dir.join(format!("target-{hash:016x}.ron"));
            if cache.exists()
                && let Ok(m) = crate::blobby::load_model(&cache)
            {
                return Ok((m, TargetOrigin::Cached(cache)));
            }
            let loaded = crate::mesh::load(mesh).map_err(|source| SceneError::Mesh {
                scene: scene.path.clone(),
                source,
            })?;
            let out = pipeline::fit(&cfg, &loaded).map_err(|source| SceneError::Fit {
                scene: scene.path.clone(),
                source,
            })?;
            crate::blobby::save_model(&cache, &out.model).map_err(model_err)?;
            Ok((out.model, TargetOrigin::Fitted(cache)))
        }
    }
}

/// The fitted-target cache key of a mesh (`identity`: its file's bytes or `builtin:` name)
/// fitted with `cfg`: the whole configuration serialized as JSON (every field, nested settings
/// included, floats in round-trip precision), [`FIT_ALGORITHM_VERSION`] and the model format
/// version.
pub fn fit_cache_key(identity: &[u8], cfg: &FitConfig) -> u64 {
    // A plain struct always serializes; `Debug` would serve as well should that ever fail.
    let config = serde_json::to_string(cfg).unwrap_or_else(|_| format!("{cfg:?}"));
    let settings = format!("fit v{FIT_ALGORITHM_VERSION}; model v{MODEL_VERSION}; {config}");
    fnv1a(&[identity, settings.as_bytes()])
}

/// 64-bit FNV-1a over the concatenated parts, each followed by its length (so part boundaries
/// count). Stable across platforms and versions.
pub(crate) fn fnv1a(parts: &[&[u8]]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |b: u8| {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    };
    for p in parts {
        p.iter().copied().for_each(&mut eat);
        (p.len() as u64)
            .to_le_bytes()
            .into_iter()
            .for_each(&mut eat);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_is_stable_and_separates_parts() {
        assert_eq!(fnv1a(&[]), 0xcbf2_9ce4_8422_2325);
        assert_ne!(fnv1a(&[b"ab", b"c"]), fnv1a(&[b"a", b"bc"]));
        assert_eq!(fnv1a(&[b"duck"]), fnv1a(&[b"duck"]));
    }

    #[test]
    fn cache_key_covers_the_whole_fit_configuration() {
        use crate::pipeline::Optimisation;
        let base = FitConfig::default();
        let key = fit_cache_key(b"builtin:duck", &base);
        assert_ne!(key, fit_cache_key(b"builtin:bunny", &base));
        // Settings the scene file cannot set still count (an optimiser change is seen).
        let changed = [
            FitConfig {
                epsilon: base.epsilon * 1.5,
                ..base.clone()
            },
            FitConfig {
                voxels: base.voxels + 1,
                ..base.clone()
            },
            FitConfig {
                optimisation: Optimisation::None,
                ..base.clone()
            },
            FitConfig {
                initial_a: 0.5,
                ..base.clone()
            },
        ];
        for cfg in &changed {
            assert_ne!(fit_cache_key(b"builtin:duck", cfg), key, "{cfg:?}");
        }
    }

    /// Pins what a small fit produces to [`FIT_ALGORITHM_VERSION`]. When this fails, the fit's
    /// output changed: bump `FIT_ALGORITHM_VERSION` (in `src/pipeline.rs`) and update both
    /// numbers here, so that old cached targets are refitted.
    #[test]
    fn fit_algorithm_version_is_pinned_to_the_fit_output() {
        let mesh = crate::mesh::load("builtin:duck").unwrap();
        let cfg = FitConfig {
            blobs: 16,
            candidates: 200,
            samples: 3000,
            ..FitConfig::default()
        };
        let model = pipeline::fit(&cfg, &mesh).unwrap().model;
        let bits: Vec<u8> = model
            .blobs
            .iter()
            .flat_map(|b| {
                let q = b.rotation;
                [b.center.to_array(), b.semi_axes.to_array()]
                    .into_iter()
                    .flatten()
                    .chain([q.x, q.y, q.z, q.w, b.a, b.b])
                    .collect::<Vec<f64>>()
            })
            .flat_map(|v| v.to_bits().to_le_bytes())
            .collect();
        let output = fnv1a(&[&bits]);
        assert_eq!(
            (FIT_ALGORITHM_VERSION, output),
            (4, 9_277_192_188_482_451_073),
            "the fit's output changed: bump FIT_ALGORITHM_VERSION and re-pin"
        );
    }
}
