//! A log's states on a simulator's clock, in the projected frame of the simulator exports:
//! the ego resampled at a fixed rate (with body-frame velocity, acceleration and yaw rate),
//! the tracked objects of the nearest frame moved to each tick, and the check that the map
//! covers the drive. nuPlan's log database (20 Hz) and CommonRoad's scenarios (10 Hz) are
//! written from the same ticks.

use std::collections::BTreeMap;

use dash2sim_core::binlog::{Record, Track3d};
use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::map::MapView;
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::obb::{Pose2, PACIFICA};

use super::projection::Projection;
use dash2sim_linux::log::views::{standing_objects, track_velocity};
use dash2sim_linux::log::LogContents;
use dash2sim_linux::{Error, Field, Result};

/// A pose farther than this from every lane is off the map, m.
const OFF_MAP_M: f64 = 10.0;

/// An ego state at a tick, in the projected frame.
#[derive(Clone, Copy, Debug)]
pub struct EgoTick {
    /// Time, µs.
    pub t_us: i64,
    /// Rear axle, projected (m) and height.
    pub x: f64,
    /// Northing.
    pub y: f64,
    /// Height.
    pub z: f64,
    /// Grid heading, rad.
    pub heading: f64,
    /// Body-frame velocity (forward, left), m/s.
    pub velocity: (f64, f64),
    /// Body-frame acceleration, m/s².
    pub acceleration: (f64, f64),
    /// Yaw rate, rad/s.
    pub yaw_rate: f64,
    /// The log's ENU pose, for map queries in the tile's frame.
    pub enu: Pose2,
}

impl EgoTick {
    /// The centre of the ego's footprint (nuPlan's Pacifica, which `verify` uses): where
    /// CommonRoad and ScenarioNet place a vehicle, while the log's pose is the rear axle.
    pub fn centre(&self) -> (f64, f64) {
        let forward = 0.5 * (PACIFICA.front - PACIFICA.rear);
        (self.x + forward * self.heading.cos(), self.y + forward * self.heading.sin())
    }
}

/// The log's origin (its header's), where its ENU frame is anchored.
fn log_origin(log: &LogContents) -> Result<Geodetic> {
    let h = log.header.ok_or_else(|| Error::invalid("the log's header is damaged (no origin)"))?;
    Geodetic::new(f64::from(h.origin[0]) * 1e-7, f64::from(h.origin[1]) * 1e-7, f64::from(h.origin[2]) * 1e-3)
        .map_err(|e| Error::refused("the log's origin", e))
}

fn wrap(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Poses in a derivative's local fit: `verify`'s comfort window (7 poses, 0.6 s of a 10 Hz
/// log).
const FIT_POSES: usize = dash2sim_core::score::COMFORT_WINDOW;

/// The first and second derivative at `t0` of the quadratic in time fitted (least squares)
/// through `samples` (time s, value); `None` where their times do not fix one.
fn quadratic_derivatives(samples: &[(f64, f64)], t0: f64) -> Option<(f64, f64)> {
    if samples.len() < 3 {
        return None;
    }
    // Normal equations of v = a + b·τ + c·τ², τ = t − t0.
    let mut m = [[0.0; 3]; 3];
    let mut r = [0.0; 3];
    for &(t, v) in samples {
        let tau = t - t0;
        let basis = [1.0, tau, tau * tau];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += basis[i] * basis[j];
            }
            r[i] += basis[i] * v;
        }
    }
    let m = dash2sim_core::nalgebra::Matrix3::from_fn(|i, j| m[i][j]);
    let coefficients = m.lu().solve(&Vector3::from(r))?;
    coefficients.iter().all(|c| c.is_finite()).then(|| (coefficients[1], 2.0 * coefficients[2]))
}

