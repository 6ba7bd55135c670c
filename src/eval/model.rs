//! The `nephele eval` measurement: a blob model against the mesh it approximates.
//!
//! In: the original mesh and a model. Out: a [`ModelEvaluation`] — the Metro error of the
//! model's polygonization against the mesh (both ways, % of the *mesh's* diagonal `D`), blob
//! and live counts, encoded sizes, the mesh's size `12·n_v + 12·n_f`, reduction ratios, and the
//! quantized codec's extra error — plus stage timings.
//!
//! The codec's extra error is Metro of the *quantized* model's polygonization against the
//! *original* (f64) model's polygonization at the same resolution, on the same grid, so
//! marching-cubes noise cancels and only the quantization shows. On request
//! ([`EvalConfig::quantized_vs_mesh`]) the quantized model is also measured against the mesh
//! (`quantized_error`), which is what a user of the quantized file gets.

use std::path::Path;

use serde::Serialize;

use super::metro::{MetroConfig, MetroReport, compare};
use crate::blobby::BlobModel;
use crate::blobby::codec::{self, Encoding};
use crate::blobby::polygonize::polygonize;
use crate::decompose::Primitive;
use crate::mesh::Mesh;
use crate::progress::Timings;

/// Settings of a model evaluation.
#[derive(Clone, Debug)]
pub struct EvalConfig {
    /// Marching-cubes cells along the longest side of the blob bounds (default 200).
    pub resolution: usize,
    /// Metro sampling. Its `diagonal` is overridden by the mesh's diagonal.
    pub metro: MetroConfig,
    /// Also measure the quantized codec's extra error (one more polygonization and one more
    /// Metro run; default true).
    pub codec_error: bool,
    /// Also measure the quantized model against the mesh (one more Metro run; default false:
    /// it is the model's error plus, at most, the extra error).
    pub quantized_vs_mesh: bool,
}

impl Default for EvalConfig {
    fn default() -> Self {
        EvalConfig {
            resolution: 200,
            metro: MetroConfig::default(),
            codec_error: true,
            quantized_vs_mesh: false,
        }
    }
}

/// Size of the original mesh.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MeshInfo {
    /// Vertex count `n_v`.
    pub vertices: usize,
    /// Triangle count `n_f`.
    pub faces: usize,
    /// `12·n_v + 12·n_f` (paper §5.1: 3 floats a vertex, 3 integers a face).
    pub bytes: usize,
    /// Bounding-box diagonal `D`, the unit of every percentage.
    pub diagonal: f64,
    /// Edges with one face: non-zero for an open mesh (a scan with holes), whose model closes
    /// the holes, so only the mesh → model direction measures the fit.
    pub boundary_edges: usize,
}

impl MeshInfo {
    /// True when the mesh has holes (see [`MeshInfo::boundary_edges`]).
    pub fn is_open(&self) -> bool {
        self.boundary_edges > 0
    }
}

/// The model's blob counts.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModelInfo {
    /// Ellipsoids or spheres.
    pub primitive: Primitive,
    /// Blobs in the model.
    pub blobs: usize,
    /// Blobs with `B ≠ 0` and positive radii.
    pub live: usize,
}

/// The polygonized blob surface that Metro measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PolygonInfo {
    /// Cells along the longest side.
    pub resolution: usize,
    /// Vertices of the polygonization.
    pub vertices: usize,
    /// Triangles of the polygonization.
    pub faces: usize,
}

/// Encoded sizes, data reduction and the quantized form's extra error.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CodecInfo {
    /// Bytes of the lossless encoding (header included).
    pub lossless_bytes: usize,
    /// Bytes of the quantized encoding (header included).
    pub quantized_bytes: usize,
    /// The paper's own count, 36 bytes a blob (9 floats).
    pub paper_bytes: usize,
    /// Mesh bytes / lossless bytes.
    pub reduction_lossless: f64,
    /// Mesh bytes / quantized bytes.
    pub reduction_quantized: f64,
    /// Quantized model's polygonization vs the original model's (the codec's extra error),
    /// percentages of the mesh's diagonal. `None` when not measured.
    pub quantized_extra: Option<MetroReport>,
    /// The mesh vs the quantized model's polygonization. `None` when not measured (the
    /// default).
    pub quantized_error: Option<MetroReport>,
}

/// Everything `nephele eval` reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ModelEvaluation {
    /// The original mesh.
    pub mesh: MeshInfo,
    /// The model.
    pub model: ModelInfo,
    /// The model's polygonization.
    pub polygonization: PolygonInfo,
    /// Metro of the mesh (A) against the model's polygonization (B).
    pub error: MetroReport,
    /// Sizes and the codec's extra error.
    pub codec: CodecInfo,
    /// Wall time of each stage, seconds, in order.
    pub timings: Vec<(String, f64)>,
}

/// The paper's mesh size: `12·n_v + 12·n_f` bytes.
pub fn mesh_bytes(mesh: &Mesh) -> usize {
    12 * mesh.positions.len() + 12 * mesh.triangles.len()
}

