//! The exceptions nephele raises, and the library's errors turned into them.
//!
//! Every exception's text is the library error's chain as the `nephele` command prints it
//! ([`nephele::error_chain::message`]); a `SceneError` also carries where (`path`, `line`,
//! `column`, `field`). The classes live in the `nephele` module (their `__module__`), and their
//! attributes are instance attributes, so an exception pickles and unpickles (a
//! `multiprocessing` worker's error reaches its parent whole).

use std::path::Path;

use nephele::file_error::FileError;
use nephele::scene::SceneError as CoreSceneError;
use pyo3::BoundObject;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

pyo3::create_exception!(
    nephele,
    NepheleError,
    PyException,
    "Base class of every error nephele raises."
);
pyo3::create_exception!(
    nephele,
    SceneError,
    NepheleError,
    "A scene that cannot be read, validated, prepared or rendered (file:line:column or field)."
);
pyo3::create_exception!(
    nephele,
    MeshError,
    NepheleError,
    "A mesh that cannot be read or is not usable (file:line)."
);
pyo3::create_exception!(
    nephele,
    FitError,
    NepheleError,
    "A fit that cannot be made (bad settings, a mesh enclosing no volume)."
);
pyo3::create_exception!(
    nephele,
    ModelError,
    NepheleError,
    "A model file or blob array that cannot be read, written or used as a model."
);

/// Add the exception classes to the module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("NepheleError", py.get_type::<NepheleError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("MeshError", py.get_type::<MeshError>())?;
    m.add("FitError", py.get_type::<FitError>())?;
    m.add("ModelError", py.get_type::<ModelError>())?;
    Ok(())
}

/// A Python exception of class `T` with `msg`, and the attributes in `attrs` (instance
/// attributes: they pickle with it).
pub(crate) fn raise<T: pyo3::PyTypeInfo>(
    py: Python<'_>,
    msg: String,
    attrs: &[(&str, Py<PyAny>)],
) -> PyErr {
    let err = PyErr::new::<T, _>(msg);
    let value = err.value(py);
    for (k, v) in attrs {
        let _ = value.setattr(*k, v);
    }
    err
}

/// `v` as a Python object (`None` should it not convert: the strings and integers given here
/// always do).
pub(crate) fn to_py<'py, T: IntoPyObject<'py>>(py: Python<'py>, v: T) -> Py<PyAny> {
    v.into_pyobject(py)
        .map_or_else(|_| py.None(), |o| o.into_any().unbind())
}

/// A `SceneError` with its location attributes: `path` (the scene file), `line`, `column`,
/// `field` (each `None` when unknown).
fn scene_error(
    py: Python<'_>,
    msg: String,
    path: Option<&Path>,
    line: Option<usize>,
    column: Option<usize>,
    field: Option<&str>,
) -> PyErr {
    raise::<SceneError>(
        py,
        msg,
        &[
            ("path", to_py(py, path.map(|p| p.to_string_lossy()))),
            ("line", to_py(py, line)),
            ("column", to_py(py, column)),
            ("field", to_py(py, field)),
        ],
    )
}

/// A `SceneError` about the value at `field` (a key path such as `shot.width`) of the scene
/// `path`: `{path}: {field}: {what}`.
pub(crate) fn scene_field_err(path: &Path, field: &str, what: impl std::fmt::Display) -> PyErr {
    Python::attach(|py| {
        let msg = format!("{}: {field}: {what}", path.display());
        scene_error(py, msg, Some(path), None, None, Some(field))
    })
}

/// The library's scene error as a `SceneError`, located.
pub(crate) fn scene_err(e: CoreSceneError) -> PyErr {
    Python::attach(|py| {
        let msg = nephele::error_chain::message(&e);
        let (path, line, column, field) = match &e {
            CoreSceneError::File(FileError::Parse {
                path, line, column, ..
            }) => (Some(path), Some(*line), Some(*column), None),
            CoreSceneError::Invalid { path, field, .. } => {
                (Some(path), None, None, Some(field.as_str()))
            }
            CoreSceneError::InvalidAt {
                path,
                line,
                column,
                field,
                ..
            } => (Some(path), Some(*line), Some(*column), Some(field.as_str())),
            CoreSceneError::File(FileError::Io { path, .. }) => (Some(path), None, None, None),
            CoreSceneError::MissingTarget { scene, .. }
            | CoreSceneError::Mesh { scene, .. }
            | CoreSceneError::Fit { scene, .. }
            | CoreSceneError::Model { scene, .. }
            | CoreSceneError::Animate { scene, .. } => (Some(scene), None, None, None),
            _ => (None, None, None, None),
        };
        scene_error(py, msg, path.map(|p| p.as_path()), line, column, field)
    })
}

/// Any other error of the library (its chain as one line) as a `SceneError` without location.
pub(crate) fn scene_other(e: &(dyn std::error::Error + 'static)) -> PyErr {
    PyErr::new::<SceneError, _>(nephele::error_chain::message(e))
}

/// The library's mesh error as a `MeshError`.
pub(crate) fn mesh_err(e: nephele::mesh::MeshError) -> PyErr {
    PyErr::new::<MeshError, _>(nephele::error_chain::message(&e))
}

/// The library's fit error as a `FitError`.
pub(crate) fn fit_err(e: nephele::pipeline::FitError) -> PyErr {
    PyErr::new::<FitError, _>(nephele::error_chain::message(&e))
}

/// The library's model error as a `ModelError`.
pub(crate) fn model_err(e: nephele::blobby::ModelError) -> PyErr {
    PyErr::new::<ModelError, _>(nephele::error_chain::message(&e))
}
