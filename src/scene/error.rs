//! Scene errors: every error names the file, the line/column when known, and the field.

use std::fmt;
use std::path::PathBuf;

/// Where in a scene file something is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    /// The scene (or referenced) file; `<generated>` for scenes built in memory.
    pub file: PathBuf,
    /// 1-based line and column, when known.
    pub line_col: Option<(usize, usize)>,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line_col {
            Some((l, c)) => write!(f, "{}:{}:{}", self.file.display(), l, c),
            None => write!(f, "{}", self.file.display()),
        }
    }
}

/// An error in a scene description or in a file it references.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file or a referenced file could not be read.
    #[error("{path}: cannot read file: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// RON syntax error, unknown field, wrong type…
    #[error("{at}: {message}")]
    Syntax {
        /// Where.
        at: Location,
        /// What ron reported.
        message: String,
    },
    /// A value that parses but is not acceptable.
    #[error("{at}: field `{field}`: {message}")]
    Invalid {
        /// Where.
        at: Location,
        /// Dotted path of the field (`objects[2].crown.radius_x_m`).
        field: String,
        /// Why.
        message: String,
    },
    /// A section that the format reserves but lumenscape does not implement yet.
    #[error("{at}: field `{field}`: not supported yet ({message})")]
    NotSupported {
        /// Where.
        at: Location,
        /// The section.
        field: String,
        /// Which issue will bring it.
        message: String,
    },
}

impl SceneError {
    /// Exit code of the CLI for this error.
    pub fn exit_code(&self) -> i32 {
        match self {
            SceneError::Io { .. } => 2,
            _ => 1,
        }
    }
}
