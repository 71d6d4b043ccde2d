//! The anchorer takes numbers from sensors: any sequence of pushes (NaN, inf, huge,
//! out of order, repeated) must be refused or absorbed without a panic, and whatever
//! estimate it reports must be finite with a positive scale.
#![no_main]

use dash2sim_core::anchor::{AnchorConfig, AnchorMode, Anchorer};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::time::Timestamp;
use libfuzzer_sys::fuzz_target;

include!("../anchor_input.rs");

fuzz_target!(|data: &[u8]| replay_anchor_input(data));
