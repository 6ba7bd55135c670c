//! The errors of reading a file nephele parses (a scene, a blob model), shared by
//! [`crate::scene::SceneError`] and [`crate::blobby::ModelError`]: the file could not be read or
//! written, or its text is malformed at a `line:column`.

use std::path::{Path, PathBuf};

/// A file that could not be read or written, or whose text does not parse.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// File concerned.
        path: PathBuf,
        /// Underlying error.
        source: std::io::Error,
    },
    /// Malformed RON, an unknown field or a wrong type, at its place in the text.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// File concerned.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the parser expected.
        message: String,
    },
}

impl FileError {
    /// A RON parse error of the text of `path`, at its place.
    pub fn ron(path: &Path, e: &ron::error::SpannedError) -> FileError {
        FileError::Parse {
            path: path.to_path_buf(),
            line: e.span.start.line,
            column: e.span.start.col,
            message: e.code.to_string(),
        }
    }
}
