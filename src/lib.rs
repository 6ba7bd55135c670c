//! nephele: approximate a closed triangle mesh by a few hundred ellipsoidal blobs (Ellipsoidal-
//! Blob Approximation of 3D Models and Its Applications), and render target-shaped cloud
//! animations that gather or diffuse into it.
//!
//! The pipeline, one module a stage:
//! [`mesh`] → [`decompose`] → [`blobby`] (field, fit, codec, polygonize) → [`animate`] →
//! [`render`], with [`scene`] tying a shot together, [`pipeline`] running a fit and [`export`]
//! taking the cloud out (OpenVDB / Mitsuba density grids, the shot as a USD stage).
#![warn(missing_docs)]
// `!(x > 0.0)` is used on purpose: it rejects NaN along with non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
// Small dense linear algebra (3×3, 10×10) reads best with explicit indices.
#![allow(clippy::needless_range_loop)]

pub mod animate;
pub mod atomic;
pub mod blobby;
pub mod cli;
pub mod decompose;
pub mod error_chain;
pub mod eval;
pub mod export;
pub mod farm;
pub mod file_error;
pub mod geometry;
pub mod hash;
pub mod input;
pub mod mesh;
pub mod pipeline;
pub mod progress;
pub mod render;
pub mod rng;
pub mod scene;
pub mod spline;
pub mod test_hook;
pub mod view;

/// The renderer's version ([`render::RENDER_VERSION`]).
pub use render::RENDER_VERSION;

// The command line's code (`cli`) names the library `nephele::…`, as the binary did.
extern crate self as nephele;
