//! Cloud animation schemes (paper §5.2, DESIGN.md §6): aggregation (pieces of cloud gather into
//! the target) and diffusion (the target spreads from one piece).
//!
//! In: a fitted [`crate::blobby::BlobModel`] and the scheme's settings. Out: per frame, the full
//! blob list (index = blob identity, same length as the model; hidden blobs have `B = 0`).
//! The last frame equals the model's blobs exactly.
