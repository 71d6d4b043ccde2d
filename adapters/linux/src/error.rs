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
    #[error("this build of {krate} has no {part} (its `{feature}` feature)")]
    FeatureMissing {
        /// The field of the request that asked for it.
        field: Field,
        /// The crate whose feature it is (`dash2sim-export`).
        krate: &'static str,
        /// The part (`Parquet export`).
        part: &'static str,
        /// The cargo feature that brings it.
        feature: &'static str,
    },
    /// One field of a request cannot be used as given, or is missing: which field, and
    /// what is wrong with it, in the library's words. A front end names its own way of
    /// setting the field (the command line its flag) beside the message.
    #[error("{field}: {message}")]
    Request {
        /// The field.
        field: Field,
        /// What is wrong with it.
        message: String,
    },
    /// The request or its inputs cannot be used as given: what is wrong, in words.
    #[error("{0}")]
    Invalid(String),
    /// A part's own error, passed on as it is (its message is the whole story).
    #[error(transparent)]
    Other(Source),
}

/// A field of a request, named as the library knows it. The requests of every crate that
/// shares this error (recording, import, finishing, verification, exports, the simulator)
/// name their fields here, so that a front end can point at its own way of setting one:
/// the command line maps each to the flag that fixes it, and the library's messages
/// never speak any front end's vocabulary.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Field {
    /// The GNSS error model's UERE.
    Uere,
    /// The log's ENU origin.
    Origin,
    /// The map tile (or OpenStreetMap file).
    Map,
    /// The DBC files.
    Dbc,
    /// The DBC signal carrying the vehicle speed.
    SpeedSignal,
    /// The DBC signals carrying GNSS fixes.
    GnssSignals,
    /// The recorded inputs (files, or live sources).
    Sources,
    /// The 2D detections.
    Detections2d,
    /// Where the merged input stream is saved.
    SaveInputs,
    /// What an import reads (captures, a trajectory, objects).
    ImportSources,
    /// The live recording's segment length.
    SegmentMinutes,
    /// How long a live recording or a publisher runs.
    Seconds,
    /// The SocketCAN interface.
    CanInterface,
    /// The map's grid cell.
    Cell,
    /// How many passes a map check makes.
    Passes,
    /// The street anchors' σ.
    Sigma,
    /// The anchorer's forgetting time.
    Forget,
    /// The finished trajectory's key-frame spacing.
    Keyframe,
    /// The export formats asked for.
    Formats,
    /// The MCAP export.
    Mcap,
    /// The Parquet export.
    Parquet,
    /// The nuPlan export.
    Nuplan,
    /// The length of an exported scenario.
    ScenarioSeconds,
    /// A generated drive's length.
    Duration,
    /// How many drives run at once.
    Jobs,
    /// How much faster than real time a publisher runs.
    Speedup,
    /// A publisher's camera frame rate.
    Fps,
    /// How many times a publisher runs its drive.
    Laps,
}

impl std::fmt::Display for Field {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Field::Uere => "the GNSS error model's UERE",
            Field::Origin => "the ENU origin",
            Field::Map => "the map",
            Field::Dbc => "the DBC files",
            Field::SpeedSignal => "the speed signal",
            Field::GnssSignals => "the GNSS signals",
            Field::Sources => "the inputs",
            Field::Detections2d => "the 2D detections",
            Field::SaveInputs => "the saved input stream",
            Field::ImportSources => "the inputs",
            Field::SegmentMinutes => "the segment length",
            Field::Seconds => "the run's length",
            Field::CanInterface => "the CAN interface",
            Field::Cell => "the grid cell",
            Field::Passes => "the number of passes",
            Field::Sigma => "the anchors' σ",
            Field::Forget => "the forgetting time",
            Field::Keyframe => "the key-frame spacing",
            Field::Formats => "the export formats",
            Field::Mcap => "the MCAP export",
            Field::Parquet => "the Parquet export",
            Field::Nuplan => "the nuPlan export",
            Field::ScenarioSeconds => "the scenario length",
            Field::Duration => "the drive's length",
            Field::Jobs => "the number of jobs",
            Field::Speedup => "the speed-up",
            Field::Fps => "the frame rate",
            Field::Laps => "the number of laps",
        })
    }
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

    /// The request's `field` cannot be used as given: `message` says why.
    pub fn request(field: Field, message: impl Into<String>) -> Error {
        Error::Request { field, message: message.into() }
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
        let e = Error::FeatureMissing {
            field: Field::Parquet,
            krate: "dash2sim-export",
            part: "Parquet export",
            feature: "parquet",
        };
        assert_eq!(e.to_string(), "this build of dash2sim-export has no Parquet export (its `parquet` feature)");
        let e = Error::request(Field::Keyframe, "20 s is not between 0.05 and 10 s");
        assert_eq!(e.to_string(), "the key-frame spacing: 20 s is not between 0.05 and 10 s");
    }
}
