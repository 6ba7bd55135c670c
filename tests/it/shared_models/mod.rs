//! The standard test meshes in `../shared/models/`: tests that read them skip, with a message,
//! when that folder is absent (a fresh clone of the repository alone).
// Each test crate includes this module and may use only some of it.
#![allow(dead_code)]

use nephele::mesh::LoadedMesh;

/// `file` in `../shared/models/`, loaded; `None` (after saying the test skips) when absent.
pub fn load(file: &str) -> Option<LoadedMesh> {
    let path = format!("{}/../shared/models/{file}", env!("CARGO_MANIFEST_DIR"));
    if !std::path::Path::new(&path).exists() {
        eprintln!("skipping: {path} not found (the shared test models are absent)");
        return None;
    }
    Some(nephele::mesh::load(&path).unwrap_or_else(|e| panic!("{e}")))
}
