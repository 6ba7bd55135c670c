//! The scene's target model: read from a model file, or fitted from a mesh and cached beside the
//! output as `target-<hash>.ron`, where the hash covers the mesh (the bytes of a mesh file, or
//! the `builtin:` name), the fit settings, the model format version and the crate version. A
//! cache file that is missing or unreadable is refitted; an unchanged one is reused.

use std::path::{Path, PathBuf};

use super::{Scene, SceneError, Target};
use crate::blobby::BlobModel;
use crate::blobby::model_file::MODEL_VERSION;
use crate::pipeline::{self, FitConfig};

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
    let model_err = |source| SceneError::Model {
        scene: scene.path.clone(),
        source,
    };
    match &scene.file.target {
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
                std::fs::read(mesh).map_err(|source| SceneError::Io {
                    path: PathBuf::from(mesh),
                    source,
                })?
            };
            let settings = format!(
                "nephele {} model v{MODEL_VERSION}; blobs {blobs} candidates {candidates} samples {samples} seed {seed}",
                env!("CARGO_PKG_VERSION")
            );
            let hash = fnv1a(&[&identity, settings.as_bytes()]);
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
            let cfg = FitConfig {
                blobs: *blobs,
                candidates: *candidates,
                samples: *samples,
                seed: *seed,
                ..FitConfig::default()
            };
            let out = pipeline::fit(&cfg, &loaded).map_err(|source| SceneError::Fit {
                scene: scene.path.clone(),
                source,
            })?;
            crate::blobby::save_model(&cache, &out.model).map_err(model_err)?;
            Ok((out.model, TargetOrigin::Fitted(cache)))
        }
    }
}

/// 64-bit FNV-1a over the concatenated parts, each followed by its length (so part boundaries
/// count). Stable across platforms and versions.
fn fnv1a(parts: &[&[u8]]) -> u64 {
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
}
