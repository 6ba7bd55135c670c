//! The scene files in `scenes/` that every look and silhouette check walks through.

use std::path::PathBuf;

/// Names of the builtin scenes (`scenes/NAME.ron`).
pub const NAMES: [&str; 6] = [
    "duck-diffusion",
    "duck-aggregation",
    "torus-knot-aggregation",
    "bunny-aggregation",
    "horse-diffusion",
    "cumulus-to-duck",
];

/// Path of builtin scene `name`.
pub fn path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(format!("{name}.ron"))
}
