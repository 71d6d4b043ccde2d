//! Trajectory files are untrusted input: any bytes must give poses or an error, never a
//! panic. Every parsed pose must be finite.
#![no_main]

use std::path::Path;

use dash2sim_trajectory::{Format, Trajectory};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&selector, rest)) = data.split_first() else { return };
    let Ok(text) = std::str::from_utf8(rest) else { return };
    let format = match selector % 3 {
        0 => Format::Tum,
        1 => Format::Kitti,
        _ => Format::Euroc,
    };
    if let Ok(traj) = Trajectory::parse(text, format, Path::new("fuzz")) {
        assert!(!traj.is_empty());
        assert!(traj.poses.iter().all(|p| p.is_finite()));
        assert!(traj.stamps.windows(2).all(|w| w[0] <= w[1]));
    }
});
