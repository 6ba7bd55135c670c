//! The scene's target model: read from a model file, or fitted from a mesh and cached beside the
//! output as `target-<hash>.ron`, where the hash ([`fit_cache_key`]) covers the mesh (the bytes
//! of a mesh file, or the `builtin:` name), the whole fit configuration, the fit's algorithm
//! version ([`FIT_ALGORITHM_VERSION`]) and the model format version. A cache file that is
//! missing or unreadable is refitted; an unchanged one is reused.

use std::path::{Path, PathBuf};

use crate::scene::{Scene, SceneError, Target};
use glam::DVec3;

use crate::blobby::BlobModel;
use crate::blobby::model_file::MODEL_VERSION;
use crate::file_error::FileError;
use crate::geometry::Aabb;
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

/// The diagonals of the target box (world units, after the scene's `transform`) nephele
/// renders: the renderer works in single precision with a few fixed tolerances, and a target
/// far outside this range rendered empty or wrong frames (measured: faithful from about
/// `4e-6` to `4e12`; the range keeps a margin of more than a decade on each side).
pub const TARGET_DIAGONAL: (f64, f64) = (1e-4, 1e10);

/// How far from the world origin the target box may reach, in diagonals of the box: farther,
/// single-precision positions no longer resolve the cloud (measured: a target 2.5·10⁵
/// diagonals away renders wrong, 2.5·10³ away as at the origin).
pub const TARGET_REACH: f64 = 1e4;

/// Load (or fit and cache in `cache_dir`) the scene's target model. A mesh whose box, moved
/// by the scene's `transform`, is outside [`TARGET_DIAGONAL`] or [`TARGET_REACH`] is refused
/// before it is fitted (see [`check_target_box`]).
/// A scene with a `story` has no `target`: its target is the story's last one (not checked
/// here: [`load_story_target`]).
pub fn load_target(
    scene: &Scene,
    cache_dir: &Path,
) -> Result<(BlobModel, TargetOrigin), SceneError> {
    match &scene.file.target {
        Some(target) => load(scene, target, cache_dir, true, "target"),
        None => load_story_target(scene, scene.file.story.len().saturating_sub(1), cache_dir),
    }
}

/// Load (or fit and cache in `cache_dir`) the target of the scene's story entry `i`, as it
/// was modelled (its `transform` not applied).
pub fn load_story_target(
    scene: &Scene,
    i: usize,
    cache_dir: &Path,
) -> Result<(BlobModel, TargetOrigin), SceneError> {
    let entry = scene.file.story.get(i).ok_or_else(|| SceneError::Invalid {
        path: scene.path.clone(),
        field: "target".into(),
        message: "a scene needs a `target` (or a `story` of targets in turn)".into(),
    })?;
    load(
        scene,
        &entry.target,
        cache_dir,
        false,
        &format!("story[{i}].target"),
    )
}

/// Load (or fit and cache in `cache_dir`) the model `spec` of `scene` (its target, or a
/// morph's `from`). `Model("builtin:cumulus")` is the procedural cumulus.
pub fn load_spec(
    scene: &Scene,
    spec: &Target,
    cache_dir: &Path,
) -> Result<(BlobModel, TargetOrigin), SceneError> {
    load(scene, spec, cache_dir, false, "animation.from")
}

/// What `spec` names, for an error: `the mesh "…"` or `the model "…"`.
pub(crate) fn spec_name(spec: &Target) -> String {
    match spec {
        Target::Model(p) => format!("the model {p:?}"),
        Target::Fit { mesh, .. } => format!("the mesh {mesh:?}"),
    }
}

