//! numpy arrays in and out: native-endian bytes made without the GIL become arrays, and blob
//! arrays are read back as the library's blobs (real numbers only, [`BLOB_COLUMNS`] wide).

use nephele::blobby::{BLOB_COLUMNS, Blob};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyByteArray;

/// `bytes` (native-endian values) as a writable numpy array of `dtype` and `shape`.
pub(crate) fn numpy_array<'py>(
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

/// The native-endian bytes of `v`.
pub(crate) fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
}

/// The native-endian bytes of `v`.
pub(crate) fn f64_bytes(v: &[f64]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
}

/// The native-endian bytes of `v`.
pub(crate) fn i32_bytes(v: &[i32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_ne_bytes()).collect()
}

/// The blobs as an (N, 12) float64 array with [`BLOB_COLUMNS`] ([`Blob::to_row`]).
pub(crate) fn blobs_array<'py>(py: Python<'py>, blobs: &[Blob]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = blobs.iter().flat_map(|b| b.to_row()).collect();
    numpy_array(
        py,
        &f64_bytes(&flat),
        "float64",
        vec![blobs.len(), BLOB_COLUMNS.len()],
    )
}

/// The blobs of an (N, 12) array-like of real numbers with [`BLOB_COLUMNS`] ([`Blob::from_row`],
/// exact; not checked). `who` names the caller in errors: a `TypeError` for anything but
/// integers or floats (strings, complex numbers, booleans, objects), a `ValueError` for
/// another shape.
pub(crate) fn blobs_from_array(
    py: Python<'_>,
    who: &str,
    blobs: &Bound<'_, PyAny>,
) -> PyResult<Vec<Blob>> {
    let np = py.import("numpy")?;
    let array = np.call_method1("asarray", (blobs,))?;
    let dtype = array.getattr("dtype")?;
    let kind: String = dtype.getattr("kind")?.extract()?;
    // Signed and unsigned integers and floats; numpy's own conversion would also take strings
    // of numbers and drop the imaginary part of complex ones.
    if !matches!(kind.as_str(), "i" | "u" | "f") {
        return Err(PyTypeError::new_err(format!(
            "{who}: blobs must be real numbers (an integer or float array), got an array of \
             dtype {}",
            dtype.str()?
        )));
    }
    let shape: Vec<usize> = array.getattr("shape")?.extract()?;
    if shape.len() != 2 || shape[1] != BLOB_COLUMNS.len() {
        return Err(PyValueError::new_err(format!(
            "{who}: blobs must be an (N, {}) array with columns {}, got shape {shape:?}",
            BLOB_COLUMNS.len(),
            BLOB_COLUMNS.join(" ")
        )));
    }
    let rows: Vec<[f64; 12]> = array
        .call_method1("astype", ("float64",))?
        .call_method0("tolist")?
        .extract()?;
    Ok(rows.iter().map(Blob::from_row).collect())
}
