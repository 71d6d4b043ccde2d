//! `dash2sim finish`: a device's log finished offline (`docs/finishing.md`).
//!
//! The device anchors causally, from what it has seen so far. Finishing re-estimates the
//! whole drive at once from everything the log holds — VO poses, GNSS fixes, wheel speed —
//! and optional external anchors ([`anchors`]), as one sparse least-squares problem
//! ([`solve`], its drift prior learnt from the anchors by [`walk`]); re-expresses and
//! smooths the 3D tracks ([`tracks`]); verifies the finished drive per window of nuPlan
//! scenario length and as a whole ([`windows`]); and writes a
//! finished log in the same format, whose first event says what it was finished from.
//!
//! The crate `dash2sim-finish` (issue #56: finishing out of the host library).
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod anchors;
pub mod clock;
mod prepare;
pub mod raw;
pub mod reckon;
pub mod report;
mod sessions;
pub mod solve;
mod timeline;
pub mod tracks;
pub mod walk;
pub mod windows;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dash2sim_core::binlog::{quantise, AnchorEstimate, EgoPose, GnssFix, Header, Record};
use dash2sim_core::pipeline::{mount_record, similarity_record, CameraMount, MountEstimate};
use dash2sim_core::sim3::Pose;

use dash2sim_linux::log::{self, event, LogContents, RecordStore};
use dash2sim_linux::record::{Device, VoFrame};
use dash2sim_linux::{Error, Field, Result};
use prepare::{prepare, Drive, Prepared};
pub use report::*;
use sessions::{bridge_gaps, frame_interval, join_sessions, solve_sessions, starting_velocity, PlanarPose, Solved};
use solve::{Settings, Solution};

/// A log to finish: `dash2sim finish` and the Python package's `finish` fill it.
#[derive(Clone, Debug)]
pub struct FinishRequest {
    /// The device's log.
    pub log: PathBuf,
    /// The finished log.
    pub output: PathBuf,
    /// Geo-referenced anchors: CSV with the header `t,lat,lon,alt,sigma_m` (rear axle at log
    /// time t, UTC s) or `x,y,z,lat,lon,alt,sigma_m` (a VO-frame point).
    pub anchors: Option<PathBuf>,
    /// A map tile: verify the finished drive per 15 s window and as a whole.
    pub map: Option<PathBuf>,
    /// The dashcam as given to `record`.
    pub device: Device,
    /// Keyframe spacing of the re-anchoring, s.
    pub keyframe: f64,
    /// Refuse the log unless every segment is signed by this public key, unaltered and in
    /// an unbroken chain.
    pub require_signed: Option<[u8; 32]>,
    /// Also write the problem each VO session's re-anchoring solved here, as JSON
    /// ([`factor_graphs`], `docs/finishing.md`).
    pub factor_graph: Option<PathBuf>,
}

/// The keyframe spacing of the re-anchoring when none is named, s.
pub const DEFAULT_KEYFRAME_S: f64 = 0.5;

/// Smoothing of the finished ego's planar track: position σ of the VO-derived positions
/// (m) and the car's white acceleration (m/s² per √s).
const EGO_SMOOTHING: (f64, f64) = (0.05, 0.5);
/// σ of the wheels' speed as the finished ego's smoother takes it, m/s: a vehicle bus's
/// speed is some tens of milliseconds old (no latency is solved for the wheels), and at
/// 1 m/s² of braking 0.1 s of it is 0.1 m/s.
const WHEEL_SPEED_SIGMA: f64 = 0.1;
/// Half the span of wheel speeds averaged for one VO pose, s.
const WHEEL_SPEED_HALF_SPAN_S: f64 = 0.05;

/// The wheels' mean speed over [`WHEEL_SPEED_HALF_SPAN_S`] either side of `t`, odometer
/// units; `None` when no speed was logged that close. `speeds` in time order.
fn wheel_speed_at(speeds: &[(f64, f64)], t: f64) -> Option<f64> {
    let from = speeds.partition_point(|s| s.0 < t - WHEEL_SPEED_HALF_SPAN_S);
    let near = speeds[from..].iter().take_while(|s| s.0 <= t + WHEEL_SPEED_HALF_SPAN_S).map(|s| s.1);
    let (sum, n) = near.fold((0.0, 0usize), |(sum, n), v| (sum + v, n + 1));
    (n > 0).then(|| sum / n as f64).filter(|v| v.is_finite())
}

/// A log as finishing reads it: its records held compactly (an hour of driving is 3 MB this
/// way and 214 MB as decoded records, [`RecordStore`]). [`log::read_compact`] reads one;
/// [`RecordStore::from_iter`] makes one of records already read.
pub type Source = LogContents<RecordStore>;

