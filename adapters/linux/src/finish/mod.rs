//! `dash2sim finish`: a device's log finished offline (`docs/finishing.md`).
//!
//! The device anchors causally, from what it has seen so far. Finishing re-estimates the
//! whole drive at once from everything the log holds — VO poses, GNSS fixes, wheel speed —
//! and optional external anchors ([`anchors`]), as one sparse least-squares problem
//! ([`solve`], its drift prior learnt from the anchors by [`walk`]); re-expresses and
//! smooths the 3D tracks ([`tracks`]); verifies the finished drive per window of nuPlan
//! scenario length and as a whole ([`windows`]); and writes a
//! finished log in the same format, whose first event says what it was finished from.

pub mod anchors;
pub mod clock;
pub mod raw;
pub mod reckon;
pub mod solve;
pub mod tracks;
pub mod walk;
pub mod windows;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dash2sim_core::binlog::{quantise, AnchorEstimate, EgoPose, Header, Record, FRAME_DEAD_RECKONED};
use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::{Matrix3, Rotation3, Vector3};
use dash2sim_core::pipeline::{
    mount_record, similarity_record, CalibrationConfig, CameraMount, MountCalibration, MountEstimate,
};
use dash2sim_core::sim3::Pose;
use serde::Serialize;

use crate::log::{self, event, LogContents};
use crate::record::{Device, VoFrame};
use crate::{Error, Result};
use anchors::AnchorForm;
use solve::{Anchor, AnchorAt, Fix, Inputs, Settings, Solution, VoSample};

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

/// What finishing produced, for the report and the tests.
#[derive(Debug)]
pub struct Finished {
    /// The finished log's records, in file order.
    pub records: Vec<Record>,
    /// The report (`--json`).
    pub report: FinishReport,
}

/// What `finish` did (`dash2sim finish --json`).
#[derive(Clone, Debug, Serialize)]
pub struct FinishReport {
    /// The log's name.
    pub log: String,
    /// Records in the finished log.
    pub records: usize,
    /// VO poses read.
    pub vo_poses: usize,
    /// Ego poses written.
    pub ego_poses: usize,
    /// Gaps in the VO bridged by GNSS and wheel speed.
    pub ego_bridged: Bridged,
    /// The main session's solution.
    pub anchoring: AnchoringReport,
    /// How much later every record of the finished log is than the device's: the
    /// receiver's latency, by which the device's UTC was early, s (0 for a log without UTC).
    pub utc_shift_s: f64,
    /// Every solved VO session.
    pub sessions: Vec<SessionReport>,
    /// VO sessions that could not be solved, and why.
    pub unsolved_sessions: Vec<UnsolvedSession>,
    /// The camera mount, calibrated over the whole drive.
    pub mount: MountReport,
    /// The dead-reckoned poses (gyro + wheels) redone, when the log has any.
    pub reckoning: Option<ReckoningReport>,
    /// GNSS fixes read, used, rejected.
    pub gnss: GnssReport,
    /// Wheel-speed samples read.
    pub speed_samples: usize,
    /// The street-imagery anchors.
    pub anchors: AnchorsReport,
    /// 3D tracks smoothed and raw detections tracked.
    pub tracks: TracksReport,
    /// Damage the log had.
    pub damage: DamageReport,
    /// The finished log replayed against the map, when one was given (the windows' report).
    pub verification: Option<windows::DriveVerification>,
}

/// VO gaps bridged.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Bridged {
    /// Gaps.
    pub gaps: usize,
    /// Their total length, s.
    pub seconds: f64,
}

/// One similarity chain's solution.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct AnchoringReport {
    /// Keyframes.
    pub keyframes: usize,
    /// Gauss–Newton iterations.
    pub iterations: usize,
    /// The drive's scale (segments weighted by duration).
    pub scale: f64,
    /// The scale's relative σ.
    pub scale_sigma_relative: f64,
    /// Position σ, m.
    pub position_sigma_m: f64,
    /// The a-posteriori variance factor.
    pub sigma0_squared: f64,
    /// The GNSS latency solved for, s.
    pub gnss_latency_s: f64,
    /// The wheel-speed factor solved for.
    pub wheel_factor: f64,
    /// A dead-reckoned path's heading drift rate solved for (the gyro bias about the
    /// vertical the device's estimate left, with the opposite sign), degrees per second;
    /// 0 for a camera's VO.
    pub heading_drift_deg_s: f64,
    /// RMS of the GNSS residuals, m (null when none).
    pub gnss_rms_m: f64,
}

/// A solved VO session.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SessionReport {
    /// The session number.
    pub session: u32,
    /// Its VO poses.
    pub vo_poses: usize,
    /// Its first pose's time, s.
    pub start_s: f64,
    /// Its last pose's time, s.
    pub end_s: f64,
    /// Its solution.
    pub anchoring: AnchoringReport,
}

/// A VO session that could not be solved.
#[derive(Clone, Debug, Serialize)]
pub struct UnsolvedSession {
    /// The session number.
    pub session: u32,
    /// Its VO poses.
    pub vo_poses: usize,
    /// Why.
    pub reason: String,
}