/// Each pose's velocity and acceleration (east, north) and yaw rate, from a quadratic fitted
/// in time through the [`FIT_POSES`] poses around it — within its stretch of poses less than
/// [`dash2sim_core::score::HOLE_S`] apart, and shifted inwards at a stretch's ends — as
/// `verify`'s comfort metric differentiates them (Savitzky–Golay's quadratic, on the log's
/// own times). Differenced between resampled ticks instead, the velocity is a staircase
/// between the log's poses and the acceleration a row of spikes at them: nuPlan, whose
/// comfort metric reads a log's accelerations, failed drives that `verify` passes.
fn pose_derivatives(poses: &[(i64, [f64; 4])]) -> Vec<[f64; 5]> {
    let seconds = |k: usize| poses[k].0 as f64 * 1e-6;
    // Unwrapped headings, so that a fit never straddles ±π.
    let mut heading = Vec::with_capacity(poses.len());
    for (k, p) in poses.iter().enumerate() {
        let previous = if k > 0 { heading[k - 1] } else { p.1[3] };
        heading.push(if k > 0 { previous + wrap(p.1[3] - previous) } else { previous });
    }
    let mut out = vec![[0.0; 5]; poses.len()];
    let mut start = 0;
    while start < poses.len() {
        let mut end = start + 1;
        while end < poses.len() && seconds(end) - seconds(end - 1) <= dash2sim_core::score::HOLE_S {
            end += 1;
        }
        for (k, derivatives) in out.iter_mut().enumerate().take(end).skip(start) {
            let from = k.saturating_sub(FIT_POSES / 2).max(start).min(end.saturating_sub(FIT_POSES).max(start));
            let to = (from + FIT_POSES).min(end);
            let t0 = seconds(k);
            let fit = |value: &dyn Fn(usize) -> f64| {
                let samples: Vec<(f64, f64)> = (from..to).map(|i| (seconds(i), value(i))).collect();
                quadratic_derivatives(&samples, t0)
            };
            let (vx, ax) = fit(&|i| poses[i].1[0]).unwrap_or((0.0, 0.0));
            let (vy, ay) = fit(&|i| poses[i].1[1]).unwrap_or((0.0, 0.0));
            let (yaw_rate, _) = fit(&|i| heading[i]).unwrap_or((0.0, 0.0));
            *derivatives = [vx, vy, ax, ay, yaw_rate];
        }
        start = end;
    }
    out
}

/// The log's ego poses resampled at exactly `rate_hz` (linear in position, shortest-way in
/// heading), projected, with body-frame velocities and accelerations and the yaw rate
/// from the log's own poses (a quadratic fitted through the 7 around each), linear between them.
pub fn ego_ticks(log: &LogContents, projection: &Projection, rate_hz: f64) -> Result<Vec<EgoTick>> {
    let mut poses: Vec<(i64, [f64; 4])> = log
        .records
        .iter()
        .filter_map(|r| match r {
            Record::EgoPose(p) => Some((
                p.t_us,
                [p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3, p.z_mm as f64 * 1e-3, p.yaw_e4 as f64 * 1e-4],
            )),
            _ => None,
        })
        .collect();
    poses.sort_by_key(|p| p.0);
    poses.dedup_by_key(|p| p.0);
    let (Some(first), Some(last)) = (poses.first(), poses.last()) else {
        return Err(Error::invalid("the log has no ego poses"));
    };
    let derivatives = pose_derivatives(&poses);
    let step = (1e6 / rate_hz) as i64;
    let ticks = ((last.0 - first.0) / step + 1) as usize;
    let mut enu = Vec::with_capacity(ticks);
    let mut k = 0;
    for n in 0..ticks {
        let t = first.0 + n as i64 * step;
        while k + 1 < poses.len() && poses[k + 1].0 < t {
            k += 1;
        }
        let next = (k + 1).min(poses.len() - 1);
        let (a, b) = (poses[k], poses[next]);
        let f = if b.0 > a.0 { ((t - a.0) as f64 / (b.0 - a.0) as f64).clamp(0.0, 1.0) } else { 0.0 };
        let lerp = |i: usize| a.1[i] + (b.1[i] - a.1[i]) * f;
        let heading = a.1[3] + wrap(b.1[3] - a.1[3]) * f;
        let derivative = |i: usize| derivatives[k][i] + (derivatives[next][i] - derivatives[k][i]) * f;
        enu.push((t, [lerp(0), lerp(1), lerp(2), heading], [0, 1, 2, 3, 4].map(derivative)));
    }
    let points: Vec<(f64, f64, f64)> = enu.iter().map(|(_, p, _)| (p[0], p[1], p[2])).collect();
    let projected = projection.project(&points);
    let mut out = Vec::with_capacity(enu.len());
    for (i, (t, p, d)) in enu.into_iter().enumerate() {
        // Body frame from the ENU heading: the projection turns the world frame and the
        // heading alike (and scales lengths by its factor, 1 ± 0.0004).
        let (s, c) = p[3].sin_cos();
        let body = |v: (f64, f64)| (c * v.0 + s * v.1, -s * v.0 + c * v.1);
        out.push(EgoTick {
            t_us: t,
            x: projected[i].0,
            y: projected[i].1,
            z: p[2],
            heading: projection.heading((p[0], p[1], p[2]), p[3]),
            velocity: body((d[0], d[1])),
            acceleration: body((d[2], d[3])),
            yaw_rate: d[4],
            enu: Pose2::new(p[0], p[1], p[3]),
        });
    }
    Ok(out)
}