/// The problem each VO session's re-anchoring solved, as [`finish`] solves it (the same
/// arguments), written out for an outside solver ([`solve::factor_graph`]). Sessions that
/// could not be solved have none.
pub fn factor_graphs(
    log: &Source,
    name: &str,
    anchor_file: Option<(&str, &anchors::AnchorFile)>,
    mount: CameraMount,
    settings: Settings,
    uere: f64,
) -> Result<Vec<SessionGraph>> {
    let unslewed = Unslewed::of(log, anchor_file);
    let (log, anchor_file) = unslewed.or(log, anchor_file);
    let Prepared { drive, anchors, lever, .. } = prepare(log, name, anchor_file, mount, uere)?;
    let Solved { sessions, .. } = solve_sessions(&drive, &anchors, lever, settings);
    sessions
        .iter()
        .map(|s| {
            let inputs = solve::Inputs {
                vo: &drive.vo[s.range.clone()],
                fixes: &drive.fixes,
                speeds: &drive.speeds,
                anchors: &anchors,
                lever,
            };
            let (settings, enabled) = &s.solved_with;
            let graph = solve::factor_graph(inputs, *settings, enabled, &s.solution)
                .map_err(|e| Error::invalid(format!("{name}: VO session {}: {e}", s.session)))?;
            Ok(SessionGraph { session: s.session, graph })
        })
        .collect()
}

/// A log and its anchors at log times with the receiver latency its device slewed into its
/// clock taken out ([`clock::DeviceSlew`]); empty when it slewed none.
struct Unslewed {
    log: Option<Source>,
    anchors: Option<anchors::AnchorFile>,
}

impl Unslewed {
    fn of(log: &Source, anchor_file: Option<(&str, &anchors::AnchorFile)>) -> Unslewed {
        let Some(slew) = clock::DeviceSlew::of(log) else { return Unslewed { log: None, anchors: None } };
        Unslewed {
            log: Some(slew.taken_out_of(log)),
            anchors: anchor_file.map(|(_, file)| slew.taken_out_of_anchors(file)),
        }
    }

    /// The log and anchors to finish: these, or the ones given when the device slewed none.
    fn or<'a>(
        &'a self,
        log: &'a Source,
        anchor_file: Option<(&'a str, &'a anchors::AnchorFile)>,
    ) -> (&'a Source, Option<(&'a str, &'a anchors::AnchorFile)>) {
        let anchors = match (&self.anchors, anchor_file) {
            (Some(moved), Some((path, _))) => Some((path, moved)),
            _ => anchor_file,
        };
        (self.log.as_ref().unwrap_or(log), anchors)
    }
}

