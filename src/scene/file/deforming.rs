//! A deforming target (`target: Fit(mesh: …)` naming a mesh that moves): read when the scene is,
//! so that a broken sequence is the scene's located error (`scene.ron:3:17: target.mesh: …`)
//! before anything is fitted or rendered.
//!
//! Which meshes deform: a file sequence (`walk_####.obj`, one run of `#` for the zero-padded
//! frame number; [`crate::mesh::sequence`]), a USD stage whose `Mesh` prims have `points` time
//! samples (every visible `Mesh` prim, as holdouts read them), and the builtin deforming shapes
//! ([`crate::mesh::builtin::DEFORMING`], e.g. `builtin:waving-tube`).
//!
//! Time: a file's frame number is the shot's frame number (`walk_0001.obj` is frame 1 of a shot
//! starting at 1, as Houdini's `$F`); a USD time code `c` is the shot's frame
//! `c · fps / timeCodesPerSecond` (the camera's rule); a builtin's frames count from the shot's
//! first frame. Before the sequence's first frame and after its last the target holds (as a
//! Nuke Read node's `hold`); between frames its vertices move linearly.

use std::path::Path;
use std::sync::Arc;

use super::{SceneFile, Target};
use crate::mesh::sequence::{MeshSequence, is_pattern};

/// The mesh sequence of `file`'s target when it deforms (`None` for a still target). `base`
/// is the scene file's folder; an error is `(field, message)` for the scene to locate.
pub fn load(base: &Path, file: &SceneFile) -> Result<Option<Arc<MeshSequence>>, (String, String)> {
    let Target::Fit { mesh, .. } = &file.target else {
        return Ok(None);
    };
    let field = "target.mesh".to_string();
    let seq = if let Some(name) = mesh.strip_prefix("builtin:") {
        match MeshSequence::builtin(name) {
            Some(s) => s,
            None => return Ok(None),
        }
    } else if is_pattern(mesh) {
        let full = base.join(mesh);
        MeshSequence::load_pattern(&full.to_string_lossy()).map_err(|e| (field, e.to_string()))?
    } else if super::usd_mesh::is_usd(mesh) {
        let full = base.join(mesh);
        let super::usd_mesh::MeshFrames {
            meshes,
            time_codes: codes,
            time_codes_per_second: tcps,
        } = super::usd_mesh::read_frames(&full, None).map_err(|e| (field.clone(), e.message))?;
        let scale = tcps.map_or(1.0, |c| file.shot.fps / c);
        let names = codes
            .iter()
            .map(|c| format!("{} at time code {c}", full.display()))
            .collect::<Vec<_>>();
        if meshes.len() < 2 {
            return Err((
                field,
                format!(
                    "{}: a deforming target needs `points` time samples at two or more time \
                     codes, found {}; nephele fits a still mesh from OBJ, PLY, OFF or STL",
                    full.display(),
                    meshes.len()
                ),
            ));
        }
        let numbers = codes.iter().map(|c| c * scale).collect();
        MeshSequence::from_frames(&full.to_string_lossy(), &names, meshes, numbers)
            .map_err(|e| (field, e.to_string()))?
    } else {
        return Ok(None);
    };
    Ok(Some(Arc::new(seq)))
}
