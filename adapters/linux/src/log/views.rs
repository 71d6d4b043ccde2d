//! The views of a log that verification and every exporter share: its ego poses, its tracks
//! (their velocities, the static objects that stay standing). The writers of the formats are
//! the `dash2sim-export` crate.

use std::collections::BTreeMap;

use dash2sim_core::binlog::{EgoPose, Record, Track3d};
use dash2sim_core::nalgebra::Vector3;

use super::LogContents;

/// The ego poses of a log.
pub fn ego_poses(log: &LogContents) -> impl Iterator<Item = &EgoPose> {
    log.records.iter().filter_map(|r| match r {
        Record::EgoPose(p) => Some(p),
        _ => None,
    })
}

/// ENU position (m) and heading (rad) of an ego pose.
pub fn ego_enu(p: &EgoPose) -> (Vector3<f64>, f64) {
    (Vector3::new(p.x_mm as f64, p.y_mm as f64, p.z_mm as f64) * 1e-3, p.yaw_e4 as f64 * 1e-4)
}

/// A track state's velocity (east, north), m/s — none when the log reports it static:
/// its filtered velocity is then the anchoring's corrections seen against the world, not
/// motion. The device's windows score it so (`pipeline::tracking`); `verify` and the
/// nuPlan export read it here.
pub fn track_velocity(t: &Track3d) -> (f64, f64) {
    if t.is_static != 0 {
        (0.0, 0.0)
    } else {
        (t.vx_mm_s as f64 * 1e-3, t.vy_mm_s as f64 * 1e-3)
    }
}

/// Every 3D track with its time, in log order.
pub fn tracks(log: &LogContents) -> impl Iterator<Item = (i64, &Track3d)> {
    log.records
        .iter()
        .filter_map(|r| match r {
            Record::Tracks3d(b) => Some(b),
            _ => None,
        })
        .flat_map(|b| b.tracks.iter().map(move |t| (b.t_us, t)))
}

/// Every static object of the log, by track id: the time it was last reported (µs) and its
/// state standing at the median of where it was reported. A camera loses a drum once the car
/// draws level with it, but the drum stays: a replay that only had what the log reports at
/// each instant would let the ego drive through it unseen. `verify` and the simulator exports
/// keep these standing to the end of the log. A track is static when the log reports it so
/// in most of its states.
pub fn standing_objects(log: &LogContents) -> BTreeMap<i64, (i64, Track3d)> {
    let mut seen: BTreeMap<i64, Vec<(i64, &Track3d)>> = BTreeMap::new();
    for (t, track) in tracks(log) {
        seen.entry(track.id).or_default().push((t, track));
    }
    seen.into_iter()
        .filter(|(_, states)| 2 * states.iter().filter(|(_, s)| s.is_static != 0).count() > states.len())
        .filter_map(|(id, states)| {
            let median = |f: fn(&Track3d) -> i64| {
                let mut v: Vec<i64> = states.iter().map(|(_, s)| f(s)).collect();
                v.sort_unstable();
                v[v.len() / 2]
            };
            let &(last, track) = states.iter().max_by_key(|(t, _)| *t)?;
            let standing = Track3d {
                x_mm: median(|s| s.x_mm),
                y_mm: median(|s| s.y_mm),
                z_mm: median(|s| s.z_mm),
                is_static: 1,
                ..*track
            };
            Some((id, (last, standing)))
        })
        .collect()
}

/// The last state of every 3D track, by id, with its time.
pub fn last_tracks(log: &LogContents) -> BTreeMap<i64, (i64, &Track3d)> {
    tracks(log).map(|(t, track)| (track.id, (t, track))).collect()
}

#[cfg(test)]
mod tests {
    use super::standing_objects;
    use crate::log::LogContents;
    use dash2sim_core::binlog::{Record, Track3d, Tracks3d};

    fn batch(t_us: i64, tracks: &[Track3d]) -> Record {
        Record::Tracks3d(Tracks3d { t_us, tracks: tracks.iter().copied().collect() })
    }

    /// A drum the log reports static stands at the median of where it was seen, from its last
    /// report on; a car, static once, is not standing.
    #[test]
    fn a_static_object_stands_at_its_median_and_a_moving_one_does_not() {
        let drum = |x_mm| Track3d { id: 3, class: 7, x_mm, y_mm: 2_000, is_static: 1, ..Track3d::default() };
        let car = |is_static| Track3d { id: 4, class: 0, x_mm: 5_000, is_static, ..Track3d::default() };
        let log = LogContents {
            header: None,
            records: vec![
                batch(0, &[drum(10_000), car(0)]),
                batch(100_000, &[drum(10_400), car(1)]),
                batch(200_000, &[drum(9_900), car(0)]),
            ],
            damage: Vec::new(),
            stats: Default::default(),
            signing: Vec::new(),
            bytes: 0,
        };
        let standing = standing_objects(&log);
        assert_eq!(standing.keys().copied().collect::<Vec<_>>(), [3]);
        let (last, state) = standing[&3];
        assert_eq!((last, state.x_mm, state.y_mm, state.is_static), (200_000, 10_000, 2_000, 1));
    }
}