/// Finish a log that has been read. `anchor_file` and `map` are optional inputs.
pub fn finish(
    log: &Source,
    name: &str,
    anchor_file: Option<(&str, &anchors::AnchorFile)>,
    map: Option<&[u8]>,
    mount: CameraMount,
    settings: Settings,
    uere: f64,
) -> Result<Finished> {
    let unslewed = Unslewed::of(log, anchor_file);
    let (log, anchor_file) = unslewed.or(log, anchor_file);
    let Prepared { drive, anchors, calibrated, lever } = prepare(log, name, anchor_file, mount, uere)?;
    let nominal_yaw = mount.roll_pitch_yaw[2];
    let mount = calibrated.mount;
    let Solved { sessions, unsolved, verdicts } = solve_sessions(&drive, &anchors, lever, settings);
    if sessions.is_empty() {
        let why = unsolved.first().map_or_else(|| solve::SolveError::NoVo.to_string(), |u| u.2.clone());
        return Err(Error::invalid(format!("{name}: {why}")));
    }
    let used_anchors = verdicts.iter().filter(|v| v.is_none()).count();
    let mut refused: Vec<(usize, String)> = anchor_file.map(|(_, f)| f.refused.clone()).unwrap_or_default();
    refused.extend(
        verdicts.iter().enumerate().filter_map(|(k, v)| v.as_ref().map(|why| (line_of(anchor_file, k), why.clone()))),
    );
    refused.sort();

    let (ego, bridged, wheel_latency_s) = finished_ego(&drive, &sessions, &mount);
    let mut placed = place_objects(log, &drive, &ego, calibrated, nominal_yaw);
    let mut records = finished_records(log, &drive, &sessions, &ego, &mut placed, used_anchors);
    let verification = match map {
        Some(bytes) => Some(windows::verify_finished(log, &records, name, bytes)?),
        None => None,
    };
    if let Some(v) = &verification {
        records.extend(&v.records);
        records = records.sorted_by_time();
    }

    let fixes_used =
        (0..drive.fixes.len()).filter(|&k| sessions.iter().any(|s| s.solution.fix_used.get(k) == Some(&true))).count();
    // The longest session speaks for the drive's scale, latency and wheel factor.
    let main = sessions.iter().max_by_key(|s| s.range.len()).map(|s| &s.solution).unwrap_or_else(|| unreachable!());
    let device_fixes: Vec<GnssFix> =
        log.records.iter().filter_map(|r| if let Record::GnssFix(f) = r { Some(f) } else { None }).collect();
    let utc_latency_s = clock::latency_from_motion(&device_fixes, &ego).unwrap_or(main.latency_s);
    let utc_shift_us = clock::utc_onto_the_fixes(&mut records, utc_latency_s);
    let calibrated = placed.calibrated;
    let [_, pitch, yaw] = calibrated.mount.roll_pitch_yaw;
    let tracks = placed.tracks.stats;
    let mut report = FinishReport {
        log: name.to_owned(),
        records: 0, // counted once the events are in, below
        vo_poses: drive.vo.len(),
        ego_poses: ego.len(),
        ego_bridged: Bridged { gaps: bridged.len(), seconds: bridged.iter().map(|g| g.seconds).sum() },
        anchoring: anchoring_report(main),
        utc_shift_s: utc_shift_us as f64 * 1e-6,
        sessions: sessions
            .iter()
            .map(|s| {
                let vo = &drive.vo[s.range.clone()];
                SessionReport {
                    session: s.session,
                    vo_poses: vo.len(),
                    start_s: vo[0].t,
                    end_s: vo[vo.len() - 1].t,
                    anchoring: anchoring_report(&s.solution),
                }
            })
            .collect(),
        unsolved_sessions: unsolved
            .iter()
            .map(|(session, poses, why)| UnsolvedSession { session: *session, vo_poses: *poses, reason: why.clone() })
            .collect(),
        mount: MountReport {
            yaw_deg: yaw.to_degrees(),
            pitch_deg: pitch.to_degrees(),
            sigma_yaw_deg: calibrated.sigma[0].to_degrees(),
            sigma_pitch_deg: calibrated.sigma[1].to_degrees(),
            samples: calibrated.samples,
            calibrated: calibrated.calibrated,
        },
        reckoning: drive
            .reckoning
            .map(|r| ReckoningReport { static_objects_turned_deg: placed.static_yaw.map(f64::to_degrees), ..r }),
        gnss: GnssReport { fixes: drive.fixes.len(), used: fixes_used, rejected: drive.fixes.len() - fixes_used },
        speed_samples: drive.speeds.len(),
        wheel_latency_s,
        anchors: AnchorsReport {
            file: anchor_file.map(|(p, _)| p.to_owned()),
            used: used_anchors,
            refused: refused.iter().map(|(line, why)| RefusedAnchor { line: *line, reason: why.clone() }).collect(),
        },
        tracks: TracksReport {
            states: tracks.states,
            unplaced: tracks.unplaced,
            smoothed: tracks.smoothed,
            static_merged: tracks.merged_static,
            ghosts_dropped: tracks.ghosts + placed.raw_ghosts,
            raw_detections: placed.raw_stats.detections,
            raw_placed: placed.raw_stats.placed,
            raw_track_states: placed.raw_stats.track_states,
        },
        damage: DamageReport { stretches: log.damage.len(), bytes: log.damage.iter().map(|d| d.1).sum::<u64>() },
        verification: verification.as_ref().map(|v| v.report.clone()),
    };
    put_events_first(&mut records, &report, log.records.len(), utc_shift_us);
    report.records = records.len();
    Ok(Finished { records, report })
}