/// A log and a map tile in one projected frame (the UTM zone of the map's origin): what a
/// simulator export starts from.
pub struct OnMap<'t> {
    /// The tile.
    pub view: MapView<'t>,
    /// The tile's origin.
    pub map_origin: Geodetic,
    /// The tile's frame into UTM.
    pub map_projection: Projection,
    /// The log's frame into the same zone.
    pub log_projection: Projection,
    /// The ego at `rate_hz`, its ENU poses in the map's frame.
    pub ticks: Vec<EgoTick>,
}

impl std::fmt::Debug for OnMap<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OnMap")
            .field("map_origin", &self.map_origin)
            .field("map_projection", &self.map_projection)
            .field("ticks", &self.ticks.len())
            .finish_non_exhaustive()
    }
}

/// `log` (named `log_name` in errors) resampled at `rate_hz` and placed on `tile`: errors for
/// a damaged tile or header, a log without ego poses, a map that does not cover the drive.
pub fn on_map<'t>(log: &LogContents, log_name: &str, tile: &'t [u8], rate_hz: f64) -> Result<OnMap<'t>> {
    let view = MapView::parse(tile).map_err(|e| Error::refused("map", e))?;
    let [lat, lon, h] = view.header().origin;
    let map_origin = Geodetic::new(lat, lon, h).map_err(|e| Error::refused("map origin", e))?;
    let map_projection = Projection::new(map_origin)?;
    let origin = log_origin(log)?;
    let log_projection = Projection::with_zone(origin, map_projection.zone, map_projection.north)?;
    let mut ticks = ego_ticks(log, &log_projection, rate_hz).map_err(|e| Error::refused(log_name.to_string(), e))?;
    place_on_map(&mut ticks, origin, map_origin, &view)?;
    Ok(OnMap { view, map_origin, map_projection, log_projection, ticks })
}

/// The ticks' ENU poses moved from the log's frame (origin `log_origin`) into the map's
/// (`map_origin`), through geodetic positions; an error when more than a tenth of them lie
/// farther than 10 m from every lane of `view` (the map does not cover the drive).
fn place_on_map(ticks: &mut [EgoTick], log_origin: Geodetic, map_origin: Geodetic, view: &MapView<'_>) -> Result<()> {
    let (log_frame, map_frame) = (LocalFrame::new(log_origin), LocalFrame::new(map_origin));
    let mut off = 0;
    for t in ticks.iter_mut() {
        if let Ok(g) = log_frame.enu_to_geodetic(&Vector3::new(t.enu.x, t.enu.y, 0.0)) {
            let m = map_frame.geodetic_to_enu(&g);
            t.enu = Pose2::new(m.x, m.y, t.enu.heading);
        }
        if view.distance_to_drivable(t.enu.x, t.enu.y, OFF_MAP_M, |_| true).is_none() {
            off += 1;
        }
    }
    if off * 10 > ticks.len() {
        return Err(Error::invalid(format!(
            "the map does not cover the drive: {off} of {} ego poses are farther than {OFF_MAP_M} m from every lane",
            ticks.len()
        )));
    }
    Ok(())
}

/// A tracked object at a tick, in the projected frame.
#[derive(Clone, Copy, Debug)]
pub struct AgentTick {
    /// Index of the tick.
    pub tick: usize,
    /// The track's state as logged (id, class, size, …).
    pub track: Track3d,
    /// Centre, projected (m), and height.
    pub x: f64,
    /// Northing.
    pub y: f64,
    /// Height.
    pub z: f64,
    /// Grid heading of the box, rad.
    pub heading: f64,
    /// Velocity in the grid (east, north), m/s; zero for a static object.
    pub velocity: (f64, f64),
}

