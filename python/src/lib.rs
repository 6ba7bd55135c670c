//! Python bindings of nephele (module `nephele._nephele`, re-exported by the `nephele` package).
//!
//! Everything goes through the library's public API, the way the command line does: a scene is
//! parsed and validated by `nephele::scene::scene_from_str` (so its errors are the CLI's, with
//! file, line and field), a shot is a `nephele::scene::Shot`, and `render_all` is the shot's own
//! resumable run. Long work runs with the GIL released.

use std::path::{Path, PathBuf};
use std::sync::RwLock;

use nephele::blobby::{Blob, BlobModel};
use nephele::decompose::Primitive;
use nephele::pipeline::{self, FitConfig};
use nephele::render::Frame;
use nephele::render::output::ColorSpace;
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

    /// Read a model file (RON or the binary codec).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Model> {
        let model = py
            .detach(|| nephele::blobby::load_model(&path))
            .map_err(model_err)?;
        Ok(Model { model })
    }
}

/// Fit a blob model to a mesh file (OBJ, PLY, OFF, STL) or `builtin:NAME`.
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
        primitive: match primitive {
            "ellipsoid" => Primitive::Ellipsoid,
            "sphere" => Primitive::Sphere,
            other => {
                return Err(PyValueError::new_err(format!(
                    "primitive must be 'ellipsoid' or 'sphere', got {other:?}"
                )));
            }
        },
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
    stage("fit")?;
    let out = py
        .detach(|| pipeline::fit(&cfg, &loaded))
        .map_err(fit_err)?;
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
    /// `"x0,y0,x1,y1"`.
    #[pyo3(signature = (preview=false, passes=false, frames=None, output=None, formats=None, force=false, region=None, dump_blobs=false))]
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
    ) -> PyResult<Shot> {
        let frames = match frames {
            None => None,
            Some(f) => {
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
                Some(text.parse::<FrameSelection>().map_err(|e| {
                    PyErr::new::<SceneError, _>(format!(
                        "{}: frames: {e}",
                        self.scene.path.display()
                    ))
                })?)
            }
        };
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
            dump_blobs,
            stats: false,
            passes,
            region,
        };
        let shot = scene::Shot::open(scene, &options).map_err(scene_err)?;
        Ok(Shot {
            shot: RwLock::new(shot),
        })
    }
}

/// A scene's shot, opened with render options.
#[pyclass(module = "nephele", frozen)]
struct Shot {
    shot: RwLock<scene::Shot>,
}

impl Shot {
    fn read(&self) -> std::sync::RwLockReadGuard<'_, scene::Shot> {
        self.shot.read().unwrap_or_else(|p| p.into_inner())
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

    /// Render `frame` with the GIL released.
    fn frame(&self, py: Python<'_>, frame: u32) -> PyResult<(Frame, ColorSpace)> {
        let shot = self.read();
        let k = Self::index(&shot, frame)?;
        let space = shot.scene().file.output.colorspace;
        let image = py.detach(|| shot.render_frame(k)).map_err(scene_err)?;
        Ok((image, space))
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
        scene::frame_files::frame_paths(&self.read(), frame)
    }