/// Measure `model` against `mesh` (see the module header). Never panics on a model whose
/// surface is empty: Metro then reports infinite distances.
pub fn evaluate_model(mesh: &Mesh, model: &BlobModel, cfg: &EvalConfig) -> ModelEvaluation {
    let mut timings = Timings::default();
    let diagonal = mesh.bounds().diagonal();
    let metro = MetroConfig {
        diagonal: Some(diagonal),
        ..cfg.metro.clone()
    };
    let field = model.field();
    let surface = timings.stage("polygonize", || polygonize(&field, cfg.resolution));
    let error = timings.stage("metro", || compare(mesh, &surface, &metro));
    let (lossless, quantized) = timings.stage("encode", || {
        (
            codec::encode(model, Encoding::Lossless),
            codec::encode(model, Encoding::Quantized),
        )
    });
    let (mut quantized_extra, mut quantized_error) = (None, None);
    if cfg.codec_error
        && let Ok(q) = codec::decode(Path::new("<quantized>"), &quantized)
    {
        let q_surface = timings.stage("polygonize q", || polygonize(&q.field(), cfg.resolution));
        quantized_extra =
            Some(timings.stage("metro q extra", || compare(&surface, &q_surface, &metro)));
        if cfg.quantized_vs_mesh {
            quantized_error = Some(timings.stage("metro q", || compare(mesh, &q_surface, &metro)));
        }
    }
    let bytes = mesh_bytes(mesh);
    ModelEvaluation {
        mesh: MeshInfo {
            vertices: mesh.positions.len(),
            faces: mesh.triangles.len(),
            bytes,
            diagonal,
            boundary_edges: mesh.boundary_edge_count(),
        },
        model: ModelInfo {
            primitive: model.primitive,
            blobs: model.blobs.len(),
            live: model.live_count(),
        },
        polygonization: PolygonInfo {
            resolution: cfg.resolution,
            vertices: surface.positions.len(),
            faces: surface.triangles.len(),
        },
        error,
        codec: CodecInfo {
            lossless_bytes: lossless.len(),
            quantized_bytes: quantized.len(),
            paper_bytes: 36 * model.blobs.len(),
            reduction_lossless: bytes as f64 / lossless.len() as f64,
            reduction_quantized: bytes as f64 / quantized.len() as f64,
            quantized_extra,
            quantized_error,
        },
        timings: timings.stages,
    }
}

impl ModelEvaluation {
    /// A readable multi-line report (no timings; see [`ModelEvaluation::timings`]).
    pub fn report(&self) -> String {
        let m = &self.mesh;
        let c = &self.codec;
        let mut s = String::new();
        let mut line = |t: String| {
            s.push_str(&t);
            s.push('\n');
        };
        line(format!(
            "mesh:   {} vertices, {} faces, {} bytes (12 n_v + 12 n_f), diagonal D = {:.6}",
            m.vertices, m.faces, m.bytes, m.diagonal
        ));
        line(format!(
            "model:  {} {:?} blobs, {} live; polygonized at resolution {}: {} vertices, {} faces",
            self.model.blobs,
            self.model.primitive,
            self.model.live,
            self.polygonization.resolution,
            self.polygonization.vertices,
            self.polygonization.faces
        ));
        line("error (Metro, mesh vs model surface):".into());
        line(metro_lines(&self.error, "mesh -> model", "model -> mesh"));
        if m.is_open() {
            let e = &self.error.a_to_b;
            line(format!(
                "open mesh ({} boundary edges): the model closes its holes with surface the mesh does not have, so model -> mesh and Hausdorff measure those caps; the fit's error is one-sided, mesh -> model: mean {:.4}%  max {:.4}% of D",
                m.boundary_edges, e.mean_pct, e.max_pct
            ));
        }
        line(format!(
            "bytes:  lossless {} ({:.1} a blob, reduction {:.1}x), quantized {} ({:.1} a blob, reduction {:.1}x); the paper's 36 a blob: {}",
            c.lossless_bytes,
            per_blob(c.lossless_bytes, self.model.blobs),
            c.reduction_lossless,
            c.quantized_bytes,
            per_blob(c.quantized_bytes, self.model.blobs),
            c.reduction_quantized,
            c.paper_bytes
        ));
        if let Some(x) = &c.quantized_extra {
            line(format!(
                "quantized codec extra error (quantized vs original model surface): mean {:.4}%  max {:.4}% of D",
                x.mean_pct(),
                x.hausdorff_pct
            ));
        }
        if let Some(q) = &c.quantized_error {
            line("quantized model vs mesh:".into());
            line(metro_lines(q, "mesh -> quantized", "quantized -> mesh"));
        }
        s.trim_end().to_string()
    }
}

fn per_blob(bytes: usize, blobs: usize) -> f64 {
    bytes as f64 / blobs.max(1) as f64
}

/// Two aligned lines (one a direction) and the Hausdorff line.
fn metro_lines(r: &MetroReport, ab: &str, ba: &str) -> String {
    let row = |name: &str, d: &super::Distances| {
        format!(
            "  {name:<18} mean {:.6e} ({:.4}%)  rms {:.6e} ({:.4}%)  max {:.6e} ({:.4}%)",
            d.mean, d.mean_pct, d.rms, d.rms_pct, d.max, d.max_pct
        )
    };
    format!(
        "{}\n{}\n  {:<18} {:.6e} ({:.4}% of D); symmetric mean {:.4}%",
        row(ab, &r.a_to_b),
        row(ba, &r.b_to_a),
        "Hausdorff",
        r.hausdorff,
        r.hausdorff_pct,
        r.mean_pct()
    )
}