/// The tracks of the batch nearest each tick (within one tick's step), moved by their
/// velocity to the tick's time, projected, with the static objects the camera has lost
/// standing where they were seen ([`standing_objects`]); in tick order.
pub fn agents_at_ticks(log: &LogContents, ticks: &[EgoTick], projection: &Projection) -> Vec<AgentTick> {
    let mut batches: BTreeMap<i64, Vec<Track3d>> = BTreeMap::new();
    for r in &log.records {
        if let Record::Tracks3d(b) = r {
            batches.entry(b.t_us).or_default().extend(b.tracks.iter().copied());
        }
    }
    // Static objects stand where they were seen after the camera lost them.
    for (last, standing) in standing_objects(log).into_values() {
        for batch in batches.range_mut(last + 1..).map(|(_, b)| b) {
            if !batch.iter().any(|t| t.id == standing.id) {
                batch.push(standing);
            }
        }
    }
    let step = match ticks {
        [a, b, ..] => b.t_us - a.t_us,
        _ => 0,
    };
    let mut placed = Vec::new();
    for (i, tick) in ticks.iter().enumerate() {
        let nearest = batches.range(tick.t_us - step..=tick.t_us + step).min_by_key(|(t, _)| (*t - tick.t_us).abs());
        if let Some((t, tracks)) = nearest {
            let dt = (tick.t_us - t) as f64 * 1e-6;
            for track in tracks {
                let (vx, vy) = track_velocity(track);
                let at =
                    (track.x_mm as f64 * 1e-3 + vx * dt, track.y_mm as f64 * 1e-3 + vy * dt, track.z_mm as f64 * 1e-3);
                placed.push((i, *track, at));
            }
        }
    }
    let points: Vec<(f64, f64, f64)> = placed.iter().map(|p| p.2).collect();
    let projected = projection.project(&points);
    placed
        .iter()
        .zip(projected)
        .map(|(&(tick, track, at), (x, y))| {
            let (vx, vy) = track_velocity(&track);
            let speed = vx.hypot(vy);
            let speed_heading = projection.heading(at, vy.atan2(vx));
            AgentTick {
                tick,
                track,
                x,
                y,
                z: at.2,
                heading: projection.heading(at, track.yaw_e4 as f64 * 1e-4),
                velocity: (speed * speed_heading.cos(), speed * speed_heading.sin()),
            }
        })
        .collect()
}

/// The windows of `ticks` ticks (`step_s` apart) a simulator export writes, as (first, end)
/// tick ranges: one per whole `window_s` seconds, or the whole drive when `None`. Errors for a
/// window under `min_steps` ticks and for a drive shorter than one window; `simulator` and
/// `log_name` name them.
pub fn windows(
    ticks: usize,
    window_s: Option<f64>,
    step_s: f64,
    min_steps: usize,
    simulator: &str,
    log_name: &str,
) -> Result<Vec<(usize, usize)>> {
    let window = match window_s {
        None => ticks,
        Some(s) if s.is_finite() && (s / step_s).round() as usize >= min_steps => (s / step_s).round() as usize,
        Some(s) => {
            return Err(Error::request(
                Field::ScenarioSeconds,
                format!(
                    "{s} s: a {simulator} scenario needs at least {} s ({min_steps} steps of {step_s} s)",
                    min_steps as f64 * step_s
                ),
            ))
        }
    };
    if ticks < window.max(min_steps) {
        return Err(Error::invalid(format!(
            "{log_name}: {:.1} s of ego poses are shorter than one scenario ({:.1} s)",
            ticks.saturating_sub(1) as f64 * step_s,
            window.max(min_steps) as f64 * step_s
        )));
    }
    Ok((0..ticks / window).map(|k| (k * window, (k + 1) * window)).collect())
}

/// A window's agents by track id, each track's states in tick order.
pub fn by_track<'a>(agents: &[&'a AgentTick]) -> BTreeMap<i64, Vec<&'a AgentTick>> {
    let mut tracks: BTreeMap<i64, Vec<&AgentTick>> = BTreeMap::new();
    for &a in agents {
        tracks.entry(a.track.id).or_default().push(a);
    }
    tracks
}

/// Whether a track stands still: static in most of its states.
pub fn stands_still(states: &[&AgentTick]) -> bool {
    2 * states.iter().filter(|a| a.track.is_static == 1).count() > states.len()
}

