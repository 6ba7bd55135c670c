//! `Model` (a fitted blob model: its blobs as an array, files in and out) and `fit`.

use std::path::{Path, PathBuf};

use nephele::blobby::{BLOB_COLUMNS, BlobModel, check_blobs};
use nephele::pipeline::{self, FitConfig};
use pyo3::prelude::*;

use crate::args::{count_at_least, int_in, primitive};
use crate::arrays::{blobs_array, blobs_from_array};
use crate::errors::{ModelError, fit_err, mesh_err, model_err, raise, to_py};

/// A fitted blob model.
#[pyclass(module = "nephele", frozen)]
pub(crate) struct Model {
    pub(crate) model: BlobModel,
}

#[pymethods]
impl Model {
    /// The blobs as an (N, 12) float64 array; columns `Model.COLUMNS`: centre x, y, z; rotation
    /// quaternion x, y, z, w (unit, rotating the blob's axes into the world); semi-axes x, y,
    /// z; the blob's weight `a` and its falloff `b` (`b == 0`: a hidden blob).
    #[getter]
    fn blobs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        blobs_array(py, &self.model.blobs)
    }

    /// Names of the columns of `blobs`.
    #[classattr]
    #[allow(non_snake_case)]
    fn COLUMNS() -> Vec<&'static str> {
        BLOB_COLUMNS.to_vec()
    }

    /// Iso-level of the blob field.
    #[getter]
    fn threshold(&self) -> f64 {
        self.model.threshold
    }

    /// Seed the fit was run with.
    #[getter]
    fn seed(&self) -> u64 {
        self.model.seed
    }

    /// `"ellipsoid"` or `"sphere"`.
    #[getter]
    fn primitive(&self) -> &'static str {
        self.model.primitive.name()
    }

    /// Path or `builtin:NAME` of the fitted mesh.
    #[getter]
    fn source(&self) -> String {
        self.model.source.mesh.clone()
    }

    /// Bounding box of the source mesh, `((x0, y0, z0), (x1, y1, z1))`.
    #[getter]
    fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        let b = &self.model.source.bounds;
        (b.min.to_array(), b.max.to_array())
    }

    fn __len__(&self) -> usize {
        self.model.blobs.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "nephele.Model({} blobs of {}, seed {})",
            self.model.blobs.len(),
            self.model.source.mesh,
            self.model.seed
        )
    }

    /// Write the model as a RON model file (the CLI's `nephele fit -o` format).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        py.detach(|| nephele::blobby::save_model(&path, &self.model))
            .map_err(model_err)
    }

    /// A model from an (N, 12) array of blob rows with `Model.COLUMNS` (what `blobs` gives,
    /// or `Shot.blobs(frame)`): its inverse, exact to the bit. `threshold` is the iso-level
    /// (the fit's is 1.0); `source` names the model's mesh and `bounds` its box (default: the
    /// box of the blobs' ellipsoids). The array must hold real numbers (`TypeError`) in
    /// (N, 12) (`ValueError`); the model is checked as a model file is (at least one blob,
    /// finite values, semi-axes ≥ 0, `a` > 0, unit quaternions), or `ModelError` naming the
    /// row and column (its attributes `row` and `columns`).
    #[staticmethod]
    #[pyo3(signature = (blobs, threshold=nephele::blobby::THRESHOLD, source="python".to_string(), seed=0, primitive="ellipsoid", bounds=None))]
    fn from_blobs(
        py: Python<'_>,
        blobs: &Bound<'_, PyAny>,
        threshold: f64,
        source: String,
        seed: u64,
        primitive: &str,
        bounds: Option<([f64; 3], [f64; 3])>,
    ) -> PyResult<Model> {
        const WHO: &str = "Model.from_blobs";
        let blobs = blobs_from_array(py, WHO, blobs)?;
        if let Err(fault) = check_blobs(&blobs) {
            let columns: Vec<&str> = BLOB_COLUMNS[fault.columns.clone()].to_vec();
            return Err(raise::<ModelError>(
                py,
                format!(
                    "{WHO}: row {}, {} {}",
                    fault.index,
                    fault.column_names(),
                    fault.problem
                ),
                &[
                    ("row", to_py(py, fault.index)),
                    ("columns", to_py(py, columns)),
                ],
            ));
        }
        let mut model = BlobModel::from_blobs(&source, threshold, seed, blobs);
        model.primitive = self::primitive(primitive)?;
        if let Some((lo, hi)) = bounds {
            model.source.bounds.min = glam::DVec3::from_array(lo);
            model.source.bounds.max = glam::DVec3::from_array(hi);
        }
        // The model file's own checks: the model through its RON text (exact both ways).
        let label = Path::new(WHO);
        let text = nephele::blobby::model_file::to_ron(&model);
        let model = nephele::blobby::model_file::from_ron(label, &text).map_err(model_err)?;
        Ok(Model { model })
    }

    /// Read a model file (RON or the binary codec).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        let model = py
            .detach(|| nephele::blobby::load_model(&path))
            .map_err(model_err)?;
        Ok(Model { model })
    }
}