/// The camera mount as calibrated.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MountReport {
    /// Yaw, degrees.
    pub yaw_deg: f64,
    /// Pitch, degrees.
    pub pitch_deg: f64,
    /// Yaw σ, degrees.
    pub sigma_yaw_deg: f64,
    /// Pitch σ, degrees.
    pub sigma_pitch_deg: f64,
    /// Straight-driving frames used.
    pub samples: u32,
    /// Whether it is calibrated.
    pub calibrated: bool,
}

/// The dead-reckoned poses redone with what the whole drive shows ([`reckon`]).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct ReckoningReport {
    /// The largest heading correction the gyro's final bias made, degrees.
    pub heading_corrected_max_deg: f64,
    /// The largest tilt correction its final horizontal bias made, degrees.
    pub tilt_corrected_max_deg: f64,
    /// The sensor's yaw on the car as the device knew it last (the car's forward axis), by
    /// which every camera is turned off its track, degrees (−δ); `None` when the device
    /// never found it.
    pub camera_turned_deg: Option<f64>,
    /// The sensor's pitch above the road's grade the fixes' heights show (its tilt on the
    /// camera and the accelerometer's forward bias), degrees; `None` when the fixes span
    /// too little road to tell and the poses were left level.
    pub pitch_offset_deg: Option<f64>,
    /// The dead-reckoned distance with fixes beside it that measured it, m.
    pub grade_baseline_m: Option<f64>,
    /// How much further left the camera looks than the mount calibrated from its track,
    /// by the static objects it saw ([`tracks::static_yaw`]), degrees; `None` with too few
    /// of them. The finished mount and every object are turned by it.
    pub static_objects_turned_deg: Option<f64>,
}

/// GNSS fixes.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct GnssReport {
    /// Read.
    pub fixes: usize,
    /// Used by the solution.
    pub used: usize,
    /// Rejected as outliers.
    pub rejected: usize,
}

/// The anchors file.
#[derive(Clone, Debug, Serialize)]
pub struct AnchorsReport {
    /// Its name, if one was given.
    pub file: Option<String>,
    /// Anchors used.
    pub used: usize,
    /// Lines refused, and why.
    pub refused: Vec<RefusedAnchor>,
}

/// A refused anchors line.
#[derive(Clone, Debug, Serialize)]
pub struct RefusedAnchor {
    /// The line.
    pub line: usize,
    /// Why.
    pub reason: String,
}

/// Tracks.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TracksReport {
    /// 3D track states read.
    pub states: usize,
    /// Of them, not placed (no pose).
    pub unplaced: usize,
    /// Smoothed tracks.
    pub smoothed: usize,
    /// Static tracks merged.
    pub static_merged: usize,
    /// Ghost tracks dropped.
    pub ghosts_dropped: usize,
    /// Raw detections read.
    pub raw_detections: usize,
    /// Of them, placed.
    pub raw_placed: usize,
    /// Track states made from them.
    pub raw_track_states: usize,
}

/// Damage.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct DamageReport {
    /// Damaged stretches.
    pub stretches: usize,
    /// Bytes in them.
    pub bytes: u64,
}

/// `finish_file`'s report: the finish report with the output's path and size.
#[derive(Clone, Debug, Serialize)]
pub struct FinishedFile {
    /// What finishing did.
    #[serde(flatten)]
    pub report: FinishReport,
    /// The finished log's path.
    pub output: String,
    /// Its size.
    pub bytes: usize,
}

/// A log's drive as the solver reads it, in the log's ENU frame.
struct Drive {
    vo: Vec<VoSample>,
    fixes: Vec<Fix>,
    speeds: Vec<(f64, f64)>,
    /// What redoing the dead-reckoned poses found, when there were any.
    reckoning: Option<ReckoningReport>,
}