/// The finished ego: every VO pose's camera through the solution and the mount, its planar
/// track smoothed (the VO's frame-to-frame noise is not the car's motion) with the wheels'
/// speeds. Each session smoothed on its own (a constant-velocity smoother across a gap would
/// turn the two sessions' disagreement into a velocity), then the sessions joined and the
/// gaps between them bridged. The wheels report the speed some tens of milliseconds late,
/// and a smoother fed them as they arrive lags the car by part of it: their latency is found
/// first against the positions smoothed alone ([`clock::wheel_latency`]), and each speed
/// is taken at the instant it describes. The poses by time, the bridges, and the wheels'
/// latency where the drive told it.
fn finished_ego(
    drive: &Drive,
    sessions: &[sessions::SessionSolution],
    mount: &CameraMount,
) -> (BTreeMap<i64, EgoPose>, Vec<sessions::Bridge>, Option<f64>) {
    // Each session's bodies, made twice (first for the positions alone, then with the
    // wheels) rather than held for the whole drive: an hour's are 7 MB.
    let bodies_of = |solved: &sessions::SessionSolution| -> Vec<(f64, Pose)> {
        let vo = &drive.vo[solved.range.clone()];
        vo.iter()
            .filter_map(|s| {
                let (c, rotation) = solved.solution.camera_at(vo, s.t)?;
                Some((s.t, mount.body_pose(&Pose { rotation, translation: c })))
            })
            .collect()
    };
    let planar_of = |bodies: &[(f64, Pose)], speed: &dyn Fn(f64) -> Option<(f64, f64)>| {
        let mut planar: Vec<tracks::Sample> = bodies
            .iter()
            .map(|(t, b)| tracks::Sample {
                t: *t,
                x: b.translation.x,
                y: b.translation.y,
                speed: speed(*t),
                ..tracks::Sample::default()
            })
            .collect();
        let velocity = starting_velocity(&planar);
        tracks::smooth_planar(&mut planar, velocity, EGO_SMOOTHING.0, EGO_SMOOTHING.1);
        planar
    };
    let positions_alone: Vec<(f64, f64, f64)> = sessions
        .iter()
        .flat_map(|solved| planar_of(&bodies_of(solved), &|_| None).into_iter().map(|p| (p.t, p.x, p.y)))
        .collect();
    let wheel_latency = clock::wheel_latency(&drive.speeds, positions_alone).map(|(latency, _)| latency);
    let speeds: Vec<(f64, f64)> = drive.speeds.iter().map(|&(t, v)| (t - wheel_latency.unwrap_or(0.0), v)).collect();

    let mut planar_poses: Vec<PlanarPose> = Vec::new();
    // Where each session begins in `planar_poses`, and its wheel factor.
    let mut starts: Vec<(usize, f64)> = Vec::new();
    for solved in sessions {
        let bodies = bodies_of(solved);
        let factor = solved.solution.wheel_factor;
        let planar = planar_of(&bodies, &|t| wheel_speed_at(&speeds, t).map(|v| (v * factor, WHEEL_SPEED_SIGMA)));
        starts.push((planar_poses.len(), factor));
        for ((t, body), p) in bodies.iter().zip(&planar) {
            let heading = dash2sim_core::pipeline::mount::heading(&body.rotation);
            let sigma = solved.solution.horizontal_sigma_at(*t);
            planar_poses.push(PlanarPose {
                t: *t,
                x: p.x,
                y: p.y,
                z: body.translation.z,
                heading,
                vx: p.vx,
                vy: p.vy,
                sigma,
            });
        }
    }
    join_sessions(&mut planar_poses, &starts, &speeds);
    let mut ego: BTreeMap<i64, EgoPose> = BTreeMap::new();
    let bridged = bridge_gaps(&planar_poses, frame_interval(&drive.vo), &speeds);
    for pose in planar_poses.iter().chain(bridged.iter().flat_map(|g| &g.poses)) {
        let t_us = quantise(pose.t, 1e-6);
        ego.insert(
            t_us,
            EgoPose {
                t_us,
                x_mm: quantise(pose.x, 1e-3),
                y_mm: quantise(pose.y, 1e-3),
                z_mm: quantise(pose.z, 1e-3),
                yaw_e4: quantise(pose.heading, 1e-4),
                sigma_mm: if pose.sigma.is_finite() { quantise(pose.sigma, 1e-3) } else { 0 },
            },
        );
    }
    (ego, bridged, wheel_latency)
}

/// The objects placed through the finished ego: the device's tracks and the raw detections.
struct PlacedObjects {
    /// Both kinds of track, finished.
    tracks: tracks::FinishedTracks,
    /// The ghosts dropped among the raw detections' tracks.
    raw_ghosts: usize,
    /// What became of the raw detections.
    raw_stats: raw::RawStats,
    /// A dead-reckoned camera's yaw found from the static objects, rad.
    static_yaw: Option<f64>,
    /// The mount the objects were placed with (the log's).
    calibrated: MountEstimate,
}