/// Refuse a target box (`bounds`: world units, after the scene's `transform`) that the
/// renderer cannot draw: a diagonal outside [`TARGET_DIAGONAL`], or a box reaching more than
/// [`TARGET_REACH`] diagonals from the origin. The error names the scene file, the field, the
/// extent found, the supported range, and the `transform` that brings the target into it.
/// `what` names the model or mesh (see [`spec_name`]).
pub fn check_target_box(scene: &Scene, bounds: &Aabb, what: &str) -> Result<(), SceneError> {
    let t = &scene.file.transform;
    let size = bounds.size();
    let diagonal = size.length();
    let (lo, hi) = TARGET_DIAGONAL;
    let spans = format!(
        "{what} spans {} × {} × {} world units{} (diagonal {})",
        num(size.x),
        num(size.y),
        num(size.z),
        if t.scale == 1.0 {
            String::new()
        } else {
            format!(" after transform.scale {}", num(t.scale))
        },
        num(diagonal)
    );
    let invalid = |field: &str, message: String| SceneError::Invalid {
        path: scene.path.clone(),
        field: field.into(),
        message,
    };
    // Written so that a NaN diagonal is refused too.
    if !(diagonal >= lo && diagonal <= hi) {
        // The power of ten that brings the diagonal to between about 0.3 and 3.
        let factor = 10f64.powf(-diagonal.log10().round());
        let scale = t.scale * factor;
        let fix = if scale.is_finite() && scale > 0.0 {
            format!(
                "set `transform: (scale: {})` in the scene (a diagonal of {}) or rescale the file",
                num(scale),
                num(diagonal * factor)
            )
        } else {
            "rescale the file".to_string()
        };
        return Err(invalid(
            "target",
            format!(
                "{spans}, outside the {} to {} world units nephele renders (in single \
                 precision, a target of this size renders empty or wrong frames); {fix}",
                num(lo),
                num(hi)
            ),
        ));
    }
    let reach = bounds.min.abs().max(bounds.max.abs()).max_element();
    if !(reach <= TARGET_REACH * diagonal) {
        let to = t.translate - bounds.center();
        return Err(invalid(
            "transform.translate",
            format!(
                "{spans} and reaches {} from the world origin, more than the {} \
                 diagonals nephele renders (in single precision, positions that far no longer \
                 resolve the cloud); set `transform: (translate: ({}, {}, {}))` to centre it \
                 on the origin, or move the file's geometry nearer",
                num(reach),
                num(TARGET_REACH),
                num(to.x),
                num(to.y),
                num(to.z)
            ),
        ));
    }
    Ok(())
}

/// The diagonals of a mesh (in its file's units) the fit handles: its objective weighs surface
/// distances in those units against dimensionless field values, so a much smaller or larger
/// mesh fits badly (measured on a cube, 10 blobs: as at unit size from `1e-3` to `1e7`, a
/// far worse fit at `1e-4`, none at all at `1e-5`).
pub const FIT_MESH_DIAGONAL: (f64, f64) = (1e-2, 1e7);

/// Refuse to fit a mesh (`bounds`, in its file's units) outside [`FIT_MESH_DIAGONAL`]; the
/// error names the scene file, `field`, the mesh (`what`), its extent, the range and the fix
/// (rescale the file, and keep its size in the shot with `transform.scale`).
fn check_fit_mesh(scene: &Scene, field: &str, what: &str, bounds: &Aabb) -> Result<(), SceneError> {
    let size = bounds.size();
    let diagonal = size.length();
    let (lo, hi) = FIT_MESH_DIAGONAL;
    if diagonal >= lo && diagonal <= hi {
        return Ok(());
    }
    let k = -diagonal.log10().round();
    let scale = scene.file.transform.scale;
    let in_shot = diagonal * scale;
    let fix = if k.is_finite() {
        let keep = if in_shot >= TARGET_DIAGONAL.0 && in_shot <= TARGET_DIAGONAL.1 {
            format!(
                ", and to keep its size in the shot set `transform: (scale: {})`",
                num(scale * 10f64.powf(-k))
            )
        } else {
            String::new()
        };
        format!(
            "multiply the file's coordinates by {} (a diagonal of {}){keep}",
            num(10f64.powf(k)),
            num(diagonal * 10f64.powf(k)),
        )
    } else {
        "rescale the file".to_string()
    };
    Err(SceneError::Invalid {
        path: scene.path.clone(),
        field: field.into(),
        message: format!(
            "{what} spans {} × {} × {} units (diagonal {}), outside the {} to {} units the \
             fit handles (it would fit badly or not at all); {fix}",
            num(size.x),
            num(size.y),
            num(size.z),
            num(diagonal),
            num(lo),
            num(hi)
        ),
    })
}

/// `v` to 4 significant digits, as RON reads it: plain between 10⁻³ and 10⁶, else with an
/// exponent (`4.123e20`).
fn num(v: f64) -> String {
    let v: f64 = format!("{v:.3e}").parse().unwrap_or(v);
    if v == 0.0 || (1e-3..1e6).contains(&v.abs()) {
        format!("{v:?}")
    } else {
        format!("{v:e}")
    }
}