/// `camera_to_body`: the mount the device reckoned with (its poses are the attitude
/// through it).
fn drive(log: &LogContents, frame: &LocalFrame, uere: f64, camera_to_body: &Matrix3<f64>) -> Drive {
    let (mut vo, mut fixes, mut speeds) = (Vec::new(), Vec::new(), Vec::new());
    let (mut dead_reckoned, mut bias) = (Vec::new(), Vec::new());
    for r in &log.records {
        match r {
            Record::FrameMeta(m) if m.flags & FRAME_DEAD_RECKONED != 0 => dead_reckoned.push(log::seconds(m.t_us)),
            Record::ImuEstimate(e) => bias.push((log::seconds(e.t_us), [e.bias_x_e7, e.bias_y_e7, e.bias_z_e7])),
            Record::VoPose(p) => vo.push(VoSample {
                t: log::seconds(p.t_us),
                session: u32::try_from(p.session).unwrap_or(u32::MAX),
                position: Vector3::new(p.x as f64, p.y as f64, p.z as f64) * 1e-3,
                rotation: Rotation3::from_euler_angles(
                    p.roll_e4 as f64 * 1e-4,
                    p.pitch_e4 as f64 * 1e-4,
                    p.yaw_e4 as f64 * 1e-4,
                )
                .into_inner(),
                grade_sigma: 0.0,
                reckoned: false,
            }),
            Record::GnssFix(f) if f.mode >= 2 => {
                let Ok(g) = Geodetic::new(f.lat_e7 as f64 * 1e-7, f.lon_e7 as f64 * 1e-7, f.alt_mm as f64 * 1e-3)
                else {
                    continue;
                };
                let hdop = if f.hdop_e2 > 0 { f.hdop_e2 as f64 * 0.01 } else { 1.0 };
                let sigma_h = hdop * uere;
                // A 2D fix's height is a guess.
                let sigma_v = if f.mode >= 3 { 1.5 * sigma_h } else { 1e3 };
                fixes.push(Fix { t: log::seconds(f.t_us), enu: frame.geodetic_to_enu(&g), sigma_h, sigma_v });
            }
            Record::VehicleSpeed(s) => speeds.push((log::seconds(s.t_us), s.speed_mm_s as f64 * 1e-3)),
            _ => {}
        }
    }
    let by_time = |a: &f64, b: &f64| a.total_cmp(b);
    vo.sort_by(|a, b| by_time(&a.t, &b.t));
    vo.dedup_by(|a, b| a.t <= b.t);
    fixes.sort_by(|a, b| by_time(&a.t, &b.t));
    speeds.sort_by(|a, b| by_time(&a.0, &b.0));
    speeds.dedup_by(|a, b| a.0 <= b.0);
    // Dead-reckoned poses (gyro + wheels) with the bias the drive found in the end.
    dead_reckoned.sort_by(by_time);
    bias.sort_by(|a, b| by_time(&a.0, &b.0));
    for sample in vo.iter_mut() {
        sample.reckoned = dead_reckoned.binary_search_by(|t| by_time(t, &sample.t)).is_ok();
    }
    let axis = |a: usize| -> Vec<(f64, f64)> { bias.iter().map(|(t, b)| (*t, b[a] as f64 * 1e-7)).collect() };
    let forward_axis = reckon::with_final_forward_axis(&mut vo, camera_to_body);
    let heading_corrected = reckon::with_final_bias(&mut vo, &axis(2));
    let tilt_corrected = reckon::with_final_tilt_bias(&mut vo, &axis(0), &axis(1), camera_to_body);
    let grade = reckon::with_grade(&mut vo, &fixes, camera_to_body);
    let reckoning = vo.iter().any(|s| s.reckoned).then_some(ReckoningReport {
        heading_corrected_max_deg: heading_corrected.to_degrees(),
        tilt_corrected_max_deg: tilt_corrected.to_degrees(),
        camera_turned_deg: forward_axis.map(f64::to_degrees),
        pitch_offset_deg: grade.map(|g| g.pitch_offset.to_degrees()),
        grade_baseline_m: grade.map(|g| g.baseline_m),
        static_objects_turned_deg: None,
    });
    Drive { vo, fixes, speeds, reckoning }
}

/// The anchors of a file in the log's frame, with those refused while reading.
fn anchors_in(file: &anchors::AnchorFile, frame: &LocalFrame) -> Vec<Anchor> {
    file.anchors
        .iter()
        .map(|a| Anchor {
            at: match a.at {
                AnchorForm::Time(t) => AnchorAt::Time(t),
                AnchorForm::VoPoint(x) => AnchorAt::VoPoint(x),
            },
            enu: frame.geodetic_to_enu(&a.position),
            sigma: a.sigma,
        })
        .collect()
}

