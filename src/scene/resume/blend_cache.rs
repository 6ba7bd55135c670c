//! The diffusion's blend path cached beside the fitted target, as `blend-<key>.ron` in the
//! output folder.
//!
//! A diffusion's blend follows a path paced by the visible volume of 289 blob sets (about
//! 0.3 s wall for the duck, [`crate::animate::DiffusionPlan::blend_key`]), made by the first
//! frame inside the blend a process renders. A farm's tasks and a `--frames` run each paid it
//! again; now the first process that makes it (`prepare`, or a render) leaves it here and the
//! others read it. The key covers every blob set the volumes are measured on, so a changed
//! target or animation never reads a stale path (a file under a key holds the path nephele
//! makes for it); a file that does not parse, or does not hold a path, is ignored, the path made
//! anew and the file replaced.

use std::path::{Path, PathBuf};

use crate::animate::Plan;
use crate::file_error::FileError;
use crate::scene::SceneError;

/// The cache file of the path with `key` in `dir`.
fn file(dir: &Path, key: u64) -> PathBuf {
    dir.join(format!("blend-{key:016x}.ron"))
}

/// Give `plan` its blend path from `dir`'s cache, if the plan is a diffusion whose blend needs
/// one and the cache holds a valid path for its key. True when a path was taken.
pub fn load(dir: &Path, plan: &Plan) -> bool {
    let Some(d) = plan.diffusion() else {
        return false;
    };
    let Some(key) = d.blend_key() else {
        return false;
    };
    let Ok(text) = crate::input::read_to_string(&file(dir, key), crate::input::Limit::Own) else {
        return false;
    };
    match ron::from_str::<Vec<[f64; 3]>>(&text) {
        Ok(knots) => d.use_blend_knots(&knots),
        Err(_) => false,
    }
}

/// Write `plan`'s blend path to `dir`'s cache when it has been made and the cache does not
/// hold it yet (a damaged file is replaced; atomically: tasks writing the same path at once
/// leave one whole file).
pub fn store(dir: &Path, plan: &Plan) -> Result<(), SceneError> {
    let Some(d) = plan.diffusion() else {
        return Ok(());
    };
    let (Some(key), Some(knots)) = (d.blend_key(), d.blend_knots()) else {
        return Ok(());
    };
    let path = file(dir, key);
    let held = crate::input::read_to_string(&path, crate::input::Limit::Own)
        .ok()
        .and_then(|text| ron::from_str::<Vec<[f64; 3]>>(&text).ok());
    if held.as_ref() == Some(&knots) {
        return Ok(());
    }
    // Floats in round-trip precision: the path read back is the path made, bit for bit.
    let text = ron::to_string(&knots).map_err(|e| {
        SceneError::File(FileError::Io {
            path: path.clone(),
            source: std::io::Error::other(e.to_string()),
        })
    })?;
    crate::atomic::write_bytes_atomically(&path, text.as_bytes())
        .map_err(|source| SceneError::File(FileError::Io { path, source }))
}
