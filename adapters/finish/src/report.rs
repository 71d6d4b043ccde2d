//! What `finish` reports (`dash2sim finish --json`, the Python package's `finish`): the
//! finished records and, beside them, what was solved, used, refused and kept.

use dash2sim_linux::log::RecordStore;
use serde::Serialize;

use super::solve::Solution;
use super::{mean_scale, windows};

/// What finishing produced, for the report and the tests.
#[derive(Debug)]
pub struct Finished {
    /// The finished log's records, in file order.
    pub records: RecordStore,
    /// The report (`--json`).
    pub report: FinishReport,
}

/// One VO session's problem ([`crate::factor_graphs`], `dash2sim finish --factor-graph`).
#[derive(Clone, Debug, Serialize)]
pub struct SessionGraph {
    /// The VO session.
    pub session: u32,
    /// Its problem.
    #[serde(flatten)]
    pub graph: crate::solve::FactorGraph,
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
    /// How late the vehicle bus reported the wheels' speed, s, as the finished ego's
    /// smoother takes it ([`crate::clock::wheel_latency`]); none where the drive did not
    /// change speed enough to tell.
    pub wheel_latency_s: Option<f64>,
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

/// The dead-reckoned poses redone with what the whole drive shows ([`super::reckon`]).
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
    /// by the static objects it saw ([`super::tracks::static_yaw`]), degrees; `None` with too few
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

pub(super) fn anchoring_report(solution: &Solution) -> AnchoringReport {
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

/// The two events a finished log opens with, in words, from its report: what it was
/// finished from and how (`source_records`: the source log's), and the mount, the VO
/// sessions and the clock (`utc_shift_us`: how far the log's UTC moved).
pub(super) fn events(report: &FinishReport, source_records: usize, utc_shift_us: i64) -> [String; 2] {
    let anchoring = &report.anchoring;
    let anchor_text = match &report.anchors.file {
        Some(path) => {
            format!("anchors {path} ({} used, {} refused)", report.anchors.used, report.anchors.refused.len())
        }
        None => "no external anchors".to_owned(),
    };
    let damage = if report.damage.stretches > 0 {
        format!(
            "; {} damaged stretches ({} bytes) of the source were lost",
            report.damage.stretches, report.damage.bytes
        )
    } else {
        String::new()
    };
    let summary = format!(
        "dash2sim finish: from {} ({source_records} records) with {} VO poses, GNSS {} of {} fixes, {} speed samples, {anchor_text}; scale {:.6} ± {:.4} %, latency {:.0} ms, wheel factor {:.4}{damage}",
        report.log,
        report.vo_poses,
        report.gnss.used,
        report.gnss.fixes,
        report.speed_samples,
        anchoring.scale,
        100.0 * anchoring.scale_sigma_relative,
        1000.0 * anchoring.gnss_latency_s,
        anchoring.wheel_factor,
    );
    let mount = &report.mount;
    let mount_text = format!(
        "camera mount yaw {:+.2}° pitch {:+.2}° ({} from {} straight-driving frames)",
        mount.yaw_deg,
        mount.pitch_deg,
        if mount.calibrated { "calibrated" } else { "not calibrated: the given mount weighs in" },
        mount.samples
    );
    let bridged = &report.ego_bridged;
    let bridge_text = if bridged.gaps == 0 {
        String::new()
    } else {
        format!("; the ego bridged across {} VO gaps ({:.1} s, interpolated)", bridged.gaps, bridged.seconds)
    };
    let sessions_text = match (report.sessions.len(), report.unsolved_sessions.len()) {
        (1, 0) => String::new(),
        (n, 0) => format!("; {n} VO sessions, each anchored on its own{bridge_text}"),
        (n, u) => format!(
            "; {n} VO sessions anchored on their own, {u} could not be ({} poses without a finished pose)",
            report.unsolved_sessions.iter().map(|s| s.vo_poses).sum::<usize>()
        ),
    };
    let clock_text = if utc_shift_us == 0 {
        String::new()
    } else {
        format!("; the log's UTC moved {:+.0} ms (the receiver's latency)", utc_shift_us as f64 * 1e-3)
    };
    [summary, format!("{mount_text}{sessions_text}{clock_text}")]
}