/// Fit a blob model to a mesh file (OBJ, PLY, OFF, STL) or `builtin:NAME`, with the GIL
/// released. `blobs`, `candidates` and `samples` are counts of at least the library's
/// minimum and `seed` an integer ≥ 0 (else `ValueError`, naming it and its range).
/// `progress(stage)` is called as each stage starts: `"load"`, then the fit's `"winding"`,
/// `"samples"`, `"grow"`, `"select"`, `"optimise"`, then `"done"`. A fit cannot stop midway:
/// an exception `progress` raises (or Ctrl-C) is raised once the fit is over, and no later
/// stage is reported.
#[pyfunction]
#[pyo3(signature = (mesh, blobs=None, seed=None, candidates=None, samples=None, primitive="ellipsoid", progress=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn fit(
    py: Python<'_>,
    mesh: PathBuf,
    blobs: Option<&Bound<'_, PyAny>>,
    seed: Option<&Bound<'_, PyAny>>,
    candidates: Option<&Bound<'_, PyAny>>,
    samples: Option<&Bound<'_, PyAny>>,
    primitive: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<Model> {
    let defaults = FitConfig::default();
    let count = |name, v: Option<&Bound<'_, PyAny>>, min, default| {
        v.map_or(Ok(default), |v| count_at_least("fit", name, v, min))
    };
    let cfg = FitConfig {
        blobs: count("blobs", blobs, FitConfig::MIN_BLOBS, defaults.blobs)?,
        candidates: count(
            "candidates",
            candidates,
            FitConfig::MIN_CANDIDATES,
            defaults.candidates,
        )?,
        samples: count("samples", samples, FitConfig::MIN_SAMPLES, defaults.samples)?,
        seed: seed.map_or(Ok(defaults.seed), |v| int_in("fit", "seed", v, 0, u64::MAX))?,
        primitive: self::primitive(primitive)?,
        ..defaults
    };
    cfg.validate().map_err(fit_err)?;
    let source = mesh.to_string_lossy().into_owned();
    let stage = |name: &str| -> PyResult<()> {
        if let Some(cb) = &progress {
            cb.call1(py, (name,))?;
        }
        Ok(())
    };
    stage("load")?;
    let loaded = py
        .detach(|| nephele::mesh::load(&source))
        .map_err(mesh_err)?;
    if !loaded.warnings.is_empty() {
        let warnings = py.import("warnings")?;
        for w in &loaded.warnings {
            warnings.call_method1("warn", (w.to_string(),))?;
        }
    }
    // The fit's own stages, reported as they start; the fit cannot stop midway, so an
    // exception from `progress` (or Ctrl-C) is raised when it ends, and no stage after it is
    // reported.
    let mut failed: Option<PyErr> = None;
    let out = py.detach(|| {
        pipeline::fit_reporting(&cfg, &loaded, &mut |name| {
            if failed.is_some() {
                return;
            }
            Python::attach(|py| {
                let called = match &progress {
                    Some(cb) => cb.call1(py, (name,)).map(|_| ()),
                    None => Ok(()),
                };
                failed = called.and_then(|()| py.check_signals()).err();
            });
        })
    });
    if let Some(e) = failed {
        return Err(e);
    }
    let out = out.map_err(fit_err)?;
    stage("done")?;
    Ok(Model { model: out.model })
}
