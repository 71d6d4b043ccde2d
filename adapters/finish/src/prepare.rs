//! What the solve of a log starts from ([`Prepared`]): the log's drive as the solver reads
//! it (VO poses, fixes with their σ, wheel speeds, the dead-reckoned poses redone with the
//! drive's final bias), in the log's ENU frame; the anchors in that frame; the camera mount
//! as calibrated from the VO, and the rear axle in the camera frame.

use dash2sim_core::binlog::{Record, FRAME_DEAD_RECKONED};
use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::{Matrix3, Rotation3, Vector3};
use dash2sim_core::pipeline::{CalibrationConfig, CameraMount, MountCalibration, MountEstimate};
use dash2sim_core::sim3::Pose;
use dash2sim_linux::log;
use dash2sim_linux::{Error, Result};

use crate::anchors::{self, AnchorForm};
use crate::reckon;
use crate::solve::{Anchor, AnchorAt, Fix, VoSample};
use crate::{ReckoningReport, Source};

/// A log's drive as the solver reads it, in the log's ENU frame.
pub(crate) struct Drive {
    pub(crate) vo: Vec<VoSample>,
    pub(crate) fixes: Vec<Fix>,
    pub(crate) speeds: Vec<(f64, f64)>,
    /// What redoing the dead-reckoned poses found, when there were any.
    pub(crate) reckoning: Option<ReckoningReport>,
}

/// `camera_to_body`: the mount the device reckoned with (its poses are the attitude
/// through it).
fn drive(log: &Source, frame: &LocalFrame, uere: f64, camera_to_body: &Matrix3<f64>) -> Drive {
    let (mut vo, mut fixes, mut speeds) = (Vec::new(), Vec::new(), Vec::new());
    let (mut dead_reckoned, mut bias) = (Vec::new(), Vec::new());
    for r in log.records.iter() {
        match &r {
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

/// What the solve of a log starts from: its drive in the log's ENU frame, the anchors, the
/// camera mount as calibrated from the VO, and the rear axle in the camera frame.
pub(crate) struct Prepared {
    pub(crate) drive: Drive,
    pub(crate) anchors: Vec<Anchor>,
    pub(crate) calibrated: MountEstimate,
    pub(crate) lever: Vector3<f64>,
}

pub(crate) fn prepare(
    log: &Source,
    name: &str,
    anchor_file: Option<(&str, &anchors::AnchorFile)>,
    mount: CameraMount,
    uere: f64,
) -> Result<Prepared> {
    let header = log
        .header
        .ok_or_else(|| Error::invalid(format!("{name}: the header is damaged: no ENU origin to finish in")))?;
    let frame =
        log::frame(&header).ok_or_else(|| Error::invalid(format!("{name}: the header's origin is not a position")))?;
    let drive = drive(log, &frame, uere, &mount.rotation());
    let anchors = anchor_file.map(|(_, f)| anchors_in(f, &frame)).unwrap_or_default();
    let calibrated = calibrate_mount(&drive.vo, mount);
    let lever = calibrated.mount.rotation().transpose() * Vector3::from(calibrated.mount.position);
    Ok(Prepared { drive, anchors, calibrated, lever })
}

fn calibrate_mount(vo: &[VoSample], nominal: CameraMount) -> MountEstimate {
    let mut calibration = MountCalibration::new(nominal, CalibrationConfig::default());
    for s in vo {
        let pose = Pose { rotation: s.rotation, translation: s.position };
        calibration.push(s.t, s.session, &pose);
    }
    calibration.estimate()
}