/// Finish a log that has been read. `anchor_file` and `map` are optional inputs.
pub fn finish(
    log: &LogContents,
    name: &str,
    anchor_file: Option<(&str, &anchors::AnchorFile)>,
    map: Option<&[u8]>,
    mount: CameraMount,
    settings: Settings,
    uere: f64,
) -> Result<Finished> {
    let header = log
        .header
        .ok_or_else(|| Error::invalid(format!("{name}: the header is damaged: no ENU origin to finish in")))?;
    let frame =
        log::frame(&header).ok_or_else(|| Error::invalid(format!("{name}: the header's origin is not a position")))?;
    let drive = drive(log, &frame, uere, &mount.rotation());
    let anchors = anchor_file.map(|(_, f)| anchors_in(f, &frame)).unwrap_or_default();
    let calibrated = calibrate_mount(&drive.vo, mount);
    let nominal_yaw = mount.roll_pitch_yaw[2];
    let mount = calibrated.mount;
    let lever = mount.rotation().transpose() * Vector3::from(mount.position);
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

    // The finished ego: every VO pose's camera through the solution and the mount, its
    // planar track smoothed (the VO's frame-to-frame noise is not the car's motion).
    // Each session smoothed on its own (a constant-velocity smoother across a gap would
    // turn the two sessions' disagreement into a velocity), then the sessions joined.
    let mut planar_poses: Vec<PlanarPose> = Vec::new();
    // Where each session begins in `planar_poses`, and its wheel factor.
    let mut starts: Vec<(usize, f64)> = Vec::new();
    for solved in &sessions {
        let vo = &drive.vo[solved.range.clone()];
        let bodies: Vec<(f64, Pose)> = vo
            .iter()
            .filter_map(|s| {
                let (c, rotation) = solved.solution.camera_at(vo, s.t)?;
                Some((s.t, mount.body_pose(&Pose { rotation, translation: c })))
            })
            .collect();
        let mut planar: Vec<tracks::Sample> = bodies
            .iter()
            .map(|(t, b)| tracks::Sample {
                t: *t,
                x: b.translation.x,
                y: b.translation.y,
                speed: wheel_speed_at(&drive.speeds, *t).map(|v| (v * solved.solution.wheel_factor, WHEEL_SPEED_SIGMA)),
                ..tracks::Sample::default()
            })
            .collect();
        let velocity = starting_velocity(&planar);
        tracks::smooth_planar(&mut planar, velocity, EGO_SMOOTHING.0, EGO_SMOOTHING.1);
        starts.push((planar_poses.len(), solved.solution.wheel_factor));
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
    join_sessions(&mut planar_poses, &starts, &drive.speeds);
    let mut ego: BTreeMap<i64, EgoPose> = BTreeMap::new();
    let bridged = bridge_gaps(&planar_poses, frame_interval(&drive.vo), &drive.speeds);
    let bridged_s: f64 = bridged.iter().map(|g| g.seconds).sum();
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
    let online: BTreeMap<i64, EgoPose> =
        log.records.iter().filter_map(|r| if let Record::EgoPose(p) = r { Some((p.t_us, *p)) } else { None }).collect();
    let batches: Vec<_> =
        log.records.iter().filter_map(|r| if let Record::Tracks3d(b) = r { Some(b.clone()) } else { None }).collect();
    let ego_at = |poses: &BTreeMap<i64, EgoPose>, t: i64| {
        poses
            .get(&t)
            .map(|p| [p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3, p.z_mm as f64 * 1e-3, p.yaw_e4 as f64 * 1e-4])
    };
    // The device placed its detections through the mount it had then; the finished ego
    // goes with the mount calibrated over the whole drive.
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
    let static_yaw = drive.reckoning.and_then(|_| tracks::static_yaw(&batches, &online_turned, &|t| ego_at(&ego, t)));
    let turn = static_yaw.unwrap_or(0.0);
    let mut objects_mount = mount;
    objects_mount.roll_pitch_yaw[2] += turn;
    // The log's mount is the one the objects were placed with.
    let calibrated = MountEstimate { mount: objects_mount, ..calibrated };
    let mut tracks = tracks::finish_tracks(&batches, &|t| online_turned(t, turn), &|t| ego_at(&ego, t));
    let raw: Vec<_> =
        log.records.iter().filter_map(|r| if let Record::Detection3d(d) = r { Some(*d) } else { None }).collect();
    let (raw_batches, raw_stats) = raw::track_raw(&raw, &ego, &objects_mount);
    // Already placed through the finished ego: re-expressed onto itself, then smoothed and
    // merged as the device's tracks are.
    let raw_tracks = tracks::finish_tracks(&raw_batches, &|t| ego_at(&ego, t), &|t| ego_at(&ego, t));
    let raw_ghosts = raw_tracks.stats.ghosts;
    tracks.batches.extend(raw_tracks.batches);
    tracks.covariances.extend(raw_tracks.covariances);

    let mut records: Vec<Record> = log
        .records
        .iter()
        .filter(|r| {
            !matches!(
                r,
                Record::EgoPose(_)
                    | Record::AnchorEstimate(_)
                    | Record::MountEstimate(_)
                    | Record::Tracks3d(_)
                    | Record::TrackCovariance(_)
                    | Record::Verification(_)
            )
        })
        .cloned()
        .collect();
    records.extend(ego.values().map(|p| Record::EgoPose(*p)));
    records.extend(tracks.batches.into_iter().map(Record::Tracks3d));
    records.extend(tracks.covariances.into_iter().map(Record::TrackCovariance));
    if let Some(first) = drive.vo.first() {
        records.push(Record::MountEstimate(mount_record(quantise(first.t, 1e-6), &calibrated)));
    }
    for solved in &sessions {
        let (vo, solution) = (&drive.vo[solved.range.clone()], &solved.solution);
        let mut last_estimate = f64::NEG_INFINITY;
        for k in 0..solution.keyframe_t.len().saturating_sub(1) {
            let t = solution.keyframe_t[k];
            if t - last_estimate < 1.0 {
                continue;
            }
            last_estimate = t;
            records.push(Record::AnchorEstimate(anchor_record(t, &solution.sim3(vo, k), solution, used_anchors)));
        }
    }
    records.sort_by_key(Record::t_us);

    let verification = match map {
        Some(bytes) => Some(windows::verify_finished(log, &records, name, bytes)?),
        None => None,
    };
    if let Some(v) = &verification {
        records.extend(v.records.iter().cloned());
        records.sort_by_key(Record::t_us);
    }

    let fixes_used =
        (0..drive.fixes.len()).filter(|&k| sessions.iter().any(|s| s.solution.fix_used.get(k) == Some(&true))).count();
    // The longest session speaks for the drive's scale, latency and wheel factor.
    let main = sessions.iter().max_by_key(|s| s.range.len()).map(|s| &s.solution).unwrap_or_else(|| unreachable!());
    let utc_latency_s = clock::latency_from_motion(&log.records, &ego).unwrap_or(main.latency_s);
    let utc_shift_us = clock::utc_onto_the_fixes(&mut records, utc_latency_s);
    let [_, pitch, yaw] = calibrated.mount.roll_pitch_yaw;
    let mount_text = format!(
        "camera mount yaw {:+.2}° pitch {:+.2}° ({} from {} straight-driving frames)",
        yaw.to_degrees(),
        pitch.to_degrees(),
        if calibrated.calibrated { "calibrated" } else { "not calibrated: the given mount weighs in" },
        calibrated.samples
    );
    let bridge_text = if bridged.is_empty() {
        String::new()
    } else {
        format!("; the ego bridged across {} VO gaps ({bridged_s:.1} s, interpolated)", bridged.len())
    };
    let sessions_text = match (sessions.len(), unsolved.len()) {
        (1, 0) => String::new(),
        (n, 0) => format!("; {n} VO sessions, each anchored on its own{bridge_text}"),
        (n, u) => format!(
            "; {n} VO sessions anchored on their own, {u} could not be ({} poses without a finished pose)",
            unsolved.iter().map(|u| u.1).sum::<usize>()
        ),
    };
    let clock_text = if utc_shift_us == 0 {
        String::new()
    } else {
        format!("; the log's UTC moved {:+.0} ms (the receiver's latency)", utc_shift_us as f64 * 1e-3)
    };
    let anchor_text = match anchor_file {
        Some((path, _)) => format!("anchors {path} ({used_anchors} used, {} refused)", refused.len()),
        None => "no external anchors".to_owned(),
    };
    let damage = if log.stats.damaged > 0 {
        format!(
            "; {} damaged stretches ({} bytes) of the source were lost",
            log.damage.len(),
            log.damage.iter().map(|d| d.1).sum::<u64>()
        )
    } else {
        String::new()
    };
    let first_t = records.first().map_or(0, Record::t_us);
    let summary = format!(
        "dash2sim finish: from {name} ({} records) with {} VO poses, GNSS {fixes_used} of {} fixes, {} speed samples, {anchor_text}; scale {:.6} ± {:.4} %, latency {:.0} ms, wheel factor {:.4}{damage}",
        log.records.len(),
        drive.vo.len(),
        drive.fixes.len(),
        drive.speeds.len(),
        mean_scale(main),
        100.0 * main.scale_sigma,
        1000.0 * main.latency_s,
        main.wheel_factor,
    );
    // A log is in UTC from its first clock offset on; a finished log is in UTC throughout,
    // so that record goes first (nothing before it to move) and the event next.
    if let Some(k) = records.iter().position(|r| matches!(r, Record::ClockOffset(_))) {
        let offset = records.remove(k);
        records.insert(0, offset);
        records.insert(1, event(first_t, 2, &summary));
        records.insert(2, event(first_t, 2, &format!("{mount_text}{sessions_text}{clock_text}")));
    } else {
        records.insert(0, event(first_t, 2, &summary));
        records.insert(1, event(first_t, 2, &format!("{mount_text}{sessions_text}{clock_text}")));
    }

    let report = FinishReport {
        log: name.to_owned(),
        records: records.len(),
        vo_poses: drive.vo.len(),
        ego_poses: ego.len(),
        ego_bridged: Bridged { gaps: bridged.len(), seconds: bridged_s },
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
            .map(|r| ReckoningReport { static_objects_turned_deg: static_yaw.map(f64::to_degrees), ..r }),
        gnss: GnssReport { fixes: drive.fixes.len(), used: fixes_used, rejected: drive.fixes.len() - fixes_used },
        speed_samples: drive.speeds.len(),
        anchors: AnchorsReport {
            file: anchor_file.map(|(p, _)| p.to_owned()),
            used: used_anchors,
            refused: refused.iter().map(|(line, why)| RefusedAnchor { line: *line, reason: why.clone() }).collect(),
        },
        tracks: TracksReport {
            states: tracks.stats.states,
            unplaced: tracks.stats.unplaced,
            smoothed: tracks.stats.smoothed,
            static_merged: tracks.stats.merged_static,
            ghosts_dropped: tracks.stats.ghosts + raw_ghosts,
            raw_detections: raw_stats.detections,
            raw_placed: raw_stats.placed,
            raw_track_states: raw_stats.track_states,
        },
        damage: DamageReport { stretches: log.damage.len(), bytes: log.damage.iter().map(|d| d.1).sum::<u64>() },
        verification: verification.as_ref().map(|v| v.report.clone()),
    };
    Ok(Finished { records, report })
}

fn anchoring_report(solution: &Solution) -> AnchoringReport {
    AnchoringReport {
        keyframes: solution.keyframe_t.len(),
        iterations: solution.iterations,
        scale: mean_scale(solution),
        scale_sigma_relative: solution.scale_sigma,
        position_sigma_m: solution.position_sigma_m,
        sigma0_squared: solution.sigma0_sq,
        gnss_latency_s: solution.latency_s,
        wheel_factor: solution.wheel_factor,
        heading_drift_deg_s: solution.heading_drift.to_degrees(),
        gnss_rms_m: solution.gnss_rms_m,
    }
}

/// A finished ego pose in the plane, with its height and smoothed velocity.
#[derive(Clone, Copy, Debug)]
struct PlanarPose {
    t: f64,
    x: f64,
    y: f64,
    z: f64,
    heading: f64,
    vx: f64,
    vy: f64,
    /// Horizontal 1-σ (DRMS), m.
    sigma: f64,
}

/// Ego poses made for a gap in the VO.
struct Bridge {
    seconds: f64,
    poses: Vec<PlanarPose>,
}

/// The speed error (m/s) a bridge's σ assumes: the ends' velocities are smoothed VO
/// velocities, good to a few per cent at town speeds.
const BRIDGE_SPEED_SIGMA: f64 = 0.5;
/// Longest gap in the VO the finished ego is carried across, s.
const MAX_BRIDGE_S: f64 = 5.0;
/// How far from a gap the two sessions' disagreement is spread, s.
const JOIN_RAMP_S: f64 = 5.0;

/// Two sessions solved apart meet with the errors of their ends, independent of each other:
/// across the gap the car went on as the wheels say, so the second session's first pose
/// should be the first session's last one moved on by the wheels' distance over the gap
/// (the wheel factor of the two sessions applied; without speeds, the mean of their
/// velocities times the gap) along their mean direction. Each end is moved by half of the
/// disagreement (the mean of two independent estimates), the shift easing out to nothing
/// [`JOIN_RAMP_S`] into each session, where its own GNSS and anchors hold it: a smoothstep,
/// so that the shift adds no step in velocity, which the comfort metrics would read as a
/// jerk. `starts` are the indices where sessions begin, with their wheel factors.
fn join_sessions(poses: &mut [PlanarPose], starts: &[(usize, f64)], speeds: &[(f64, f64)]) {
    let n = poses.len();
    for (k, &(b, factor)) in starts.iter().enumerate().filter(|(_, (b, _))| *b > 0 && *b < n) {
        let (end, start) = (poses[b - 1], poses[b]);
        let gap = start.t - end.t;
        if !(gap > 0.0 && gap <= MAX_BRIDGE_S) {
            continue;
        }
        let (mean_vx, mean_vy) = (0.5 * (end.vx + start.vx), 0.5 * (end.vy + start.vy));
        let factor = k.checked_sub(1).and_then(|j| starts.get(j)).map_or(factor, |&(_, f)| 0.5 * (f + factor));
        let travelled = solve::wheel_distance(speeds, end.t, start.t)
            .map(|d| d * factor)
            .filter(|d| d.is_finite())
            .unwrap_or_else(|| mean_vx.hypot(mean_vy) * gap);
        // Along the ends' mean direction; nowhere when the car stands.
        let speed = mean_vx.hypot(mean_vy);
        let (ux, uy) = if speed > 0.0 { (mean_vx / speed, mean_vy / speed) } else { (0.0, 0.0) };
        let predicted_x = end.x + travelled * ux;
        let predicted_y = end.y + travelled * uy;
        let (dx, dy) = (0.5 * (start.x - predicted_x), 0.5 * (start.y - predicted_y));
        if !(dx.is_finite() && dy.is_finite()) {
            continue;
        }
        let weight = |from_gap: f64| {
            let x = (from_gap / JOIN_RAMP_S).clamp(0.0, 1.0);
            1.0 - x * x * (3.0 - 2.0 * x)
        };
        for p in poses[..b].iter_mut().rev().take_while(|p| end.t - p.t < JOIN_RAMP_S) {
            let w = weight(end.t - p.t);
            (p.x, p.y) = (p.x + w * dx, p.y + w * dy);
            // The disagreement is an error of one session or the other: it counts in the σ.
            p.sigma = p.sigma.hypot(w * dx.hypot(dy));
        }
        for p in poses[b..].iter_mut().take_while(|p| p.t - start.t < JOIN_RAMP_S) {
            let w = weight(p.t - start.t);
            (p.x, p.y) = (p.x - w * dx, p.y - w * dy);
            p.sigma = p.sigma.hypot(w * dx.hypot(dy));
        }
    }
}

/// A session's velocity at its first pose, for the smoother to start from: the chord over
/// its first [`STARTING_CHORD_S`] (a smoother started at rest would pull the session's first
/// second towards a standstill the car never made).
fn starting_velocity(planar: &[tracks::Sample]) -> (f64, f64) {
    let Some(first) = planar.first() else { return (0.0, 0.0) };
    match planar.iter().find(|s| s.t - first.t >= STARTING_CHORD_S) {
        Some(s) => ((s.x - first.x) / (s.t - first.t), (s.y - first.y) / (s.t - first.t)),
        None => (0.0, 0.0),
    }
}

/// The span whose chord gives a session's starting velocity, s.
const STARTING_CHORD_S: f64 = 0.5;

/// The VO's frame interval: the median spacing of its poses, s.
fn frame_interval(vo: &[VoSample]) -> f64 {
    let gaps: Vec<f64> = vo.windows(2).map(|w| w[1].t - w[0].t).filter(|d| *d > 0.0).collect();
    let m = median(gaps);
    if m.is_finite() {
        m
    } else {
        0.1
    }
}

/// Where the VO lost track (a re-initialisation, a stretch of dropped frames) the finished
/// ego has no pose, and a hole reads as a stop and a start to the metrics. Gaps up to
/// [`MAX_BRIDGE_S`] are filled at the frame rate along a cubic Hermite curve between the
/// smoothed poses at their two ends, leaving each along its heading. Where the wheels cover
/// the gap the curve is laid out by distance and each pose put where the odometer says the
/// car was (a car that braked in the gap brakes there too); without them, by time with the
/// ends' velocities. The heading and the height go linearly.
fn bridge_gaps(poses: &[PlanarPose], interval: f64, speeds: &[(f64, f64)]) -> Vec<Bridge> {
    let mut out = Vec::new();
    for w in poses.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        let gap = b.t - a.t;
        if !(gap > 1.5 * interval && gap <= MAX_BRIDGE_S) {
            continue;
        }
        let steps = (gap / interval).round().max(2.0) as usize;
        let turn = dash2sim_core::track3d::wrap_angle(b.heading - a.heading);
        // By distance: tangents along the ends' headings as long as the chord, and each
        // pose at the odometer's fraction of the gap's distance.
        let chord = (b.x - a.x).hypot(b.y - a.y);
        let (speed_a, speed_b) = (a.vx.hypot(a.vy), b.vx.hypot(b.vy));
        let by_distance = solve::wheel_distance(speeds, a.t, b.t)
            .filter(|&d| d > 0.5 && chord > 0.5 && speed_a > 0.0 && speed_b > 0.0)
            .map(|d| {
                let tangents =
                    (a.vx * chord / speed_a, a.vy * chord / speed_a, b.vx * chord / speed_b, b.vy * chord / speed_b);
                (d, tangents)
            });
        let poses = (1..steps)
            .map(|k| {
                let u = k as f64 / steps as f64;
                let t = a.t + u * gap;
                let (s, (ax, ay, bx, by)) = match by_distance {
                    Some((d, tangents)) => {
                        let s = solve::wheel_distance(speeds, a.t, t).map_or(u, |part| (part / d).clamp(0.0, 1.0));
                        (s, tangents)
                    }
                    None => (u, (gap * a.vx, gap * a.vy, gap * b.vx, gap * b.vy)),
                };
                let (h00, h10, h01, h11) = (
                    2.0 * s.powi(3) - 3.0 * s * s + 1.0,
                    s.powi(3) - 2.0 * s * s + s,
                    -2.0 * s.powi(3) + 3.0 * s * s,
                    s.powi(3) - s * s,
                );
                PlanarPose {
                    t,
                    x: h00 * a.x + h10 * ax + h01 * b.x + h11 * bx,
                    y: h00 * a.y + h10 * ay + h01 * b.y + h11 * by,
                    z: a.z + u * (b.z - a.z),
                    heading: dash2sim_core::track3d::wrap_angle(a.heading + u * turn),
                    vx: f64::NAN,
                    vy: f64::NAN,
                    // The ends' σ, and what a curve through a gap may miss: the speed's
                    // assumed error times the time to the nearer end.
                    sigma: a.sigma.max(b.sigma).hypot(BRIDGE_SPEED_SIGMA * gap * u.min(1.0 - u)),
                }
            })
            .collect();
        out.push(Bridge { seconds: gap, poses });
    }
    out
}

