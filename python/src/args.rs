//! Arguments from Python read into the library's types, each refusal naming the argument:
//! integers in their range, frame selections, primitives.

use std::path::Path;

use nephele::decompose::Primitive;
use nephele::scene::frames::FrameSelection;
use pyo3::exceptions::{PyOverflowError, PyTypeError, PyValueError};
use pyo3::prelude::*;

use crate::errors::scene_field_err;

/// The integer argument `name` of `who`, in `min..=max`: a `TypeError` for a value that is no
/// integer, a `ValueError` naming the argument and its range for one outside it (where Python's
/// own conversion raised a bare `OverflowError`).
pub(crate) fn int_in(
    who: &str,
    name: &str,
    value: &Bound<'_, PyAny>,
    min: u64,
    max: u64,
) -> PyResult<u64> {
    int_stating(who, name, value, (min, max), min)
}

/// [`int_in`] for a count (`usize`) the library wants at least `min` of. A value the type
/// holds is passed on for the library to judge (its `FitError` for one below `min`); one it
/// cannot hold (negative, too large) is a `ValueError` stating `min`.
pub(crate) fn count_at_least(
    who: &str,
    name: &str,
    value: &Bound<'_, PyAny>,
    min: usize,
) -> PyResult<usize> {
    // usize is 64 bits wide on every platform the wheel is built for.
    int_stating(who, name, value, (0, usize::MAX as u64), min as u64).map(|n| n as usize)
}

/// An integer in `accepted` (inclusive), the message stating the range `stated..=max`.
fn int_stating(
    who: &str,
    name: &str,
    value: &Bound<'_, PyAny>,
    (lo, hi): (u64, u64),
    stated: u64,
) -> PyResult<u64> {
    let range = if hi == u64::MAX || hi == usize::MAX as u64 {
        format!("an integer ≥ {stated}")
    } else {
        format!("an integer from {stated} to {hi}")
    };
    let got = value.repr().map_or_else(|_| "?".into(), |r| r.to_string());
    let n: i128 = match value.extract::<i128>() {
        Ok(n) => n,
        Err(e) if e.is_instance_of::<PyOverflowError>(value.py()) => i128::MAX,
        Err(_) => {
            return Err(PyTypeError::new_err(format!(
                "{who}: {name} must be {range}, got {got} ({})",
                value.get_type().name()?
            )));
        }
    };
    if n < i128::from(lo) || n > i128::from(hi) {
        return Err(PyValueError::new_err(format!(
            "{who}: {name} must be {range}, got {got}"
        )));
    }
    Ok(n as u64)
}

/// `"ellipsoid"` or `"sphere"` ([`Primitive::from_name`]), else a `ValueError`.
pub(crate) fn primitive(name: &str) -> PyResult<Primitive> {
    Primitive::from_name(name).map_err(PyValueError::new_err)
}

/// A frame selection from Python: a selection string (`"1..24,30"`), a frame number or a
/// list of frame numbers; `path` (the scene's) labels a malformed one.
pub(crate) fn selection(f: &Bound<'_, PyAny>, path: &Path) -> PyResult<FrameSelection> {
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
        .map_err(|e| scene_field_err(path, "frames", e))
}