/// The device's tracks re-expressed through the finished ego and the mount calibrated over
/// the whole drive (the device placed its detections through the mount it had then), and the
/// raw detections tracked through the finished ego; both smoothed and merged.
fn place_objects(
    log: &Source,
    drive: &Drive,
    ego: &BTreeMap<i64, EgoPose>,
    calibrated: MountEstimate,
    nominal_yaw: f64,
) -> PlacedObjects {
    let mount = calibrated.mount;
    let online: BTreeMap<i64, EgoPose> =
        log.records.iter().filter_map(|r| if let Record::EgoPose(p) = r { Some((p.t_us, p)) } else { None }).collect();
    let batches: Vec<_> =
        log.records.iter().filter_map(|r| if let Record::Tracks3d(b) = r { Some(b) } else { None }).collect();
    let ego_at = |poses: &BTreeMap<i64, EgoPose>, t: i64| {
        poses
            .get(&t)
            .map(|p| [p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3, p.z_mm as f64 * 1e-3, p.yaw_e4 as f64 * 1e-4])
    };
    let device_mounts: Vec<(i64, f64)> = log
        .records
        .iter()
        .filter_map(|r| if let Record::MountEstimate(m) = r { Some((m.t_us, m.yaw_e6 as f64 * 1e-6)) } else { None })
        .collect();
    let device_yaw = |t: i64| {
        let k = device_mounts.partition_point(|(ts, _)| *ts <= t);
        k.checked_sub(1).and_then(|i| device_mounts.get(i)).map_or(nominal_yaw, |m| m.1)
    };
    let camera = [mount.position[0], mount.position[1]];
    let online_turned = |t: i64, delta: f64| {
        ego_at(&online, t).map(|a| tracks::as_if_mounted(&a, camera, mount.roll_pitch_yaw[2] + delta - device_yaw(t)))
    };
    // A dead-reckoned camera's yaw on the car is the forward axis the gyro found (to a
    // degree or two); the static objects it saw say the rest. A camera's VO places its
    // objects and its ego with the same rotation, so a mount's yaw cannot move them.
    let static_yaw = drive.reckoning.and_then(|_| tracks::static_yaw(&batches, &online_turned, &|t| ego_at(ego, t)));
    let turn = static_yaw.unwrap_or(0.0);
    let mut objects_mount = mount;
    objects_mount.roll_pitch_yaw[2] += turn;
    let mut tracks = tracks::finish_tracks(&batches, &|t| online_turned(t, turn), &|t| ego_at(ego, t));
    let raw: Vec<_> =
        log.records.iter().filter_map(|r| if let Record::Detection3d(d) = r { Some(d) } else { None }).collect();
    let (raw_batches, raw_stats) = raw::track_raw(&raw, ego, &objects_mount);
    // Already placed through the finished ego: re-expressed onto itself, then smoothed and
    // merged as the device's tracks are.
    let raw_tracks = tracks::finish_tracks(&raw_batches, &|t| ego_at(ego, t), &|t| ego_at(ego, t));
    let raw_ghosts = raw_tracks.stats.ghosts;
    tracks.batches.extend(raw_tracks.batches);
    tracks.covariances.extend(raw_tracks.covariances);
    PlacedObjects {
        tracks,
        raw_ghosts,
        raw_stats,
        static_yaw,
        calibrated: MountEstimate { mount: objects_mount, ..calibrated },
    }
}

/// The finished log's records before verification: the source's, less what finishing
/// redoes (ego, anchor and mount estimates, tracks, verification), and the finished ones
/// (ego, tracks and their covariances — taken out of `placed`, which keeps their stats —
/// the mount, an anchor estimate a second per session); in time order.
fn finished_records(
    log: &Source,
    drive: &Drive,
    sessions: &[sessions::SessionSolution],
    ego: &BTreeMap<i64, EgoPose>,
    placed: &mut PlacedObjects,
    used_anchors: usize,
) -> RecordStore {
    let mut records = RecordStore::with_capacity(log.records.len() + ego.len());
    records.extend(log.records.iter().filter(|r| {
        !matches!(
            r,
            Record::EgoPose(_)
                | Record::AnchorEstimate(_)
                | Record::MountEstimate(_)
                | Record::Tracks3d(_)
                | Record::TrackCovariance(_)
                | Record::Verification(_)
        )
    }));
    records.extend(ego.values().map(|p| Record::EgoPose(*p)));
    records.extend(std::mem::take(&mut placed.tracks.batches).into_iter().map(Record::Tracks3d));
    records.extend(std::mem::take(&mut placed.tracks.covariances).into_iter().map(Record::TrackCovariance));
    if let Some(first) = drive.vo.first() {
        records.push(&Record::MountEstimate(mount_record(quantise(first.t, 1e-6), &placed.calibrated)));
    }
    for solved in sessions {
        let (vo, solution) = (&drive.vo[solved.range.clone()], &solved.solution);
        let mut last_estimate = f64::NEG_INFINITY;
        for k in 0..solution.keyframe_t.len().saturating_sub(1) {
            let t = solution.keyframe_t[k];
            if t - last_estimate < 1.0 {
                continue;
            }
            last_estimate = t;
            records.push(&Record::AnchorEstimate(anchor_record(t, &solution.sim3(vo, k), solution, used_anchors)));
        }
    }
    records.sorted_by_time()
}