/// A VO session of a drive with several whose heading's 1-σ is above this is not anchored
/// on its own (rad): a session of a few frames, its fixes a few metres apart, points
/// anywhere within 10–20°, where one of seconds is known to a degree.
pub const MAX_SESSION_HEADING_SIGMA_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// Every VO session solved: the solutions, the sessions that could not be, and per anchor
/// why no session used it (`None`: used).
struct Solved {
    sessions: Vec<SessionSolution>,
    unsolved: Vec<(u32, usize, String)>,
    verdicts: Vec<Option<String>>,
}

fn solve_sessions(drive: &Drive, anchors: &[Anchor], lever: Vector3<f64>, settings: Settings) -> Solved {
    let single_session = drive.vo.first().zip(drive.vo.last()).is_none_or(|(a, b)| a.session == b.session);
    let mut verdicts: Vec<Option<String>> = vec![Some("outside the VO poses' time span".to_owned()); anchors.len()];
    let (mut sessions, mut unsolved) = (Vec::new(), Vec::new());
    for range in session_ranges(&drive.vo) {
        let vo = &drive.vo[range.clone()];
        let session = vo[0].session;
        let inputs = Inputs { vo, fixes: &drive.fixes, speeds: &drive.speeds, anchors, lever };
        match solve_session(inputs, settings, &drive.fixes, single_session) {
            // A session too short to fix which way it points is not anchored on its own: its
            // heading would be a guess, and the bridge from it into the next session a turn the
            // car never made. Its poses stay without a finished pose (another session's
            // bridge may cover them).
            Ok((solution, session_verdicts))
                if !single_session && solution.heading_sigma_rad > MAX_SESSION_HEADING_SIGMA_RAD =>
            {
                let why = format!(
                    "its heading is not determined ({:.1}° 1-σ over {:.1} s of VO; at most {:.0}°)",
                    solution.heading_sigma_rad.to_degrees(),
                    vo[vo.len() - 1].t - vo[0].t,
                    MAX_SESSION_HEADING_SIGMA_RAD.to_degrees()
                );
                for (verdict, mine) in verdicts.iter_mut().zip(session_verdicts) {
                    if matches!(mine, AnchorVerdict::Used) && verdict.is_some() {
                        *verdict = Some(format!("in VO session {session}, not anchored: {why}"));
                    }
                }
                unsolved.push((session, vo.len(), why));
            }
            Ok((solution, session_verdicts)) => {
                for (verdict, mine) in verdicts.iter_mut().zip(session_verdicts) {
                    match mine {
                        AnchorVerdict::Used => *verdict = None,
                        AnchorVerdict::Refused(why) if verdict.is_some() => *verdict = Some(why),
                        AnchorVerdict::Refused(_) | AnchorVerdict::Elsewhere => {}
                    }
                }
                sessions.push(SessionSolution { session, range, solution });
            }
            Err(e) => unsolved.push((session, vo.len(), e.to_string())),
        }
    }
    Solved { sessions, unsolved, verdicts }
}

