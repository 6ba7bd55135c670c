//! nephele's integration tests, one binary (one link of the library instead of one per file):
//! each module is one area, run alone with `cargo test --release --test it -- AREA::`.
//! Modules ending in `_support` (and `builtin_scenes`, `mesh_checks`, `shared_models`) are the
//! helpers they share.

mod builtin_scenes;
mod cli_support;
mod eval_support;
mod exr_support;
mod look_support;
mod mesh_checks;
mod readers_support;
mod shared_models;
mod temp_support;
mod view_support;

mod animate;
mod bench;
mod builtin;
mod cli_flags;
mod codec;
mod decompose;
mod deform;
mod environment;
mod eval;
mod export;
mod farm;
mod fit;
mod frames;
mod integrity;
mod look;
mod mesh_io;
mod mitsuba;
mod moving;
mod polygonize;
mod readme_defaults;
mod reference;
mod render;
mod robustness;
mod scene;
mod sheets;
mod story;
mod surfaces;
mod usd_camera;
mod usd_holdouts;
mod view;
