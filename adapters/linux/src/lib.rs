//! # dash2sim-linux
//!
//! The dash2sim library on std, around `dash2sim-core`: ingest (NMEA and CAN captures,
//! trajectory and detection files, OpenStreetMap into map tiles), the host pipeline
//! (`record`, from files or live over shared memory) and the 4D log (read, imported,
//! inspected, and the views and writers every consumer shares). Verification is
//! `dash2sim-verify`, finishing `dash2sim-finish` and the simulator exports
//! `dash2sim-export`, above it; the simulator that measures them all is `dash2sim-sim`. It
//! takes requests and returns results; it never prints (the `dash2sim` command line renders
//! them) and knows no command line (no clap: the binaries' words for its option values are
//! `dash2sim-args`'s). ARCHITECTURE.md maps the modules.
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod error;
pub mod geometry;
pub mod ingest;
pub mod log;
mod numbers;
pub mod record;
pub mod sync;
pub mod utc;
/// Trajectory files (TUM, KITTI, EuRoC): the `dash2sim-trajectory` crate.
pub use dash2sim_trajectory as trajectory;
pub use error::{Error, Field, Result};
