//! The `nephele` command of the wheel: the library's command line ([`nephele::cli::main`]),
//! the same code as the `nephele` binary's, run with the GIL released.

use pyo3::prelude::*;

/// Run the `nephele` command with `argv` (the program's name first, as `sys.argv`) and return
/// its exit code: 0, or 1 after printing the error on stderr. `--help`, `--version` and usage
/// errors are printed and end the process, as the binary does.
#[pyfunction]
pub(crate) fn main(py: Python<'_>, argv: Vec<String>) -> u8 {
    py.detach(|| nephele::cli::main(argv))
}
