//! `dash2sim map check`: the drivable-area check alone, on the footprints at a file of
//! poses — what a tile says about each, and how long the check takes per pose (timed in
//! process, the fastest of several passes, so that other processes' noise drops out). The
//! shapely comparison (`scripts/crosscheck_drivable_shapely.py`) times it this way.

use std::path::Path;
use std::time::Instant;

use crate::{Error, Result};
use dash2sim_core::drivable::Channel;
use dash2sim_core::map::MapView;
use dash2sim_core::obb::PACIFICA;

/// What checking a file of poses found, and how long it took (`dash2sim map check --json`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Checked {
    /// Poses checked.
    pub poses: usize,
    /// Of them, with the footprint inside the drivable area.
    pub compliant: usize,
    /// Footprint corners outside it.
    pub corners_outside: usize,
    /// Footprint corners with nothing drivable within 10 m.
    pub corners_nothing_near: usize,
    /// The fastest pass's time per pose, µs.
    pub us_per_pose: f64,
    /// Passes made.
    pub passes: u32,
}

/// Check every pose of `poses` (TUM, rear axle, the tile's ENU frame) `passes` times.
pub fn check_file(map: &Path, poses: &Path, passes: u32) -> Result<Checked> {
    if passes == 0 {
        return Err(Error::invalid("--passes must be at least 1"));
    }
    let bytes = std::fs::read(map).map_err(|e| Error::file(map, e))?;
    let view = MapView::parse(&bytes).map_err(|e| Error::file(map, e))?;
    let path = poses;
    let poses = crate::ingest::ego::read_ego(path)?;
    if poses.is_empty() {
        return Err(Error::file(path, "no poses to check (TUM: t x y z qx qy qz qw per line)"));
    }
    // A map of polygons (Lanelet2) is checked through its fine index, built first (not timed).
    let index = super::polygon_index::build(&view);
    let checker = super::polygon_index::checker(view, PACIFICA, index.as_ref());
    let mut fastest = f64::INFINITY;
    let (mut compliant, mut outside, mut nothing_near) = (0usize, 0usize, 0usize);
    for _ in 0..passes {
        let (mut c, mut o, mut n) = (0, 0, 0);
        let start = Instant::now();
        for (_, pose) in &poses {
            let check = checker.check::<1>(pose, Channel::Insensitive, None);
            c += usize::from(check.compliant());
            o += check.corners.iter().filter(|d| d.is_some_and(|d| d > 0.0)).count();
            n += check.corners.iter().filter(|d| d.is_none()).count();
        }
        fastest = fastest.min(start.elapsed().as_secs_f64());
        (compliant, outside, nothing_near) = (c, o, n);
    }
    Ok(Checked {
        poses: poses.len(),
        compliant,
        corners_outside: outside,
        corners_nothing_near: nothing_near,
        us_per_pose: fastest / poses.len() as f64 * 1e6,
        passes,
    })
}