/// The two events that say what `report` says (the first also the source's size, `source`
/// records) put first in `records`: a log is in UTC from its first clock offset on, a
/// finished log in UTC throughout, so that record goes first (nothing before it to move)
/// and the events next.
fn put_events_first(records: &mut RecordStore, report: &FinishReport, source: usize, utc_shift_us: i64) {
    let [summary, settings] = events(report, source, utc_shift_us);
    let first_t = records.get(0).map_or(0, |r| r.t_us());
    let clock = records.iter().position(|r| matches!(r, Record::ClockOffset(_)));
    let mut first = RecordStore::with_capacity(records.len() + 2);
    first.extend(clock.and_then(|k| records.get(k)));
    first.extend([event(first_t, 2, &summary), event(first_t, 2, &settings)]);
    first.extend(records.iter().enumerate().filter(|(k, _)| Some(*k) != clock).map(|(_, r)| r));
    *records = first;
}

/// The camera mount over the whole drive: the device's calibration run on every VO pose,
/// from the mount given to `finish` (the device's nominal one).
fn anchor_record(t: f64, sim3: &dash2sim_core::sim3::Sim3, solution: &Solution, used_anchors: usize) -> AnchorEstimate {
    let anchors = (solution.fix_used.iter().filter(|&&u| u).count() + used_anchors) as i64;
    similarity_record(quantise(t, 1e-6), sim3, 2, anchors, solution.gnss_rms_m, solution.latency_s)
}

/// The median of `v` (NaN when empty).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn line_of(file: Option<(&str, &anchors::AnchorFile)>, k: usize) -> usize {
    file.and_then(|(_, f)| f.anchors.get(k)).map_or(0, |a| a.line)
}

/// The drive's scale (segments weighted by duration).
pub fn mean_scale(s: &Solution) -> f64 {
    let mut sum = 0.0;
    let mut total = 0.0;
    for (k, w) in s.keyframe_t.windows(2).enumerate() {
        sum += (w[1] - w[0]) * s.log_scale[k];
        total += w[1] - w[0];
    }
    if total > 0.0 {
        (sum / total).exp()
    } else {
        f64::NAN
    }
}

/// The format `dash2sim finish --factor-graph` writes (`docs/finishing.md`).
pub const FACTOR_GRAPH_FORMAT: &str = "dash2sim-factor-graph 1";

/// What `dash2sim finish --factor-graph` writes.
#[derive(serde::Serialize)]
struct FactorGraphFile<'a> {
    format: &'static str,
    log: &'a str,
    sessions: Vec<SessionGraph>,
}

