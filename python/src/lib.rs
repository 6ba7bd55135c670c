//! Python bindings of nephele (module `nephele._nephele`, re-exported by the `nephele` package).
//!
//! Everything goes through the library's public API, the way the command line does: a scene is
//! parsed and validated by `nephele::scene::scene_from_str` (so its errors are the CLI's, with
//! file, line and field), a shot is a `nephele::scene::Shot`, `render_all` is the shot's own
//! resumable run (`Shot::run_until`), and `frames_iter` renders frames in memory through one
//! `nephele::render::FrameRenderer` as that run does (its reuse: holds and still clouds). Long
//! work runs with the GIL released; Python callbacks are called back under it.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use nephele::blobby::{Blob, BlobModel};
use nephele::decompose::Primitive;
use nephele::pipeline::{self, FitConfig};
use nephele::render::output::ColorSpace;
use nephele::render::output::cryptomatte::{self, RANKS};
use nephele::render::{Frame, FrameOptions, FrameRenderer, Reuse};
use nephele::scene::frames::FrameSelection;
use nephele::scene::{self, RenderOptions, SceneError as CoreSceneError, SceneFile};
use pyo3::BoundObject;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyByteArray, PyDict, PyList};

pyo3::create_exception!(
    _nephele,
    NepheleError,
    PyException,
    "Base class of every error nephele raises."
);
pyo3::create_exception!(
    _nephele,
    SceneError,
    NepheleError,
    "A scene that cannot be read, validated, prepared or rendered (file:line:column or field)."
);
pyo3::create_exception!(
    _nephele,
    MeshError,
    NepheleError,
    "A mesh that cannot be read or is not usable (file:line)."
);
pyo3::create_exception!(
    _nephele,
    FitError,
    NepheleError,
    "A fit that cannot be made (bad settings, a mesh enclosing no volume)."
);
pyo3::create_exception!(
    _nephele,
    ModelError,
    NepheleError,
    "A model file that cannot be read or written."
);

/// The error and its causes as one line, each cause once: the CLI's `error_message`.
fn message(e: &(dyn std::error::Error + 'static)) -> String {
    let mut line = String::new();
    let mut cur: Option<&(dyn std::error::Error + 'static)> = Some(e);
    while let Some(c) = cur {
        let text = c.to_string();
        if !line.contains(&text) {
            if !line.is_empty() {
                line.push_str(": ");
            }
            line.push_str(&text);
        }
        cur = c.source();
    }
    line
}

/// A Python exception of class `ty` with `message`, and the attributes in `attrs`.
fn raise<T: pyo3::PyTypeInfo>(py: Python<'_>, msg: String, attrs: &[(&str, Py<PyAny>)]) -> PyErr {
    let err = PyErr::new::<T, _>(msg);
    let value = err.value(py);
    for (k, v) in attrs {
        let _ = value.setattr(*k, v);
    }
    err
}

/// `v` as a Python object (`None` should it not convert: the strings and integers given here
/// always do).
fn to_py<'py, T: IntoPyObject<'py>>(py: Python<'py>, v: T) -> Py<PyAny> {
    v.into_pyobject(py)
        .map_or_else(|_| py.None(), |o| o.into_any().unbind())
}

fn scene_err(e: CoreSceneError) -> PyErr {
    Python::attach(|py| {
        let msg = message(&e);
        let none = || py.None();
        let path = |p: &std::path::Path| to_py(py, p.to_string_lossy());
        let (path, line, column, field) = match &e {
            CoreSceneError::Parse {
                path: p,
                line,
                column,
                ..
            } => (path(p), to_py(py, line), to_py(py, column), none()),
            CoreSceneError::Invalid { path: p, field, .. } => {
                (path(p), none(), none(), to_py(py, field))
            }
            CoreSceneError::Io { path: p, .. } => (path(p), none(), none(), none()),
            CoreSceneError::MissingTarget { scene, .. }
            | CoreSceneError::Mesh { scene, .. }
            | CoreSceneError::Fit { scene, .. }
            | CoreSceneError::Model { scene, .. }
            | CoreSceneError::Animate { scene, .. } => (path(scene), none(), none(), none()),
            _ => (none(), none(), none(), none()),
        };
        raise::<SceneError>(
            py,
            msg,
            &[
                ("path", path),
                ("line", line),
                ("column", column),
                ("field", field),
            ],
        )
    })
}

fn mesh_err(e: nephele::mesh::MeshError) -> PyErr {
    PyErr::new::<MeshError, _>(message(&e))
}
fn fit_err(e: pipeline::FitError) -> PyErr {
    PyErr::new::<FitError, _>(message(&e))
}
fn model_err(e: nephele::blobby::ModelError) -> PyErr {
    PyErr::new::<ModelError, _>(message(&e))
}

/// `bytes` (native-endian values) as a writable numpy array of `dtype` and `shape`.
fn numpy_array<'py>(
    py: Python<'py>,
    bytes: &[u8],
    dtype: &str,
    shape: Vec<usize>,
) -> PyResult<Bound<'py, PyAny>> {
    let np = py.import("numpy")?;
    let buf = PyByteArray::new(py, bytes);
    np.call_method1("frombuffer", (buf, dtype))?
        .call_method1("reshape", (shape,))
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
}
fn f64_bytes(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
}

