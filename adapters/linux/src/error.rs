//! The library's one error type. Every fallible function returns [`Result`]; the message a
//! user sees is the error's `Display` (the command line prints it after `error: `), and the
//! kind says what went wrong and where: a file, a line of one, something a part refused, a
//! part this build was made without, or a request that cannot be met as given.

use std::path::{Path, PathBuf};

/// Any error behind a `Box`, as the sources of [`Error`] are kept.
pub type Source = Box<dyn std::error::Error + Send + Sync + 'static>;

/// What went wrong.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file could not be opened, read, written or understood as a whole.
    #[error("{}: {source}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// Why (an I/O error, a parser's error, …).
        #[source]
        source: Source,
    },
    /// One line of an input file is wrong.
    #[error("{}:{line}: {message}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },
    /// A part refused what it was given (a map tile, a log, an origin, a projection): what
    /// it was given, and the part's own error.
    #[error("{context}: {source}")]
    Refused {
        /// What was given (`map`, `the log's origin`, `UTM zone 35`, …).
        context: String,
        /// The part's error.
        #[source]
        source: Source,
    },
    /// The request needs a part this build of the library was made without.
    #[error("{option}: this build of dash2sim-linux has no {part} (its `{feature}` feature)")]
    FeatureMissing {
        /// The option that asked for it (`--parquet`).
        option: &'static str,
        /// The part (`Parquet export`).
        part: &'static str,
        /// The cargo feature that brings it.
        feature: &'static str,
    },
    /// The request or its inputs cannot be used as given: what is wrong, in words.
    #[error("{0}")]
    Invalid(String),
    /// A part's own error, passed on as it is (its message is the whole story).
    #[error(transparent)]
    Other(Source),
}

/// The library's result.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// `path` could not be used: `source` says why.
    pub fn file(path: &Path, source: impl Into<Source>) -> Error {
        Error::File { path: path.to_path_buf(), source: source.into() }
    }

    /// Line `line` (1-based) of `path` is wrong.
    pub fn line(path: &Path, line: usize, message: impl Into<String>) -> Error {
        Error::Line { path: path.to_path_buf(), line, message: message.into() }
    }

    /// `context` was refused with `source`.
    pub fn refused(context: impl Into<String>, source: impl Into<Source>) -> Error {
        Error::Refused { context: context.into(), source: source.into() }
    }

    /// The request cannot be met: `message` says why.
    pub fn invalid(message: impl Into<String>) -> Error {
        Error::Invalid(message.into())
    }

    /// A part's error, passed on as it is.
    pub fn other(source: impl Into<Source>) -> Error {
        Error::Other(source.into())
    }

    /// The I/O error underneath, if this is one (a missing file, a full disk).
    pub fn io(&self) -> Option<&std::io::Error> {
        match self {
            Error::File { source, .. } | Error::Refused { source, .. } | Error::Other(source) => source.downcast_ref(),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_say_what_and_where() {
        let missing = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory (os error 2)");
        let e = Error::file(Path::new("drive/ego.tum"), missing);
        assert_eq!(e.to_string(), "drive/ego.tum: No such file or directory (os error 2)");
        assert_eq!(e.io().map(std::io::Error::kind), Some(std::io::ErrorKind::NotFound));
        assert_eq!(Error::line(Path::new("a.csv"), 3, "negative size").to_string(), "a.csv:3: negative size");
        let e = Error::refused("map", dash2sim_core::map::MapError::BadMagic);
        assert_eq!(e.to_string(), "map: not a dash2sim map tile (bad magic)");
        assert!(std::error::Error::source(&e).is_some());
        assert!(e.io().is_none());
        let e = Error::FeatureMissing { option: "--parquet", part: "Parquet export", feature: "parquet" };
        assert_eq!(
            e.to_string(),
            "--parquet: this build of dash2sim-linux has no Parquet export (its `parquet` feature)"
        );
    }
}
