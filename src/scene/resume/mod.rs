//! What makes a run resumable and safe to repeat: each frame's provenance (its inputs hashed
//! part by part through a canonical encoding, [`provenance`], [`canonical`]), its files written
//! atomically with the manifest last ([`frame_files`]), one writer per frame ([`lock`]), and the
//! caches a run leaves for the next ([`blend_cache`]).

pub(crate) mod blend_cache;
pub mod canonical;
pub mod frame_files;
pub mod frame_names;
pub mod lock;
pub mod provenance;