/// Where a standing track stands: the median of its positions, its first state otherwise.
/// `states` is not empty.
pub fn standing(states: &[&AgentTick]) -> AgentTick {
    let median = |f: fn(&AgentTick) -> f64| {
        let mut v: Vec<f64> = states.iter().map(|a| f(a)).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    AgentTick { x: median(|a| a.x), y: median(|a| a.y), ..*states[0] }
}

/// A track unseen for at most this many ticks is bridged in its trajectory.
pub const MAX_BRIDGED_TICKS: usize = 10;

/// A track's states (in tick order) as gapless runs of one state per tick: a gap of up to
/// [`MAX_BRIDGED_TICKS`] is bridged linearly, a longer one starts a new run (simulators'
/// trajectories have no gaps).
pub fn runs(states: &[&AgentTick]) -> Vec<Vec<AgentTick>> {
    let mut runs: Vec<Vec<AgentTick>> = Vec::new();
    for &&a in states {
        match runs.last_mut() {
            Some(run) if run.last().is_some_and(|p| a.tick <= p.tick + MAX_BRIDGED_TICKS) => {
                if let Some(&p) = run.last() {
                    run.extend((p.tick + 1..a.tick).map(|tick| between(&p, &a, tick)));
                }
                run.push(a);
            }
            _ => runs.push(vec![a]),
        }
    }
    runs
}

/// The state at `tick` between `a` and `b` (linear; the heading the shorter way).
fn between(a: &AgentTick, b: &AgentTick, tick: usize) -> AgentTick {
    let f = (tick - a.tick) as f64 / (b.tick - a.tick) as f64;
    let lerp = |p: f64, q: f64| p + (q - p) * f;
    AgentTick {
        tick,
        x: lerp(a.x, b.x),
        y: lerp(a.y, b.y),
        z: lerp(a.z, b.z),
        heading: a.heading + wrap(b.heading - a.heading) * f,
        velocity: (lerp(a.velocity.0, b.velocity.0), lerp(a.velocity.1, b.velocity.1)),
        ..*a
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::binlog::{quantise, EgoPose};

    /// A log braking east at 3 m/s² from 20 m/s, its poses at 10 Hz each off by ±2 cm
    /// alternately (a VO's frame-to-frame noise).
    fn braking() -> LogContents {
        let records = (0..50)
            .map(|k| {
                let t = 0.1 * f64::from(k);
                let noise = if k % 2 == 0 { 0.02 } else { -0.02 };
                let t_us = quantise(t, 1e-6);
                Record::EgoPose(EgoPose {
                    t_us,
                    x_mm: quantise(20.0 * t - 1.5 * t * t + noise, 1e-3),
                    ..EgoPose::default()
                })
            })
            .collect();
        LogContents {
            header: None,
            records,
            damage: Vec::new(),
            stats: Default::default(),
            bytes: 0,
            signing: Vec::new(),
        }
    }

    #[test]
    fn the_ticks_brake_as_the_log_does_without_its_frame_noise() {
        let projection = Projection::new(Geodetic::new(60.17, 24.94, 0.0).expect("origin")).expect("projection");
        let ticks = ego_ticks(&braking(), &projection, 20.0).expect("ticks");
        assert_eq!(ticks.len(), 99);
        for tick in &ticks[6..93] {
            let t = tick.t_us as f64 * 1e-6;
            let (forward, left) = tick.velocity;
            assert!((forward - (20.0 - 3.0 * t)).abs() < 0.15 && left.abs() < 1e-6, "t {t}: {forward} m/s");
            // Differenced between ticks, the ±2 cm read as ±8 m/s² spikes.
            assert!((tick.acceleration.0 + 3.0).abs() < 0.5, "t {t}: {:?}", tick.acceleration);
            assert!(tick.yaw_rate.abs() < 1e-9);
        }
    }

    #[test]
    fn a_fit_needs_three_times() {
        assert_eq!(quadratic_derivatives(&[(0.0, 1.0), (0.1, 2.0)], 0.0), None);
        let (v, a) = quadratic_derivatives(&[(0.0, 0.0), (0.1, 0.1), (0.3, 0.9)], 0.1).expect("three");
        // y = 10t²: 2 m/s and 20 m/s² at 0.1 s.
        assert!((v - 2.0).abs() < 1e-9 && (a - 20.0).abs() < 1e-9, "{v} {a}");
    }
}