/// Columns of a blob row: see `BLOB_COLUMNS`.
const BLOB_COLUMNS: [&str; 12] = [
    "cx", "cy", "cz", "qx", "qy", "qz", "qw", "sx", "sy", "sz", "a", "b",
];

fn blobs_array<'py>(py: Python<'py>, blobs: &[Blob]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = blobs
        .iter()
        .flat_map(|b| {
            [
                b.center.x,
                b.center.y,
                b.center.z,
                b.rotation.x,
                b.rotation.y,
                b.rotation.z,
                b.rotation.w,
                b.semi_axes.x,
                b.semi_axes.y,
                b.semi_axes.z,
                b.a,
                b.b,
            ]
        })
        .collect();
    numpy_array(py, &f64_bytes(&flat), "float64", vec![blobs.len(), 12])
}

/// `"ellipsoid"` or `"sphere"`.
fn parse_primitive(name: &str) -> PyResult<Primitive> {
    match name {
        "ellipsoid" => Ok(Primitive::Ellipsoid),
        "sphere" => Ok(Primitive::Sphere),
        other => Err(PyValueError::new_err(format!(
            "primitive must be 'ellipsoid' or 'sphere', got {other:?}"
        ))),
    }
}

/// A fitted blob model.
#[pyclass(module = "nephele", frozen)]
struct Model {
    model: BlobModel,
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
        match self.model.primitive {
            Primitive::Sphere => "sphere",
            _ => "ellipsoid",
        }
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
    /// box of the blobs' ellipsoids). Checked as a model file is (at least one blob, finite
    /// values, semi-axes ≥ 0, `a` > 0, unit quaternions), or `ModelError`.
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
        let np = py.import("numpy")?;
        let array = np.call_method1("asarray", (blobs, "float64"))?;
        let shape: Vec<usize> = array.getattr("shape")?.extract()?;
        if shape.len() != 2 || shape[1] != BLOB_COLUMNS.len() {
            return Err(PyValueError::new_err(format!(
                "blobs must be an (N, {}) array with columns {}, got shape {shape:?}",
                BLOB_COLUMNS.len(),
                BLOB_COLUMNS.join(" ")
            )));
        }
        let rows: Vec<[f64; 12]> = array.call_method0("tolist")?.extract()?;
        let blobs = rows
            .iter()
            .map(|r| Blob {
                center: glam::DVec3::new(r[0], r[1], r[2]),
                rotation: glam::DQuat::from_xyzw(r[3], r[4], r[5], r[6]),
                semi_axes: glam::DVec3::new(r[7], r[8], r[9]),
                a: r[10],
                b: r[11],
            })
            .collect();
        let mut model = BlobModel::from_blobs(&source, threshold, seed, blobs);
        model.primitive = parse_primitive(primitive)?;
        if let Some((lo, hi)) = bounds {
            model.source.bounds.min = glam::DVec3::from_array(lo);
            model.source.bounds.max = glam::DVec3::from_array(hi);
        }
        // The model file's own checks: the model through its RON text (exact both ways).
        let label = Path::new("Model.from_blobs");
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
/// released. `progress(stage)` is called as each stage starts: `"load"`, then the fit's
/// `"winding"`, `"samples"`, `"grow"`, `"select"`, `"optimise"`, then `"done"`. A fit cannot
/// stop midway: an exception `progress` raises (or Ctrl-C) is raised once the fit is over,
/// and no later stage is reported.
#[pyfunction]
#[pyo3(signature = (mesh, blobs=None, seed=None, candidates=None, samples=None, primitive="ellipsoid", progress=None))]
#[allow(clippy::too_many_arguments)]
fn fit(
    py: Python<'_>,
    mesh: PathBuf,
    blobs: Option<usize>,
    seed: Option<u64>,
    candidates: Option<usize>,
    samples: Option<usize>,
    primitive: &str,
    progress: Option<Py<PyAny>>,
) -> PyResult<Model> {
    let defaults = FitConfig::default();
    let cfg = FitConfig {
        blobs: blobs.unwrap_or(defaults.blobs),
        candidates: candidates.unwrap_or(defaults.candidates),
        samples: samples.unwrap_or(defaults.samples),
        seed: seed.unwrap_or(defaults.seed),
        primitive: parse_primitive(primitive)?,
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

/// A loaded, validated scene.
#[pyclass(module = "nephele", frozen)]
struct Scene {
    scene: scene::Scene,
}

#[pymethods]
impl Scene {
    /// Read, parse and validate a scene file (RON).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Scene> {
        let scene = py.detach(|| scene::load_scene(&path)).map_err(scene_err)?;
        Ok(Scene { scene })
    }

    /// Parse and validate scene text (RON); `path` names it in errors and is where relative
    /// target paths resolve from (its folder) and the default output name comes from.
    #[staticmethod]
    #[pyo3(signature = (text, path="scene.ron".into()))]
    fn from_str(text: &str, path: PathBuf) -> PyResult<Scene> {
        let scene = scene::scene_from_str(&path, text).map_err(scene_err)?;
        Ok(Scene { scene })
    }

    /// `from_dict` after `json.dumps`: the JSON is read into the scene file's own types, written
    /// back as RON and loaded like a file (same validation and messages).
    #[staticmethod]
    fn _from_json(py: Python<'_>, json: &str, path: PathBuf) -> PyResult<Scene> {
        let mut de = serde_json::Deserializer::from_str(json);
        let file: SceneFile = serde_path_to_error::deserialize(&mut de).map_err(|e| {
            let field = e.path().to_string();
            let inner = e.into_inner().to_string();
            // serde_json appends " at line L column C" of the JSON text; the field path is
            // what locates it in a dict.
            let inner = match inner.rfind(" at line ") {
                Some(at) => inner[..at].to_string(),
                None => inner,
            };
            let field_py = field.clone().into_pyobject(py).unwrap().into_any().unbind();
            let path_py = path
                .to_string_lossy()
                .into_owned()
                .into_pyobject(py)
                .unwrap()
                .into_any()
                .unbind();
            raise::<SceneError>(
                py,
                format!("{}: {field}: {inner}", path.display()),
                &[
                    ("path", path_py),
                    ("line", py.None()),
                    ("column", py.None()),
                    ("field", field_py),
                ],
            )
        })?;
        let text = ron::ser::to_string_pretty(&file, ron::ser::PrettyConfig::new())
            .map_err(|e| PyErr::new::<SceneError, _>(format!("{}: {e}", path.display())))?;
        let scene = scene::scene_from_str(&path, &text).map_err(scene_err)?;
        Ok(Scene { scene })
    }

    /// The scene file as JSON text (its target paths resolved), for `to_dict`.
    fn _to_json(&self) -> PyResult<String> {
        serde_json::to_string(&self.scene.file).map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The scene file as RON text (its target paths resolved).
    fn to_ron(&self) -> PyResult<String> {
        ron::ser::to_string_pretty(&self.scene.file, ron::ser::PrettyConfig::new())
            .map_err(|e| PyValueError::new_err(e.to_string()))
    }

    /// The scene file's path (as given).
    #[getter]
    fn path(&self) -> PathBuf {
        self.scene.path.clone()
    }

    /// Frame file prefix (`output.name`, else the file's stem).
    #[getter]
    fn name(&self) -> String {
        self.scene.name.clone()
    }

    /// Output folder (`output.dir`, else `renders/<stem>`).
    #[getter]
    fn output_dir(&self) -> PathBuf {
        self.scene.output_dir.clone()
    }

    fn __repr__(&self) -> String {
        format!("nephele.Scene({:?})", self.scene.path)
    }

    /// Open the scene's shot (the options of `nephele render`). `frames` is a frame selection
    /// (`"1..24,30"`, or a list of frame numbers), `formats` overrides `output.formats`
    /// (`["exr", "vdb"]`), `output` overrides the output folder, `region` is
    /// `"x0,y0,x1,y1"`; `clean` removes the frames' files of formats the run does not write
    /// (kept otherwise).
    #[pyo3(signature = (preview=false, passes=false, frames=None, output=None, formats=None, force=false, region=None, dump_blobs=false, clean=false))]
    #[allow(clippy::too_many_arguments)]
    fn shot(
        &self,
        preview: bool,
        passes: bool,
        frames: Option<&Bound<'_, PyAny>>,
        output: Option<PathBuf>,
        formats: Option<Vec<String>>,
        force: bool,
        region: Option<String>,
        dump_blobs: bool,
        clean: bool,
    ) -> PyResult<Shot> {
        let frames = frames.map(|f| selection(f, &self.scene.path)).transpose()?;
        let mut scene = self.scene.clone();
        if let Some(list) = formats {
            let mut out = Vec::new();
            for name in &list {
                out.push(scene::Format::from_name(name).ok_or_else(|| {
                    PyErr::new::<SceneError, _>(format!(
                        "{}: formats: '{name}' is not a format (use exr, png, vdb or vol)",
                        self.scene.path.display()
                    ))
                })?);
            }
            scene.file.output.formats = out;
        }
        let options = RenderOptions {
            frames,
            output,
            preview,
            force,
            clean,
            dump_blobs,
            stats: false,
            passes,
            region,
        };
        let shot = scene::Shot::open(scene, &options).map_err(scene_err)?;
        Ok(Shot { shot })
    }
}

/// A frame selection from Python: a selection string (`"1..24,30"`), a frame number or a
/// list of frame numbers; `path` (the scene's) labels a malformed one.
fn selection(f: &Bound<'_, PyAny>, path: &Path) -> PyResult<FrameSelection> {
    let text = if let Ok(s) = f.extract::<String>() {
        s
    } else if let Ok(n) = f.extract::<u32>() {
        n.to_string()
    } else {
        let list: Vec<u32> = f.extract().map_err(|_| {
            PyValueError::new_err(
                "frames must be a selection string ('1..24,30'), a frame number or a list of frame numbers",
            )
        })?;
        list.iter()
            .map(|n| n.to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    text.parse::<FrameSelection>()
        .map_err(|e| PyErr::new::<SceneError, _>(format!("{}: frames: {e}", path.display())))
}

/// A scene's shot, opened with render options. Nothing mutates it after `Scene.shot`: its
/// target and plan are made once, on first need, so any number of threads (and a
/// `render_all` progress callback) can use it at once.
#[pyclass(module = "nephele", frozen)]
struct Shot {
    shot: scene::Shot,
}

impl Shot {
    fn read(&self) -> &scene::Shot {
        &self.shot
    }

    /// The shot's 0-based frame of `frame`, checked against the whole shot.
    fn index(shot: &scene::Shot, frame: u32) -> PyResult<u32> {
        let first = shot.number(0);
        let last = shot.number(shot.total() - 1);
        if frame < first || frame > last {
            return Err(PyValueError::new_err(format!(
                "frame {frame} is outside the shot (frames {first}..{last})"
            )));
        }
        Ok(shot.index(frame))
    }

    /// Render `frame` on its own (nothing reused, nothing kept) with the GIL released, and
    /// convert it for numpy while still without the GIL.
    fn frame(&self, py: Python<'_>, frame: u32) -> PyResult<Layers> {
        let shot = self.read();
        let k = Self::index(shot, frame)?;
        let space = shot.scene().file.output.colorspace;
        py.detach(|| shot.render_frame(k).map(|image| Layers::of(&image, space)))
            .map_err(scene_err)
    }
}

/// The frame a [`FrameRenderer`] renders for 0-based frame `k` of `shot`: what the shot loop
/// (`Shot::run`) does for each frame — the frame's settings and blobs, its shutter, the shot's
/// film — so a frame comes out with the bits of the CLI's file.
fn render_with(
    renderer: &mut FrameRenderer,
    shot: &scene::Shot,
    k: u32,
) -> Result<(Layers, Reuse), CoreSceneError> {
    let settings = shot.settings(k)?;
    let blobs = shot.blobs(k)?;
    let shutter = shot.shutter(k, settings.quality.time_samples)?;
    let options = FrameOptions {
        shutter: shutter.as_ref(),
        film: shot.film()?,
    };
    let (image, report) = renderer.render_reporting(&settings, &blobs, &options);
    let space = shot.scene().file.output.colorspace;
    Ok((Layers::of(image, space), report.reuse))
}

/// A rendered frame as the bytes of its numpy arrays (native-endian), made without the GIL.
struct Layers {
    width: usize,
    height: usize,
    /// (H, W, 4) float32 RGBA in the output colour space.
    rgba: Vec<u8>,
    /// (H, W) float32.
    depth: Vec<u8>,
    /// `sun`, `sky`, `multiple`: (H, W, 3) float32 each.
    passes: Option<[(&'static str, Vec<u8>); 3]>,
    mattes: Option<MatteLayers>,
}

/// A frame's Cryptomatte layer ([`nephele::render::IdMattes`]) as arrays.
struct MatteLayers {
    layer: String,
    names: Vec<String>,
    /// (H, W, RANKS) int32: the rank's matte (index into `names`), -1 where empty.
    index: Vec<u8>,
    /// (H, W, RANKS) float32: the rank's id as the EXR stores it (0 where empty).
    id: Vec<u8>,
    /// (H, W, RANKS) float32: the rank's coverage.
    coverage: Vec<u8>,
}

impl Layers {
    fn of(image: &Frame, space: ColorSpace) -> Layers {
        let mut rgba = Vec::with_capacity(image.alpha.len() * 4);
        for (rgb, a) in image.rgb.iter().zip(&image.alpha) {
            rgba.extend_from_slice(&convert(rgb, space));
            rgba.push(*a);
        }
        let passes = image.passes.as_ref().map(|p| {
            let layer = |l: &[[f32; 3]]| {
                f32_bytes(&l.iter().flat_map(|c| convert(c, space)).collect::<Vec<_>>())
            };
            [
                ("sun", layer(&p.sun)),
                ("sky", layer(&p.sky)),
                ("multiple", layer(&p.multiple)),
            ]
        });
        let mattes = image.mattes.as_ref().map(|m| {
            let ids: Vec<f32> = m.names.iter().map(|n| cryptomatte::name_id(n)).collect();
            let n = m.ranks.len() * RANKS;
            let (mut index, mut id, mut coverage) = (
                Vec::with_capacity(n),
                Vec::with_capacity(n),
                Vec::with_capacity(n),
            );
            for pixel in &m.ranks {
                for r in pixel {
                    // The EXR writer's rule: an id only where the rank covers something.
                    let named = ids.get(r.matte as usize).filter(|_| r.coverage > 0.0);
                    index.push(named.map_or(-1, |_| r.matte as i32));
                    id.push(named.copied().unwrap_or(0.0));
                    coverage.push(r.coverage);
                }
            }
            MatteLayers {
                layer: m.layer.clone(),
                names: m.names.clone(),
                index: index.iter().flat_map(|x| x.to_ne_bytes()).collect(),
                id: f32_bytes(&id),
                coverage: f32_bytes(&coverage),
            }
        });
        Layers {
            width: image.width as usize,
            height: image.height as usize,
            rgba: f32_bytes(&rgba),
            depth: f32_bytes(&image.depth),
            passes,
            mattes,
        }
    }

    fn rgba<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        numpy_array(py, &self.rgba, "float32", vec![self.height, self.width, 4])
    }

    /// `render_passes`' dict.
    fn dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let (h, w) = (self.height, self.width);
        let out = PyDict::new(py);
        out.set_item("rgba", self.rgba(py)?)?;
        out.set_item(
            "depth",
            numpy_array(py, &self.depth, "float32", vec![h, w])?,
        )?;
        if let Some(passes) = &self.passes {
            for (name, bytes) in passes {
                out.set_item(*name, numpy_array(py, bytes, "float32", vec![h, w, 3])?)?;
            }
        }
        if let Some(m) = &self.mattes {
            let d = PyDict::new(py);
            d.set_item("layer", &m.layer)?;
            d.set_item("names", &m.names)?;
            let ids: Vec<f32> = m.names.iter().map(|n| cryptomatte::name_id(n)).collect();
            let manifest = PyDict::new(py);
            for (name, id) in m.names.iter().zip(&ids) {
                manifest.set_item(name, format!("{:08x}", id.to_bits()))?;
            }
            d.set_item("ids", ids)?;
            d.set_item("manifest", manifest)?;
            d.set_item("key", cryptomatte::layer_key(&m.layer))?;
            let shape = vec![h, w, RANKS];
            d.set_item("index", numpy_array(py, &m.index, "int32", shape.clone())?)?;
            d.set_item("id", numpy_array(py, &m.id, "float32", shape.clone())?)?;
            d.set_item("coverage", numpy_array(py, &m.coverage, "float32", shape)?)?;
            out.set_item("mattes", d)?;
        }
        Ok(out)
    }
}

/// `rgb` in `space`, exactly as the EXR writer converts it (f32 matrix times the Rec.709 value).
fn convert(rgb: &[f32; 3], space: ColorSpace) -> [f32; 3] {
    match space {
        ColorSpace::Rec709 => *rgb,
        _ => (space.from_rec709().as_mat3() * glam::Vec3::from(*rgb)).to_array(),
    }
}

#[pymethods]
impl Shot {
    /// The frame numbers to render (the scene's `frames`, or the `frames` given), sorted.
    #[getter]
    fn frames(&self) -> Vec<u32> {
        self.read().frames().to_vec()
    }

    /// All frame numbers of the shot, first to last.
    #[getter]
    fn all_frames(&self) -> Vec<u32> {
        let shot = self.read();
        (0..shot.total()).map(|k| shot.number(k)).collect()
    }

    /// Image `(width, height)` in pixels.
    #[getter]
    fn size(&self) -> (u32, u32) {
        self.read().size()
    }

    /// Frames per second.
    #[getter]
    fn fps(&self) -> f64 {
        self.read().scene().file.shot.fps
    }

    /// Open shutter as a fraction of a frame (`shot.shutter`; 0 = no motion blur).
    #[getter]
    fn shutter(&self) -> f64 {
        self.read().scene().file.shot.shutter
    }

    /// Folder the frame files are written to.
    #[getter]
    fn dir(&self) -> PathBuf {
        self.read().dir().to_path_buf()
    }

    /// True when frames are rendered with passes.
    #[getter]
    fn passes(&self) -> bool {
        self.read().passes()
    }

    /// The file names of `frame` (one per format, plus the blob dump if asked), in `dir`.
    fn frame_paths(&self, frame: u32) -> Vec<PathBuf> {
        scene::frame_files::frame_paths(self.read(), frame)
    }

    /// Render `frame` in memory: (H, W, 4) float32 linear RGBA, premultiplied, in the scene's
    /// `output.colorspace`: the values of the R, G, B, A channels of the EXR that
    /// `nephele render` writes for the frame, bit for bit. The frame is rendered on its own
    /// (nothing of it is kept); `frames_iter` renders a sequence with the shot's reuse.
    fn render<'py>(&self, py: Python<'py>, frame: u32) -> PyResult<Bound<'py, PyAny>> {
        self.frame(py, frame)?.rgba(py)
    }

    /// Render `frame` in memory with every layer the EXR has: `rgba` (H, W, 4), `depth`
    /// (H, W; the EXR's Z, infinity where empty), and when the shot has passes (`passes=True`
    /// or `output.passes`) `sun`, `sky`, `multiple` (H, W, 3 each; they sum to the RGB) and
    /// `mattes`, the Cryptomatte layer (a dict: `layer`, `names`, `ids`, `manifest`, `key`,
    /// and (H, W, 6) arrays `index` int32, `id` and `coverage` float32, ranked by coverage).
    fn render_passes<'py>(&self, py: Python<'py>, frame: u32) -> PyResult<Bound<'py, PyDict>> {
        self.frame(py, frame)?.dict(py)
    }

    /// Render frames in memory, in order, through one renderer that keeps what the shot loop
    /// keeps (a hold reuses the last frame, a still cloud its light grid): an iterator of
    /// `(frame, image)`, `image` being `render(frame)`'s array, or `render_passes(frame)`'s
    /// dict with `layers=True`. `frames` is a selection like `Scene.shot`'s (default: the
    /// shot's frames). Each frame has the bits `render(frame)` gives.
    #[pyo3(signature = (frames=None, layers=false))]
    fn frames_iter(
        slf: &Bound<'_, Self>,
        frames: Option<&Bound<'_, PyAny>>,
        layers: bool,
    ) -> PyResult<FrameIter> {
        let shot = slf.get().read();
        let frames = match frames {
            None => shot.frames().to_vec(),
            Some(f) => {
                let (first, last) = (shot.number(0), shot.number(shot.total() - 1));
                selection(f, &shot.scene().path)?
                    .resolve(first, last)
                    .map_err(|e| {
                        PyErr::new::<SceneError, _>(format!(
                            "{}: frames: {e}",
                            shot.scene().path.display()
                        ))
                    })?
            }
        };
        Ok(FrameIter {
            shot: slf.clone().unbind(),
            renderer: FrameRenderer::new(),
            frames,
            next: 0,
            layers,
            reuse: None,
        })
    }

    /// The blobs of `frame`, an (N, 12) float64 array with `Model.COLUMNS`.
    fn blobs<'py>(&self, py: Python<'py>, frame: u32) -> PyResult<Bound<'py, PyAny>> {
        let shot = self.read();
        let k = Self::index(shot, frame)?;
        let blobs = py.detach(|| shot.blobs(k)).map_err(scene_err)?;
        blobs_array(py, &blobs)
    }

    /// The target model (loaded, or fitted and cached in the output folder), placed by the
    /// scene's transform.
    #[getter]
    fn target(&self, py: Python<'_>) -> PyResult<Model> {
        let shot = self.read();
        let model = py
            .detach(|| shot.prepared().map(|p| p.model.clone()))
            .map_err(scene_err)?;
        Ok(Model { model })
    }

    /// The camera of `frame` as rendered: `eye`, `right`, `up`, `forward` (world, unit axes),
    /// `tan_half_fov` `(horizontal, vertical)`, and the EXR header's `world_to_camera` and
    /// `world_to_ndc` (4×4, row-vector convention `p' = p · M`).
    fn camera<'py>(&self, py: Python<'py>, frame: u32) -> PyResult<Bound<'py, PyDict>> {
        let shot = self.read();
        let k = Self::index(shot, frame)?;
        let settings = py.detach(|| shot.settings(k)).map_err(scene_err)?;
        let cam = nephele::render::output::CameraFrame::new(
            &settings.camera,
            settings.width,
            settings.height,
        );
        let (view, ndc) = cam.exr_matrices();
        let d = PyDict::new(py);
        d.set_item("eye", cam.eye.to_array())?;
        d.set_item("right", cam.right.to_array())?;
        d.set_item("up", cam.up.to_array())?;
        d.set_item("forward", cam.forward.to_array())?;
        d.set_item("tan_half_fov", (cam.tan_half_h, cam.tan_half_v))?;
        let view32: Vec<f64> = view.iter().map(|v| *v as f32 as f64).collect();
        let ndc32: Vec<f64> = ndc.iter().map(|v| *v as f32 as f64).collect();
        d.set_item(
            "world_to_camera",
            numpy_array(py, &f64_bytes(&view32), "float64", vec![4, 4])?,
        )?;
        d.set_item(
            "world_to_ndc",
            numpy_array(py, &f64_bytes(&ndc32), "float64", vec![4, 4])?,
        )?;
        Ok(d)
    }

    /// Render the shot's frames to files, as `nephele render` does: one run of the shot
    /// (`Shot::run`, its reuse and its writing beside the next frame's render), resumable
    /// (finished, up-to-date frames are skipped unless the shot was opened with `force=True`),
    /// with the GIL released. `progress(report)` is called after each frame with a dict
    /// `frame`, `of` (the shot's last frame), `skipped`, `seconds`, `index` (0-based among the
    /// frames), `count`; the frame's files are then being written (all of them are on disk
    /// when `render_all` returns). An exception `progress` raises, or Ctrl-C, stops the shot
    /// after that frame (its files written) and is raised. Returns `{"dir", "rendered",
    /// "skipped", "out_of_date"}`.
    #[pyo3(signature = (progress=None))]
    fn render_all<'py>(
        &self,
        py: Python<'py>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let shot = self.read();
        let count = shot.frames().len();
        nephele::atomic::check_writable(shot.dir()).map_err(|e| {
            PyErr::new::<SceneError, _>(format!(
                "output folder {} is not writable: {e}",
                shot.dir().display()
            ))
        })?;
        let mut index = 0usize;
        let mut stopped: Option<PyErr> = None;
        let report = py.detach(|| {
            shot.run_until(&mut |f| {
                let i = index;
                index += 1;
                Python::attach(|py| {
                    let called = (|| -> PyResult<()> {
                        if let Some(cb) = &progress {
                            let d = PyDict::new(py);
                            d.set_item("frame", f.frame)?;
                            d.set_item("of", f.of)?;
                            d.set_item("skipped", f.skipped)?;
                            d.set_item("seconds", f.seconds)?;
                            d.set_item("index", i)?;
                            d.set_item("count", count)?;
                            cb.call1(py, (d,))?;
                        }
                        py.check_signals()
                    })();
                    match called {
                        Ok(()) => ControlFlow::Continue(()),
                        Err(e) => {
                            stopped = Some(e);
                            ControlFlow::Break(())
                        }
                    }
                })
            })
        });
        // A failed write is the worse news; else the stop's exception.
        let report = report.map_err(scene_err)?;
        if let Some(e) = stopped {
            return Err(e);
        }
        let d = PyDict::new(py);
        d.set_item("dir", report.output_dir)?;
        d.set_item("rendered", report.rendered)?;
        d.set_item("skipped", report.skipped)?;
        d.set_item("out_of_date", PyList::new(py, report.out_of_date)?)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let shot = self.read();
        let (w, h) = shot.size();
        format!(
            "nephele.Shot({:?}, {} frames, {w}×{h})",
            shot.scene().path,
            shot.frames().len()
        )
    }
}

