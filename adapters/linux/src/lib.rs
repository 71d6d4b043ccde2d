//! # dash2sim-linux
//!
//! std adapters around `dash2sim-core` and the `dash2sim` command line: timestamp
//! association, evaluation, offline anchoring, decoders for NMEA and CAN captures,
//! MOT evaluation and the seeded work-zone scenario generator.
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod anchoring;
pub mod bridge;
pub mod can_decode;
pub mod detections;
pub mod ego;
pub mod evaluate;
pub mod exports;
pub mod fidelity;
pub mod finish;
pub mod logfile;
pub mod map_tile;
pub mod mot;
pub mod nmea_decode;
pub mod nuplan;
pub mod objects;
pub mod osm;
pub mod plot;
pub mod record;
pub mod recordings;
pub mod scenario;
pub mod sync;
pub mod track2d;
/// Trajectory files (TUM, KITTI, EuRoC): the `dash2sim-trajectory` crate.
pub use dash2sim_trajectory as trajectory;
pub mod verify;
