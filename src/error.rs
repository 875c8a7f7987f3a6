//! The one error type of the library. Every variant names the file it is about and says what is
//! wrong in words a user can act on; `main.rs` maps variants to exit statuses (2 for bad input).

use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A pipeline file problem located at a line and column.
    #[error("{}:{line}:{column}: {message}", file.display())]
    Pipeline {
        file: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    /// A scene (glTF) problem; `object` is a JSON-pointer-like path such as
    /// `meshes[3].primitives[0].attributes.POSITION`, or empty when the whole file is at fault.
    #[error("{}: {}{message}", file.display(), if object.is_empty() { String::new() } else { format!("{object}: ") })]
    Scene {
        file: PathBuf,
        object: String,
        message: String,
    },
    /// Bad input that is neither a pipeline nor a scene: a command-line value, an image to compare.
    #[error("{}: {message}", file.display())]
    Input { file: PathBuf, message: String },
    /// Reading or writing a file failed for a reason outside the input's content.
    #[error("{}: {source}", file.display())]
    Io {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// `compare` could not read an input or write its difference image: idiff's status 4.
    #[error(transparent)]
    Compare(Box<Error>),
    /// `render` stopped on SIGINT or SIGTERM; `message` says what was finished and how to go on.
    #[error("interrupted: {message}")]
    Interrupted { message: String },
    /// `assemble` (or a whole-range `--resume`) found frames missing or stale; `message` lists
    /// them. Not the input's fault: the farm has work left (status 1).
    #[error("{message}")]
    Incomplete { message: String },
    /// The GPU backend cannot run here: no adapter, a device lost, or a scene larger than the
    /// adapter's limits. Not the input's fault (status 1).
    #[error("GPU: {message}")]
    Device { message: String },
    /// A broken invariant of the program, never the user's input.
    #[error("internal error (a bug in stereotrace, please report it): {0}")]
    Internal(String),
}

impl Error {
    pub fn scene(file: &Path, object: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Scene {
            file: file.to_path_buf(),
            object: object.into(),
            message: message.into(),
        }
    }

    pub fn input(file: &Path, message: impl Into<String>) -> Self {
        Error::Input {
            file: file.to_path_buf(),
            message: message.into(),
        }
    }

    pub fn io(file: &Path, source: std::io::Error) -> Self {
        Error::Io {
            file: file.to_path_buf(),
            source,
        }
    }

    /// Exit status for the command line: 2 for anything the user's input caused, 1 when
    /// reading or writing failed otherwise, 4 for `compare`'s unreadable inputs (idiff's), and
    /// 70 for a program bug (`EX_SOFTWARE` of BSD's sysexits.h), 130 when interrupted (128 +
    /// SIGINT, the shells' convention).
    pub fn exit_code(&self) -> u8 {
        match self {
            Error::Interrupted { .. } => 130,
            Error::Incomplete { .. } | Error::Device { .. } => 1,
            // A missing file, or a folder where a file is expected, is the user's input.
            Error::Io { source, .. }
                if !matches!(
                    source.kind(),
                    std::io::ErrorKind::NotFound | std::io::ErrorKind::IsADirectory
                ) =>
            {
                1
            }
            Error::Compare(_) => 4,
            Error::Internal(_) => 70,
            _ => 2,
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
