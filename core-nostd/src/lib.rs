//! # dash2sim-core
//!
//! The on-device half of dash2sim: `#![no_std]`, allocation-free, no `unsafe`.
//! It turns what a dashcam sees and where it is into a metric, geo-referenced 4D log.
//!
//! | module | concept |
//! |---|---|
//! | [`time`] | the one timestamp type (i64 µs) |
//! | [`geo`] | WGS84 ↔ ECEF ↔ local ENU |
//! | [`sim3`] | similarity transforms, poses, Umeyama from moments |
//! | [`anchor`] | incremental Sim(3) anchoring of VO to GNSS and wheel speed |
//! | [`traj`] | APE / RPE with evo's definitions |
//! | [`nmea`] | NMEA 0183: framer, sentences, messages, epoch assembly |
//! | [`box2d`] | image boxes, IoU, GIoU |
//! | [`box3d`] | oriented 3D boxes, 3D IoU and GIoU (AB3DMOT) |
//! | [`assign`] | optimal assignment (SciPy's algorithm) without allocation |
//! | [`track2d`] | ByteTrack-style 2D tracking-by-detection |
//! | [`claim`] | claim-and-suppress with a video propagator (Algorithm 1) |
//! | [`track3d`] | AB3DMOT-style 3D track manager with class priors |
//! | [`ekf`] | fixed-size (extended) Kalman filter, Joseph form, RTS smoother |
//! | [`map`] | the compact map tile: zero-copy view, grid index, distance to the drivable area |
//! | [`obb`] | oriented boxes in the plane: the ego footprint at its rear axle, overlap tests |
//! | [`drivable`] | drivable-area compliance of a footprint, lane occupancy, channel modes |
//! | `fine_grid`, `polygon_index`, `lane_index` | (feature `fine-index`) fine indexes of a map's polygons and of its buffered lanes for the drivable check, on a grid of small cells |
//! | [`score`] | the nuPlan-style closed-loop score, streaming |
//! | [`binlog`] | the compact, crash-safe 4D log: writer over `embedded-io`, push decoder |
//! | [`can`] | CAN: J1939/NMEA 2000 ids, fast packets, GNSS/speed decoders, DBC signals |
//! | [`pipeline`] | the on-device pipeline: raw inputs in, the 4D log out; input streams for replay |
//!
//! Capacity is part of the types; nothing here allocates or panics on untrusted input.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(not(test), warn(clippy::unwrap_used, clippy::expect_used, clippy::panic))]

#[cfg(feature = "std")]
extern crate std;

pub mod anchor;
pub mod assign;
pub mod binlog;
pub mod box2d;
pub mod box3d;
pub mod can;
pub mod claim;
pub mod class;
pub mod decimal;
pub mod drivable;
pub mod ekf;
#[cfg(feature = "fine-index")]
pub mod fine_grid;
pub mod frame_order;
pub mod geo;
pub mod imu;
#[cfg(feature = "fine-index")]
pub mod lane_index;
pub mod map;
pub mod nmea;
pub mod obb;
pub mod pipeline;
#[cfg(feature = "fine-index")]
pub mod polygon_index;
pub mod score;
pub mod sim3;
pub mod time;
pub mod track2d;
pub mod track3d;
pub mod traj;

pub use nalgebra;

/// Every error the core returns is a `core::error::Error` whose message reads the same way:
/// a lower-case phrase, no full stop (the adapters put it after a file name or a colon).
#[cfg(all(test, feature = "std"))]
mod error_messages {
    extern crate std;
    use std::string::ToString;

    fn message(e: &dyn core::error::Error) -> std::string::String {
        e.to_string()
    }

    #[test]
    fn read_alike() {
        let errors: [&dyn core::error::Error; 21] = [
            &crate::geo::GeoError::OutOfRange,
            &crate::traj::TrajError::LengthMismatch,
            &crate::anchor::AnchorError::InvalidSigma,
            &crate::ekf::KalmanError::Singular,
            &crate::can::fast_packet::FrameError::TooShort,
            &crate::can::signal::SignalError::NotFinite,
            &crate::can::decoder::Error::FastPacket(crate::can::fast_packet::FrameError::BadLength(9)),
            &crate::nmea::framer::FrameError::TooLong,
            &crate::nmea::sentence::SentenceError::MissingChecksum,
            &crate::pipeline::replay::ReplayError::Truncated(12),
            &crate::assign::AssignError::TooLarge,
            &crate::box2d::BoxError::Empty,
            &crate::score::ScoreError::TimeNotIncreasing,
            &crate::binlog::HeaderError::NotALog,
            &crate::sim3::AlignError::Degenerate,
            &crate::map::MapError::BadChecksum,
            &crate::frame_order::TrackError::OutOfOrder { previous: 4, frame: 3 },
            &crate::claim::ClaimError::TooMany,
            &crate::track3d::SmoothError::NotIncreasing,
            &crate::binlog::WriteError::<()>::RecordTooLarge,
            &crate::nmea::messages::MessageError::OutOfRange { index: 3 },
        ];
        for e in errors {
            let m = message(e);
            let first = m.chars().next().unwrap_or('.');
            assert!(!first.is_uppercase() || m.starts_with("CRC") || m.starts_with("NMEA"), "{m:?}");
            assert!(!m.is_empty() && !m.ends_with('.'), "{m:?}");
        }
    }
}