/// [`load_spec`]; with `check`, a mesh's transformed box is checked before the fit
/// ([`check_target_box`]), so nothing is fitted or cached for a target that is refused.
/// `field` names the spec in errors.
fn load(
    scene: &Scene,
    spec: &Target,
    cache_dir: &Path,
    check: bool,
    field: &str,
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
                    field: field.into(),
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
        Target::Fit { mesh, .. } => {
            // A deforming target is fitted on its rest frame (the sequence's first).
            let rest = scene.deforming.as_deref().filter(|_| check);
            let cfg = fit_config(spec).unwrap_or_default();
            let cache = fit_cache_file(&fit_identity(mesh, rest)?, &cfg, cache_dir);
            if cache.exists()
                && let Ok(m) = crate::blobby::load_model(&cache)
            {
                return Ok((m, TargetOrigin::Cached(cache)));
            }
            let loaded = match rest {
                Some(seq) => crate::mesh::prepare(seq.rest(), &seq.rest_name),
                None => crate::mesh::load(mesh),
            }
            .map_err(|source| SceneError::Mesh {
                scene: scene.path.clone(),
                source,
            })?;
            let b = loaded.mesh.bounds();
            check_fit_mesh(scene, field, &spec_name(spec), &b)?;
            if check {
                let moved = (0..8).fold(Aabb::EMPTY, |moved, i| {
                    let corner = DVec3::new(
                        if i & 1 == 0 { b.min.x } else { b.max.x },
                        if i & 2 == 0 { b.min.y } else { b.max.y },
                        if i & 4 == 0 { b.min.z } else { b.max.z },
                    );
                    moved.grown(scene.file.transform.apply_point(corner))
                });
                check_target_box(scene, &moved, &spec_name(spec))?;
            }
            let out = pipeline::fit(&cfg, &loaded).map_err(|source| SceneError::Fit {
                scene: scene.path.clone(),
                source,
            })?;
            crate::blobby::save_model(&cache, &out.model).map_err(model_err)?;
            Ok((out.model, TargetOrigin::Fitted(cache)))
        }
    }
}

/// The fit settings `spec` asks for (`None` for a model): the counts and seed it writes, the
/// rest [`FitConfig::default`].
pub fn fit_config(spec: &Target) -> Option<FitConfig> {
    match spec {
        Target::Model(_) => None,
        Target::Fit {
            blobs,
            candidates,
            samples,
            seed,
            ..
        } => Some(FitConfig {
            blobs: *blobs,
            candidates: *candidates,
            samples: *samples,
            seed: *seed,
            ..FitConfig::default()
        }),
    }
}

/// The cache file in `cache_dir` of the scene's target fit, where [`load_target`] reads or
/// writes it (`None` for a model target). Fails when the mesh file cannot be read.
pub fn target_cache_file(scene: &Scene, cache_dir: &Path) -> Result<Option<PathBuf>, SceneError> {
    let Some(spec @ Target::Fit { mesh, .. }) = scene.file.target.as_ref() else {
        return Ok(None);
    };
    let Some(cfg) = fit_config(spec) else {
        return Ok(None);
    };
    let identity = fit_identity(mesh, scene.deforming.as_deref())?;
    Ok(Some(fit_cache_file(&identity, &cfg, cache_dir)))
}

/// What a fit's cache key knows of its mesh: a deforming target's rest frame (`rest`), a mesh
/// file's bytes, or a builtin's name. Fails when the mesh file cannot be read.
fn fit_identity(
    mesh: &str,
    rest: Option<&crate::mesh::sequence::MeshSequence>,
) -> Result<Vec<u8>, SceneError> {
    Ok(if let Some(seq) = rest {
        seq.rest_identity()
    } else if mesh.starts_with("builtin:") {
        mesh.as_bytes().to_vec()
    } else {
        crate::input::read(Path::new(mesh), crate::input::Limit::Mesh).map_err(|source| {
            SceneError::File(FileError::Io {
                path: PathBuf::from(mesh),
                source,
            })
        })?
    })
}

/// The cache file in `cache_dir` of a fit with `cfg` of the mesh `identity` ([`fit_identity`]):
/// `target-<key>.ron`, [`fit_cache_key`].
fn fit_cache_file(identity: &[u8], cfg: &FitConfig, cache_dir: &Path) -> PathBuf {
    let hash = fit_cache_key(identity, cfg);
    cache_dir.join(format!("target-{hash:016x}.ron"))
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
    let mut h = crate::hash::Fnv1a::new();
    for p in parts {
        h.write(p).write_u64(p.len() as u64);
    }
    h.finish()
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