/// One VO session's re-anchoring: its poses (a range of the drive's) and its solution.
struct SessionSolution {
    session: u32,
    range: std::ops::Range<usize>,
    solution: Solution,
}

/// The runs of consecutive poses of one VO session.
fn session_ranges(vo: &[VoSample]) -> Vec<std::ops::Range<usize>> {
    let mut out = Vec::new();
    let mut start = 0;
    for k in 1..=vo.len() {
        if k == vo.len() || vo[k].session != vo[start].session {
            out.push(start..k);
            start = k;
        }
    }
    out
}

/// What one session made of an external anchor.
enum AnchorVerdict {
    /// Used in the solution.
    Used,
    /// Refused, and why.
    Refused(String),
    /// Not this session's: outside its time span.
    Elsewhere,
}

/// Re-anchor one VO session. Anchors are first checked against the session anchored
/// without them: one far from it (a wrong place-recognition match) is refused before it can
/// pull. A VO-point anchor names a point of one VO frame, which a re-initialisation
/// replaces: it is used only in a log of one session.
fn solve_session(
    inputs: Inputs<'_>,
    settings: Settings,
    fixes: &[Fix],
    vo_points_valid: bool,
) -> Result<(Solution, Vec<AnchorVerdict>), solve::SolveError> {
    let anchors = inputs.anchors;
    let (first, last) = (inputs.vo[0].t, inputs.vo[inputs.vo.len() - 1].t);
    let mut verdicts: Vec<AnchorVerdict> = anchors
        .iter()
        .map(|a| match a.at {
            AnchorAt::Time(t) if (first..=last).contains(&t) => AnchorVerdict::Used,
            AnchorAt::VoPoint(_) if vo_points_valid => AnchorVerdict::Used,
            AnchorAt::VoPoint(_) => AnchorVerdict::Refused(
                "a VO point, but the VO re-initialised during the drive (give the anchor's time instead)".to_owned(),
            ),
            AnchorAt::Time(_) => AnchorVerdict::Elsewhere,
        })
        .collect();
    let candidate = |v: &AnchorVerdict| matches!(v, AnchorVerdict::Used);
    let mut latency_s = settings.latency_prior.0;
    if !fixes.is_empty() && verdicts.iter().any(candidate) {
        let without = solve::solve(inputs, settings, &vec![false; anchors.len()])?;
        latency_s = without.latency_s;
        let median_sigma = median(fixes.iter().map(|f| f.sigma_h).collect());
        let position_sigma = without.position_sigma_m.max(median_sigma);
        for (a, verdict) in anchors.iter().zip(verdicts.iter_mut()).filter(|(_, v)| candidate(v)) {
            let limit = settings.gate * (a.sigma * a.sigma + position_sigma * position_sigma).sqrt();
            match without.anchor_residual(&inputs, a) {
                Some(r) if r > limit => {
                    *verdict =
                        AnchorVerdict::Refused(format!("{r:.1} m from the drive anchored by GNSS (limit {limit:.1} m)"))
                }
                None => *verdict = AnchorVerdict::Elsewhere,
                Some(_) => {}
            }
        }
    }
    let enabled: Vec<bool> = verdicts.iter().map(candidate).collect();
    let settings = if enabled.iter().any(|&on| on) {
        let (scale_walk, rotation_walk) = walk::anchored_walk(inputs, settings, &enabled, latency_s)?;
        Settings { scale_walk, rotation_walk, ..settings }
    } else {
        settings
    };
    let solution = solve::solve(inputs, settings, &enabled)?;
    for ((verdict, &on), &used) in verdicts.iter_mut().zip(&enabled).zip(&solution.anchor_used) {
        if on && !used {
            *verdict = AnchorVerdict::Refused(format!("residual beyond {}σ in the solution", settings.gate));
        }
    }
    Ok((solution, verdicts))
}