/// `Shot.frames_iter`'s iterator: renders the next frame on `next()` (GIL released),
/// through one [`FrameRenderer`] for all of them.
#[pyclass(module = "nephele")]
struct FrameIter {
    shot: Py<Shot>,
    renderer: FrameRenderer,
    frames: Vec<u32>,
    next: usize,
    layers: bool,
    reuse: Option<Reuse>,
}

#[pymethods]
impl FrameIter {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&mut self, py: Python<'_>) -> PyResult<Option<(u32, Py<PyAny>)>> {
        let Some(&frame) = self.frames.get(self.next) else {
            return Ok(None);
        };
        self.next += 1;
        let shot = self.shot.get().read();
        let k = shot.index(frame);
        let renderer = &mut self.renderer;
        let (layers, reuse) = py
            .detach(|| render_with(renderer, shot, k))
            .map_err(scene_err)?;
        self.reuse = Some(reuse);
        let image = if self.layers {
            layers.dict(py)?.into_any().unbind()
        } else {
            layers.rgba(py)?.unbind()
        };
        Ok(Some((frame, image)))
    }

    fn __len__(&self) -> usize {
        self.frames.len() - self.next
    }

    /// The frame numbers this iterator renders, in order.
    #[getter]
    fn frames(&self) -> Vec<u32> {
        self.frames.clone()
    }

    /// What the last frame took from the one before: `"frame"` (a hold: nothing rendered),
    /// `"light_grid"` (a still cloud: its lighting), `"buffers"` (memory only; also the first
    /// frame and every frame with motion blur); `None` before the first frame.
    #[getter]
    fn reuse(&self) -> Option<&'static str> {
        self.reuse.map(|r| match r {
            Reuse::Frame => "frame",
            Reuse::LightGrid => "light_grid",
            Reuse::Buffers => "buffers",
        })
    }

    fn __repr__(&self) -> String {
        format!(
            "nephele.FrameIter({} of {} frames left)",
            self.frames.len() - self.next,
            self.frames.len()
        )
    }
}

/// The library's version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[pymodule]
fn _nephele(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("NepheleError", py.get_type::<NepheleError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("MeshError", py.get_type::<MeshError>())?;
    m.add("FitError", py.get_type::<FitError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    m.add_class::<Model>()?;
    m.add_class::<Scene>()?;
    m.add_class::<Shot>()?;
    m.add_class::<FrameIter>()?;
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
