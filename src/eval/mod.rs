//! Evaluation (paper §5.1; docs/ARCHITECTURE.md, Evaluation and codec): how far a blob model's surface is from the mesh it was
//! fitted to, and how many bytes it takes.
//!
//! - [`metro`]: Metro's method (Cignoni, Rocchini & Scopigno 1998) on two triangle meshes —
//!   area-weighted samples plus all vertices of each surface, nearest point on the other surface
//!   through a BVH, both directions; mean, RMS, max and the Hausdorff distance.
//! - [`model`]: the whole `nephele eval` measurement of a model against its mesh: polygonize,
//!   Metro both ways, encoded sizes (lossless and quantized), data reduction, and the quantized
//!   codec's extra error.
//!
//! In: meshes and models. Out: typed, serde-serializable reports.

pub mod metro;
pub mod model;

pub use metro::{Distances, MetroConfig, MetroReport, compare};
pub use model::{EvalConfig, ModelEvaluation, evaluate_model, mesh_bytes};
