//! The end-to-end and conformance tests against the peers' outputs, one test binary: each
//! file of this folder is a module of it. As 35 binaries, each compiled the pipeline's
//! generic code again and was linked on its own (issue #56: CI's build time).
//! Run one file's tests with its module's name, e.g.
//! `cargo test --release -p dash2sim-tests --test integration pipeline_record::`.
//! `no_allocation` is a binary of its own: it counts the allocations of the whole process,
//! which the other tests, running beside it in one binary, would add to.

mod anchoring_comma2k19;
mod architecture;
mod binlog_roundtrip;
mod binlog_size;
mod canboat_conformance;
mod comma2k19_can;
mod comma_imu;
mod css_conformance;
mod device_windows;
mod driver_kinds;
mod ekf_filterpy;
mod evo_conformance;
mod finish_comma2k19;
mod finish_scenarios;
mod geo_pymap3d;
mod gpsd_conformance;
mod imu_forward_axis;
mod map_lane_index;
mod map_lanelet2;
mod mcu_drive;
mod mcu_tile;
mod motmetrics_conformance;
mod nuplan_junctions;
mod osm_pyosmium;
mod pipeline_comma2k19;
mod pipeline_record;
mod recordings;
mod reinit_and_mount;
mod scenario_profiles;
mod scenario_tracking;
mod score_doubt;
mod score_hostile;
mod verify_scenarios;