/// The camera mount over the whole drive: the device's calibration run on every VO pose,
/// from the mount given to `finish` (the device's nominal one).
fn calibrate_mount(vo: &[VoSample], nominal: CameraMount) -> MountEstimate {
    let mut calibration = MountCalibration::new(nominal, CalibrationConfig::default());
    for s in vo {
        let pose = Pose { rotation: s.rotation, translation: s.position };
        calibration.push(s.t, s.session, &pose);
    }
    calibration.estimate()
}

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

/// Finish the log at `args.log` into `args.output` (the command line and the Python
/// package's `finish`): the report (`--json`) with the output's path and size.
pub fn finish_file(args: &FinishRequest) -> Result<FinishedFile> {
    if !(args.keyframe.is_finite() && (0.05..=10.0).contains(&args.keyframe)) {
        return Err(Error::invalid(format!("--keyframe {} must be between 0.05 and 10 s", args.keyframe)));
    }
    let (mount, uere) = args.device.parse()?;
    let log = log::read(&args.log).map_err(Error::other)?;
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
    let finished =
        finish(&log, &name, anchor_name.as_deref().zip(anchor_file.as_ref()), map.as_deref(), mount, settings, uere)?;
    let header = log.header.unwrap_or(Header { device_id: [0; 16], origin: [0; 3] });
    let bytes = log::import::encode_in_order(&header, &finished.records)?;
    std::fs::write(&args.output, &bytes).map_err(|e| Error::file(&args.output, e))?;
    Ok(FinishedFile { report: finished.report, output: args.output.display().to_string(), bytes: bytes.len() })
}

#[cfg(test)]
mod tests {
    use super::*;

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