/// Finish the log at `args.log` into `args.output` (the command line and the Python
/// package's `finish`): the report (`--json`) with the output's path and size.
pub fn finish_file(args: &FinishRequest) -> Result<FinishedFile> {
    if !(args.keyframe.is_finite() && (0.05..=10.0).contains(&args.keyframe)) {
        return Err(Error::request(Field::Keyframe, format!("{} must be between 0.05 and 10 s", args.keyframe)));
    }
    let device = args.device.check()?;
    let (mount, uere) = (device.mount, device.uere);
    let log = log::read_compact(&args.log).map_err(Error::other)?;
    let name = args.log.display().to_string();
    if let Some(public) = &args.require_signed {
        log::signing::require_signed(public, &name, &log)?;
    }
    let anchor_file = args.anchors.as_deref().map(anchors::read).transpose()?;
    let anchor_name = args.anchors.as_deref().map(Path::display).map(|d| d.to_string());
    let map = args.map.as_deref().map(|p| std::fs::read(p).map_err(|e| Error::file(p, e))).transpose()?;
    let settings = Settings {
        keyframe_s: args.keyframe,
        gravity_aligned: args.device.mode == VoFrame::Gravity,
        ..Settings::default()
    };
    let anchor_file = anchor_name.as_deref().zip(anchor_file.as_ref());
    let finished = finish(&log, &name, anchor_file, map.as_deref(), mount, settings, uere)?;
    if let Some(path) = &args.factor_graph {
        let sessions = factor_graphs(&log, &name, anchor_file, mount, settings, uere)?;
        let text = serde_json::to_vec(&FactorGraphFile { format: FACTOR_GRAPH_FORMAT, log: &name, sessions })
            .map_err(Error::other)?;
        std::fs::write(path, text).map_err(|e| Error::file(path, e))?;
    }
    let header = log.header.unwrap_or(Header { device_id: [0; 16], origin: [0; 3] });
    let bytes = log::import::encode_in_order(&header, finished.records.iter())?;
    std::fs::write(&args.output, &bytes).map_err(|e| Error::file(&args.output, e))?;
    Ok(FinishedFile { report: finished.report, output: args.output.display().to_string(), bytes: bytes.len() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::nalgebra::{Matrix3, Vector3};
    use solve::{Fix, VoSample};

    /// A pose on the x axis, heading east.
    fn east(t: f64, x: f64, speed: f64) -> PlanarPose {
        PlanarPose { t, x, y: 0.0, z: 0.0, heading: 0.0, vx: speed, vy: 0.0, sigma: 0.1 }
    }

    /// The wheels at 50 Hz from `t0` to `t1` at a steady `speed`.
    fn steady_wheels(t0: f64, t1: f64, speed: f64) -> Vec<(f64, f64)> {
        let n = ((t1 - t0) * 50.0).round() as usize;
        (0..=n).map(|k| (t0 + k as f64 * 0.02, speed)).collect()
    }

    #[test]
    fn the_finished_ego_follows_the_wheels_at_their_instant_not_their_arrival() {
        use std::f64::consts::TAU;
        // East at 15 ± 5 m/s (an 8 s swing); the VO's positions 5 cm off alternately, so
        // that the wheels carry the speed; the bus reports each speed 80 ms late.
        let distance = |t: f64| 15.0 * t - 5.0 * 8.0 / TAU * (TAU * t / 8.0).cos();
        let speed = |t: f64| 15.0 + 5.0 * (TAU * t / 8.0).sin();
        let vo: Vec<VoSample> = (0..=400)
            .map(|k| {
                let t = 0.1 * k as f64;
                let noise = if k % 2 == 0 { 0.05 } else { -0.05 };
                VoSample {
                    t,
                    session: 0,
                    position: Vector3::new(distance(t) + noise, 0.0, 0.0),
                    rotation: Matrix3::identity(),
                    grade_sigma: 0.0,
                    reckoned: false,
                }
            })
            .collect();
        let fixes: Vec<Fix> = (0..=200)
            .map(|k| {
                let t = 0.2 * k as f64;
                Fix { t, enu: Vector3::new(distance(t), 0.0, 0.0), sigma_h: 1.0, sigma_v: 1.5 }
            })
            .collect();
        let speeds: Vec<(f64, f64)> = (0..=2000).map(|k| (0.02 * k as f64 + 0.08, speed(0.02 * k as f64))).collect();
        let settings = Settings { gravity_aligned: true, ..Settings::default() }.with_latency_held(0.0);
        let inputs = solve::Inputs { vo: &vo, fixes: &fixes, speeds: &speeds, anchors: &[], lever: Vector3::zeros() };
        let solution = solve::solve(inputs, settings, &[]).expect("solved");
        let session =
            sessions::SessionSolution { session: 0, range: 0..vo.len(), solution, solved_with: (settings, Vec::new()) };
        let drive = Drive { vo, fixes, speeds, reckoning: None };
        let (ego, _, latency) = finished_ego(&drive, &[session], &CameraMount::default());
        let latency = latency.expect("the speed swings");
        assert!((latency - 0.08).abs() < 0.01, "the wheels found {latency} s late");
        // The ego's speed (chords over ±0.1 s of its poses) against the car's: the shift that
        // matches them best is none (10 ms with the speeds taken as they arrive: the positions
        // hold the smoother back from the whole 80 ms).
        let track: Vec<(f64, f64)> = ego.values().map(|p| (p.t_us as f64 * 1e-6, p.x_mm as f64 * 1e-3)).collect();
        let x_at = |t: f64| {
            let k = track.partition_point(|p| p.0 <= t).clamp(1, track.len() - 1);
            let (a, b) = (track[k - 1], track[k]);
            a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
        };
        let cost = |shift: f64| -> f64 {
            (50..350)
                .map(|k| {
                    let t = 0.1 * k as f64;
                    ((x_at(t + shift + 0.1) - x_at(t + shift - 0.1)) / 0.2 - speed(t)).powi(2)
                })
                .sum()
        };
        let best = (-50..=50).map(|i| i as f64 * 0.002).min_by(|a, b| cost(*a).total_cmp(&cost(*b))).unwrap_or(1.0);
        assert!(best.abs() < 0.005, "the finished ego's speed lags the car's by {best} s");
    }

    #[test]
    fn a_bridge_advances_as_the_wheels_say_whatever_the_ends_velocities() {
        // 20 m/s throughout a 2 s gap; the second session's first smoothed velocity reads
        // 15 m/s, as a smoother's end can.
        let poses = [east(0.0, 0.0, 20.0), east(2.0, 40.0, 15.0)];
        let bridged = bridge_gaps(&poses, 0.1, &steady_wheels(-1.0, 3.0, 20.0));
        assert_eq!(bridged.len(), 1);
        let made = &bridged[0].poses;
        assert_eq!(made.len(), 19);
        for p in made {
            assert!((p.x - 20.0 * p.t).abs() < 0.05, "at {:.1} s: {:.3} m, the wheels say {:.3}", p.t, p.x, 20.0 * p.t);
        }
        // Without speeds the curve keeps to the ends' velocities: 1.25 m off at mid-gap.
        let by_time = bridge_gaps(&poses, 0.1, &[]);
        let middle = by_time[0].poses.iter().find(|p| (p.t - 1.0).abs() < 1e-9).map_or(f64::NAN, |p| p.x);
        assert!((middle - 21.25).abs() < 1e-9, "{middle}");
    }

    #[test]
    fn a_session_s_smoother_starts_at_the_session_s_own_speed_not_at_rest() {
        // A session that begins at 20 m/s east, its positions 5 cm off alternately.
        let samples: Vec<tracks::Sample> = (0..50)
            .map(|k| tracks::Sample {
                t: 0.1 * k as f64,
                x: 2.0 * k as f64 + if k % 2 == 0 { 0.05 } else { -0.05 },
                ..tracks::Sample::default()
            })
            .collect();
        let start = starting_velocity(&samples);
        assert!((start.0 - 20.0).abs() < 0.5 && start.1.abs() < 1e-9, "{start:?}");
        let first_speed = |velocity: (f64, f64)| {
            let mut smoothed = samples.clone();
            tracks::smooth_planar(&mut smoothed, velocity, EGO_SMOOTHING.0, EGO_SMOOTHING.1);
            smoothed[0].vx.hypot(smoothed[0].vy)
        };
        let (own, at_rest) = (first_speed(start), first_speed((0.0, 0.0)));
        assert!((own - 20.0).abs() < 0.3, "started at its own speed: {own:.2} m/s");
        assert!((at_rest - 20.0).abs() > 2.0 * (own - 20.0).abs(), "at rest {at_rest:.2}, own {own:.2}");
    }

    #[test]
    fn sessions_are_joined_at_the_wheels_distance_and_the_shift_eases_in() {
        // Session one ends at 0 m at 10 s; session two starts 1 s later at 21 m (its own
        // offset error 1 m), its first velocity read as 18 m/s. The wheels: 20 m/s.
        let mut poses: Vec<PlanarPose> =
            (0..=50).map(|k| east(5.0 + 0.1 * k as f64, 2.0 * k as f64 - 100.0, 20.0)).collect();
        let start = poses.len();
        poses.extend(
            (0..=50).map(|k| east(11.0 + 0.1 * k as f64, 21.0 + 2.0 * k as f64, if k == 0 { 18.0 } else { 20.0 })),
        );
        let before = poses.clone();
        join_sessions(&mut poses, &[(0, 1.0), (start, 1.0)], &steady_wheels(4.0, 17.0, 20.0));
        let (end, first) = (poses[start - 1], poses[start]);
        assert!((first.x - end.x - 20.0).abs() < 1e-6, "joined {:.3} m apart; the wheels went 20 m", first.x - end.x);
        assert!(
            (end.x - 0.5).abs() < 1e-6 && (first.x - 20.5).abs() < 1e-6,
            "each end takes half: {} {}",
            end.x,
            first.x
        );
        // The shift has no slope at the gap: 0.1 s in, it has barely changed (a linear
        // ramp would have changed by 1 cm, a 0.1 m/s step in velocity).
        let shift = |k: usize| poses[k].x - before[k].x;
        assert!((shift(start) - shift(start + 1)).abs() < 1e-3, "{} {}", shift(start), shift(start + 1));
        assert!((shift(start - 1) - shift(start - 2)).abs() < 1e-3);
        // And it is gone 5 s into each session.
        assert!(shift(start + 50).abs() < 1e-9 && shift(start - 51).abs() < 1e-9);
    }
}
