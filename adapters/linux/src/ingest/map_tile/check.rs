//! `dash2sim map check`: the drivable-area check alone, on the footprints at a file of
//! poses — what a tile says about each, and how long the check takes per pose (timed in
//! process, the fastest of several passes, so that other processes' noise drops out). The
//! shapely comparison (`scripts/crosscheck_drivable_shapely.py`) times it this way.

use std::path::Path;
use std::time::Instant;

use crate::{Error, Field, Result};
use dash2sim_core::drivable::{Channel, Checker, LaneSet};
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{Pose2, PACIFICA};

/// What checking a file of poses found, and how long it took (`dash2sim map check --json`):
/// channel-insensitive, and channel-sensitive on the channel the poses drive.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Checked {
    /// Poses checked.
    pub poses: usize,
    /// Channel-insensitive: of them, with the footprint inside the drivable area.
    pub compliant: usize,
    /// Footprint corners outside it.
    pub corners_outside: usize,
    /// Footprint corners with nothing drivable within 10 m.
    pub corners_nothing_near: usize,
    /// The fastest pass's time per pose, µs.
    pub us_per_pose: f64,
    /// The same channel-sensitive, the channel the lanes the poses drive (as `verify`
    /// collects it from a drive); `None` when the map has more lanes than a channel holds.
    pub channel_sensitive: Option<SensitiveChecked>,
    /// Passes made.
    pub passes: u32,
}

/// [`Checked`]'s channel-sensitive figures.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SensitiveChecked {
    /// Lanes on the channel.
    pub channel_lanes: usize,
    /// Poses with the footprint inside the channel.
    pub compliant: usize,
    /// Footprint corners outside it.
    pub corners_outside: usize,
    /// Footprint corners with nothing of the channel within 10 m.
    pub corners_nothing_near: usize,
    /// The fastest pass's time per pose, µs.
    pub us_per_pose: f64,
}

/// Lanes a channel holds here (32 a word).
const CHANNEL_WORDS: usize = 8192;

/// Check every pose of `poses` (TUM, rear axle, the tile's ENU frame) `passes` times in each
/// channel mode.
pub fn check_file(map: &Path, poses: &Path, passes: u32) -> Result<Checked> {
    if passes == 0 {
        return Err(Error::request(Field::Passes, "at least 1 is needed"));
    }
    let bytes = std::fs::read(map).map_err(|e| Error::file(map, e))?;
    let view = MapView::parse(&bytes).map_err(|e| Error::file(map, e))?;
    let path = poses;
    let poses: Vec<Pose2> = crate::ingest::ego::read_ego(path)?.into_iter().map(|(_, p)| p).collect();
    if poses.is_empty() {
        return Err(Error::file(path, "no poses to check (TUM: t x y z qx qy qz qw per line)"));
    }
    // Through the tile's fine index, built first (not timed).
    let index = super::fine_index::build(&view);
    let checker = super::fine_index::checker(view, PACIFICA, index.as_ref());
    let insensitive = timed(&checker, &poses, Channel::<1>::Insensitive, passes);
    let channel_sensitive = (view.header().lanes as usize <= LaneSet::<CHANNEL_WORDS>::capacity()).then(|| {
        let mut channel: Box<LaneSet<CHANNEL_WORDS>> = Box::default();
        for pose in &poses {
            channel.add_route_pose(&view, &PACIFICA, pose);
        }
        let t = timed(&checker, &poses, Channel::Sensitive(&channel), passes);
        SensitiveChecked {
            channel_lanes: channel.len(),
            compliant: t.compliant,
            corners_outside: t.outside,
            corners_nothing_near: t.nothing_near,
            us_per_pose: t.us_per_pose,
        }
    });
    Ok(Checked {
        poses: poses.len(),
        compliant: insensitive.compliant,
        corners_outside: insensitive.outside,
        corners_nothing_near: insensitive.nothing_near,
        us_per_pose: insensitive.us_per_pose,
        channel_sensitive,
        passes,
    })
}

/// One mode's counts and its fastest pass.
struct Timed {
    compliant: usize,
    outside: usize,
    nothing_near: usize,
    us_per_pose: f64,
}

fn timed<const WORDS: usize>(
    checker: &Checker<'_>,
    poses: &[Pose2],
    channel: Channel<'_, WORDS>,
    passes: u32,
) -> Timed {
    let mut fastest = f64::INFINITY;
    let (mut compliant, mut outside, mut nothing_near) = (0usize, 0usize, 0usize);
    for _ in 0..passes {
        let (mut c, mut o, mut n) = (0, 0, 0);
        let start = Instant::now();
        for pose in poses {
            let check = checker.check(pose, channel, None);
            c += usize::from(check.compliant());
            o += check.corners.iter().filter(|d| d.is_some_and(|d| d > 0.0)).count();
            n += check.corners.iter().filter(|d| d.is_none()).count();
        }
        fastest = fastest.min(start.elapsed().as_secs_f64());
        (compliant, outside, nothing_near) = (c, o, n);
    }
    Timed { compliant, outside, nothing_near, us_per_pose: fastest / poses.len() as f64 * 1e6 }
}