    /// Render `frame` in memory: (H, W, 4) float32 linear RGBA, premultiplied, in the scene's
    /// `output.colorspace`: the values of the R, G, B, A channels of the EXR that
    /// `nephele render` writes for the frame, bit for bit.
    fn render<'py>(&self, py: Python<'py>, frame: u32) -> PyResult<Bound<'py, PyAny>> {
        let (image, space) = self.frame(py, frame)?;
        let mut flat = Vec::with_capacity(image.alpha.len() * 4);
        for (rgb, a) in image.rgb.iter().zip(&image.alpha) {
            flat.extend_from_slice(&convert(rgb, space));
            flat.push(*a);
        }
        numpy_array(
            py,
            &f32_bytes(&flat),
            "float32",
            vec![image.height as usize, image.width as usize, 4],
        )
    }

    /// Render `frame` in memory with every layer the EXR has: `rgba` (H, W, 4), `depth`
    /// (H, W; the EXR's Z, infinity where empty), and when the shot has passes (`passes=True`
    /// or `output.passes`) `sun`, `sky`, `multiple` (H, W, 3 each; they sum to the RGB).
    fn render_passes<'py>(&self, py: Python<'py>, frame: u32) -> PyResult<Bound<'py, PyDict>> {
        let (image, space) = self.frame(py, frame)?;
        let (w, h) = (image.width as usize, image.height as usize);
        let out = PyDict::new(py);
        let mut flat = Vec::with_capacity(w * h * 4);
        for (rgb, a) in image.rgb.iter().zip(&image.alpha) {
            flat.extend_from_slice(&convert(rgb, space));
            flat.push(*a);
        }
        out.set_item(
            "rgba",
            numpy_array(py, &f32_bytes(&flat), "float32", vec![h, w, 4])?,
        )?;
        out.set_item(
            "depth",
            numpy_array(py, &f32_bytes(&image.depth), "float32", vec![h, w])?,
        )?;
        if let Some(p) = &image.passes {
            for (name, layer) in [("sun", &p.sun), ("sky", &p.sky), ("multiple", &p.multiple)] {
                let flat: Vec<f32> = layer.iter().flat_map(|c| convert(c, space)).collect();
                out.set_item(
                    name,
                    numpy_array(py, &f32_bytes(&flat), "float32", vec![h, w, 3])?,
                )?;
            }
        }
        Ok(out)
    }

    /// The blobs of `frame`, an (N, 12) float64 array with `Model.COLUMNS`.
    fn blobs<'py>(&self, py: Python<'py>, frame: u32) -> PyResult<Bound<'py, PyAny>> {
        let shot = self.read();
        let k = Self::index(&shot, frame)?;
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
        let k = Self::index(&shot, frame)?;
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

    /// Render the shot's frames to files, as `nephele render` does (resumable: finished,
    /// up-to-date frames are skipped unless the shot was opened with `force=True`), one frame
    /// at a time with the GIL released. `progress(report)` is called after each frame with a
    /// dict `frame`, `of` (the shot's last frame), `skipped`, `seconds`, `index` (0-based among
    /// the frames rendered), `count`; an exception it raises stops the shot after that frame.
    /// Returns `{"dir", "rendered", "skipped", "out_of_date"}`.
    #[pyo3(signature = (progress=None))]
    fn render_all<'py>(
        &self,
        py: Python<'py>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let mut shot = self.shot.write().unwrap_or_else(|p| p.into_inner());
        let frames = shot.frames().to_vec();
        nephele::atomic::check_writable(shot.dir()).map_err(|e| {
            PyErr::new::<SceneError, _>(format!(
                "output folder {} is not writable: {e}",
                shot.dir().display()
            ))
        })?;
        let (mut rendered, mut skipped) = (0u32, 0u32);
        let mut out_of_date: Vec<(String, u32)> = Vec::new();
        let result = (|| -> PyResult<()> {
            for (i, &frame) in frames.iter().enumerate() {
                shot.set_frames(vec![frame]);
                let mut last = None;
                let one: &scene::Shot = &shot;
                let report = py
                    .detach(|| one.run(&mut |f| last = Some(f.clone())))
                    .map_err(scene_err)?;
                rendered += report.rendered;
                skipped += report.skipped;
                for (reason, n) in report.out_of_date {
                    match out_of_date.iter_mut().find(|(r, _)| *r == reason) {
                        Some((_, m)) => *m += n,
                        None => out_of_date.push((reason, n)),
                    }
                }
                if let (Some(cb), Some(f)) = (&progress, last) {
                    let d = PyDict::new(py);
                    d.set_item("frame", f.frame)?;
                    d.set_item("of", f.of)?;
                    d.set_item("skipped", f.skipped)?;
                    d.set_item("seconds", f.seconds)?;
                    d.set_item("index", i)?;
                    d.set_item("count", frames.len())?;
                    cb.call1(py, (d,))?;
                }
                py.check_signals()?;
            }
            Ok(())
        })();
        shot.set_frames(frames);
        result?;
        let d = PyDict::new(py);
        d.set_item("dir", shot.dir().to_path_buf())?;
        d.set_item("rendered", rendered)?;
        d.set_item("skipped", skipped)?;
        d.set_item("out_of_date", PyList::new(py, out_of_date)?)?;
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

/// The library's version.
#[pyfunction]
fn version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

#[allow(dead_code)]
fn _assert_path(_: &Path) {}

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
    m.add_function(wrap_pyfunction!(fit, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
