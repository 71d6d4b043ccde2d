//! The ego as the map checks see it: rear-axle poses in the ground plane, read from a TUM
//! trajectory in the map's ENU frame (`verify --ego`, `map check`).

use std::path::Path;

use dash2sim_core::obb::Pose2;

use crate::trajectory::{Format, Trajectory};
use crate::{Error, Result};

/// Heading of a pose: its body x axis in the ENU plane.
fn heading(pose: &dash2sim_core::sim3::Pose) -> f64 {
    pose.rotation[(1, 0)].atan2(pose.rotation[(0, 0)])
}

/// Rear-axle poses from a TUM file in a map's ENU frame (heading from the body x axis).
pub fn read_ego(path: &Path) -> Result<Vec<(f64, Pose2)>> {
    let trajectory = Trajectory::read(path, Format::Tum).map_err(Error::other)?;
    Ok(trajectory
        .stamps
        .iter()
        .zip(&trajectory.poses)
        .map(|(t, p)| (*t, Pose2::new(p.translation.x, p.translation.y, heading(p))))
        .collect())
}
