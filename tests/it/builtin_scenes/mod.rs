//! The scene files in `scenes/` that every look and silhouette check walks through.
//!
//! Two of them fit a mesh from the standard test models in `../shared/models/` (beside the
//! repository, not in it): `bunny-aggregation` (`bunny.off`) and `horse-diffusion`
//! (`horse.ply`). The others fit `builtin:` meshes, made in code and always there.

use std::path::{Component, Path, PathBuf};

use nephele::scene::{Scene, SceneError, load_scene};

/// Names of the builtin scenes (`scenes/NAME.ron`).
pub const NAMES: [&str; 6] = [
    "duck-diffusion",
    "duck-aggregation",
    "torus-knot-aggregation",
    "bunny-aggregation",
    "horse-diffusion",
    "cumulus-to-duck",
];

/// How many of [`NAMES`] fit a `builtin:` mesh, so load wherever the repository is.
pub const ON_BUILTIN_MESHES: usize = 4;

/// The directed scenes (issue 51), all on `builtin:` meshes: a target that moves
/// (`duck-drift`, keyed `transform`), one that bends (`waving-tube`, a mesh sequence) and a
/// story of targets (`cumulus-duck-torus-knot`). Their final frames are walked by the look and
/// silhouette checks with the target where the final frame has it (see
/// `render::final_target_mesh`); [`NAMES`]' other walks (the picture sheets, the pinned
/// frames) leave them to their own tests (`moving`, `deform`, `story`).
pub const DIRECTED: [&str; 3] = ["duck-drift", "waving-tube", "cumulus-duck-torus-knot"];

/// Path of builtin scene `name`.
pub fn path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(format!("{name}.ron"))
}

/// Builtin scene `name`, loaded; `None` (after saying it skips) only when its target is a mesh
/// in `../shared/models/` and that folder is absent. Any other error panics: a broken scene
/// fails the test that walks it.
pub fn load(name: &str) -> Option<Scene> {
    match load_scene(&path(name)) {
        Ok(scene) => Some(scene),
        Err(SceneError::MissingTarget { target, .. })
            if lexical(&target).starts_with(shared_models()) && !shared_models().exists() =>
        {
            eprintln!(
                "skipped {name}: its target {} is in ../shared/models, which is absent (the \
                 shared test models are not beside this clone)",
                target.display()
            );
            None
        }
        Err(e) => panic!("builtin scene {name}: {e}"),
    }
}

/// `../shared/models` beside the repository, without `..`.
fn shared_models() -> PathBuf {
    lexical(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/models"))
}

/// `p` with `.` and `..` resolved by the names alone (the folder may not exist to
/// canonicalize).
fn lexical(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                out.pop();
            }
            other => out.push(other),
        }
    }
    out
}
