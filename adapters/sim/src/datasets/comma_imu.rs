//! comma2k19's minute with nothing simulated: the device's real IMU (gyro and
//! accelerometer at ~104 Hz, `processed_log/IMU/`, axes forward, right, down), the real
//! Toyota wheels (0xB4 SPEED on the CAN capture) and a real receiver's fixes — the u-blox
//! at 10 Hz, or the phone-grade Qualcomm (`qcom`) at 0.5 Hz — recorded with gyro + wheels
//! as the relative motion (no VO at all), finished, and measured against comma's fused
//! poses.
//!
//! The reference is comma's own offline fusion (GNSS, this IMU and vision): the best
//! estimate of where the car was, not an independent ground truth — its attitude in
//! particular rests on the same accelerometer.

use std::path::Path;

use dash2sim_core::binlog::{Kind, Record};
use dash2sim_core::imu::so3;
use dash2sim_core::nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use super::comma::{self, compare, Compared, UERE};
use super::{device_times, write};
use crate::{Error, Result};
use dash2sim_core::pipeline::RelativeMotion;
use dash2sim_finish::solve::Settings;
use dash2sim_linux::log;
use dash2sim_linux::record::{self, Device, RecordRequest, VoFrame};
use dash2sim_linux::trajectory::{Format, Trajectory};

/// The receiver whose fixes anchor the minute.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Receiver {
    /// The u-blox M8 (10 Hz).
    Ublox,
    /// The phone's Qualcomm receiver (0.5 Hz).
    Qcom,
}

impl Receiver {
    fn csv(self) -> &'static str {
        match self {
            Receiver::Ublox => "expected/live_gnss_ublox.csv",
            Receiver::Qcom => "expected/live_gnss_qcom.csv",
        }
    }

    /// The HDOP its sentences carry: σ = HDOP × 2.78 m is 2.5 m for the u-blox (the
    /// anchoring test's) and 8.3 m for the phone (within the 3–10 m such receivers give).
    fn hdop(self) -> f64 {
        match self {
            Receiver::Ublox => 0.9,
            Receiver::Qcom => 3.0,
        }
    }
}

/// A NumPy array of `f64` (C or Fortran order) as rows of `columns` values.
fn npy_rows(path: &Path, columns: usize) -> Result<Vec<Vec<f64>>> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let file = npyz::NpyFile::new(&bytes[..]).map_err(|e| Error::file(path, e))?;
    let shape: Vec<usize> = file.shape().iter().map(|&d| d as usize).collect();
    let fortran = file.order() == npyz::Order::Fortran;
    let (rows, cols) = match shape[..] {
        [n] => (n, 1),
        [n, m] => (n, m),
        _ => return Err(Error::file(path, format!("shape {shape:?}: expected one or two dimensions"))),
    };
    if cols != columns {
        return Err(Error::file(path, format!("shape {shape:?}: expected {columns} columns")));
    }
    let flat: Vec<f64> = file.into_vec().map_err(|e| Error::file(path, e))?;
    Ok((0..rows)
        .map(|r| (0..cols).map(|c| flat[if fortran { c * rows + r } else { r * cols + c }]).collect())
        .collect())
}

/// The minute's IMU as the `record --imu` CSV: the raw gyro (`gyro_uncalibrated`: no bias
/// removed — the device estimates its own) and the accelerometer, paired by time.
pub fn imu_csv(dir: &Path) -> Result<(String, usize)> {
    let imu = dir.join("b0c9d2329ad1606b_2018-08-02--08-34-47_40/processed_log/IMU");
    let gyro_t = npy_rows(&imu.join("gyro_uncalibrated/t"), 1)?;
    let gyro = npy_rows(&imu.join("gyro_uncalibrated/value"), 3)?;
    let accel_t = npy_rows(&imu.join("accelerometer/t"), 1)?;
    let accel = npy_rows(&imu.join("accelerometer/value"), 3)?;
    let mut csv = format!("{}\n", record::sources::IMU_CSV_HEADER);
    let mut samples = 0;
    let mut j = 0;
    for (t, g) in gyro_t.iter().zip(&gyro) {
        // The accelerometer sample of the same instant (both sensors are read together).
        while accel_t.get(j).is_some_and(|a| a[0] < t[0] - 1e-4) {
            j += 1;
        }
        let Some((_, a)) = accel_t.get(j).zip(accel.get(j)).filter(|(at, _)| (at[0] - t[0]).abs() <= 1e-4) else {
            continue;
        };
        csv += &format!("{:.6},{},{},{},{},{},{}\n", t[0], g[0], g[1], g[2], a[0], a[1], a[2]);
        samples += 1;
    }
    Ok((csv, samples))
}

/// What the minute gave with gyro + wheels and one receiver.
#[derive(Debug, Serialize)]
pub struct ImuMinute {
    /// Whose fixes.
    pub receiver: Receiver,
    /// IMU samples in the CSV.
    pub imu_samples: usize,
    /// Fixes in the receiver's CSV.
    pub fixes: usize,
    /// The device's ego against the fused poses.
    pub device: Compared,
    /// Seconds from the first fix to the first anchored ego pose.
    pub anchored_after_first_fix_s: f64,
    /// The finished ego against the fused poses.
    pub finished: Compared,
    /// The finished wheel factor.
    pub wheel_factor: f64,
    /// The device's pitch and roll from gravity against the fused attitude: median of the
    /// absolute difference over the minute, degrees.
    pub pitch_error_median_deg: f64,
    /// See `pitch_error_median_deg`.
    pub roll_error_median_deg: f64,
    /// The same differences' medians with their sign (a constant part is the sensor's
    /// tilt on the camera), degrees.
    pub pitch_offset_median_deg: f64,
    /// See `pitch_offset_median_deg`.
    pub roll_offset_median_deg: f64,
    /// The sensor's pitch above the road's grade that finishing found from the fixes'
    /// heights, degrees, in the sense of `pitch_offset_median_deg` (Z-Y-X pitch, nose down
    /// positive); NaN when it found none. It is the camera's tilt on the car plus the
    /// sensor's on the camera (`pitch_offset_median_deg`).
    pub pitch_offset_found_deg: f64,
    /// The fused poses' camera pitch below the road's grade (the grade from the fused
    /// positions themselves over ±0.5 s), median over the minute, degrees.
    pub reference_camera_pitch_deg: f64,
    /// The device's gyro bias about the body's z at the end, rad/s, against the phone's own
    /// calibration (`processed_log/IMU/gyro_bias`, in body axes).
    pub gyro_bias_z: f64,
    /// See `gyro_bias_z`.
    pub reference_gyro_bias_z: f64,
    /// Log bytes per minute, and of them the IMU's records.
    pub log_bytes_per_minute: f64,
    /// See `log_bytes_per_minute`.
    pub imu_bytes_per_minute: f64,
}

/// The body's (x forward, y left, z up) rotation of comma's camera pose (x forward, y
/// right, z down).
fn body_of(camera: &Matrix3<f64>) -> Matrix3<f64> {
    camera * Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
}

/// The camera's pitch below the road (nose down positive), degrees, median over the
/// poses: the angle of its forward axis under the grade the poses' own positions climb
/// over ±0.5 s (where the car has moved at least 5 m).
fn camera_below_road(truth: &Trajectory) -> f64 {
    let n = truth.poses.len();
    let angles = (0..n).filter_map(|i| {
        let span = |j: usize| truth.stamps.get(j).zip(truth.stamps.get(i)).map(|(a, b)| (a - b).abs());
        let a = (0..i).rev().take_while(|&j| span(j).is_some_and(|s| s <= 0.5)).last()?;
        let b = (i + 1..n).take_while(|&j| span(j).is_some_and(|s| s <= 0.5)).last()?;
        let rise = truth.poses[b].translation - truth.poses[a].translation;
        let run = rise.xy().norm();
        let forward = truth.poses[i].rotation.column(0).into_owned();
        (run >= 5.0).then(|| (rise.z.atan2(run) - forward.z.atan2(forward.xy().norm())).to_degrees())
    });
    median(angles.collect())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

/// The minute into `work` with gyro + wheels and `receiver`'s fixes: recorded, finished,
/// compared.
pub fn run(dir: &Path, work: &Path, receiver: Receiver) -> Result<ImuMinute> {
    std::fs::create_dir_all(work).map_err(|e| Error::file(work, e))?;
    let truth = Trajectory::read(&dir.join("expected/global_pose_camera_enu.tum"), Format::Tum)
        .map_err(|e| Error::refused("comma2k19 poses", e))?;
    let (csv, imu_samples) = imu_csv(dir)?;
    let imu_path = work.join("imu.csv");
    write(&imu_path, &csv)?;
    let nmea = comma::receiver_nmea(&dir.join(receiver.csv()), receiver.hdop())?;
    let nmea_path = work.join("gnss.serial.log");
    write(&nmea_path, &nmea.stamped)?;
    let sources = record::Sources {
        nmea: Some(nmea_path),
        can: vec![dir.join("raw_can.candump.log")],
        imu: Some(imu_path),
        ..record::Sources::default()
    };
    let device = Device {
        mount: comma::mount(),
        mode: VoFrame::Gravity,
        uere: UERE,
        relative_motion: RelativeMotion::ImuWheels,
        ..Device::default()
    };
    let args = RecordRequest {
        dbc: vec![dir.join("opendbc-toyota/_toyota_2017.dbc")],
        speed_signal: Some("SPEED.SPEED".parse()?),
        origin: Some(comma::origin()?),
        device: device.clone(),
        ..RecordRequest::from_files(&work.join("imu.d2slog"), sources)
    };
    let (recording, _) = record::record_files(&args)?;
    write(&args.output, &recording.log)?;
    let log = log::read(&args.output).map_err(Error::other)?;
    let times = device_times(&log.records)?;
    let online = compare(&log.records, &times, &truth)?;
    let first_fix = times.iter().zip(&log.records).find_map(|(t, r)| matches!(r, Record::GnssFix(_)).then_some(*t));
    let first_ego = times.iter().zip(&log.records).find_map(|(t, r)| matches!(r, Record::EgoPose(_)).then_some(*t));

    let mut pitch = Vec::new();
    let mut roll = Vec::new();
    let mut bias_z = f64::NAN;
    for (r, &t) in log.records.iter().zip(&times) {
        let Record::ImuEstimate(e) = r else { continue };
        bias_z = e.bias_z_e7 as f64 * 1e-7;
        let k = truth.stamps.partition_point(|s| *s < t);
        let Some(pose) = truth.poses.get(k).filter(|_| truth.stamps.get(k).is_some_and(|s| (s - t).abs() < 0.06))
        else {
            continue;
        };
        let [_, p, rl] = so3::yaw_pitch_roll(&body_of(&pose.rotation));
        pitch.push((e.pitch_e6 as f64 * 1e-6 - p).to_degrees());
        roll.push((e.roll_e6 as f64 * 1e-6 - rl).to_degrees());
    }
    let reference_bias =
        npy_rows(&dir.join("b0c9d2329ad1606b_2018-08-02--08-34-47_40/processed_log/IMU/gyro_bias/value"), 3)?;
    // Sensor axes (forward, right, down) → body (forward, left, up): z changes sign.
    let reference_gyro_bias_z = -reference_bias.last().map_or(f64::NAN, |b| b[2]);

    let (mount, uere) = (device.mount, device.uere);
    let name = args.output.display().to_string();
    // Finished as `dash2sim finish` would, in the frame the device recorded in.
    let settings = Settings { gravity_aligned: device.mode == VoFrame::Gravity, ..Settings::default() };
    let finished = dash2sim_finish::finish(&log.compact(), &name, None, None, mount, settings, uere)?;
    // The finish's offset is a grade's (nose up positive); the Z-Y-X pitch is nose down.
    let found = finished.report.reckoning.and_then(|r| r.pitch_offset_deg).map_or(f64::NAN, |d| -d);
    let finished_records = finished.records.to_vec();
    let finished_times = device_times(&finished_records)?;
    let finished_compared = compare(&finished_records, &finished_times, &truth)?;
    let span = truth.stamps.last().copied().unwrap_or_default() - truth.stamps.first().copied().unwrap_or_default();
    let imu_bytes: u64 = Kind::ALL
        .iter()
        .zip(log.stats.bytes)
        .filter(|(k, _)| matches!(k, Kind::ImuDelta | Kind::ImuEstimate))
        .map(|(_, bytes)| bytes)
        .sum();
    Ok(ImuMinute {
        receiver,
        imu_samples,
        fixes: nmea.fixes,
        device: online,
        anchored_after_first_fix_s: first_ego.zip(first_fix).map_or(f64::NAN, |(e, f)| e - f),
        finished: finished_compared,
        wheel_factor: finished.report.anchoring.wheel_factor,
        pitch_error_median_deg: median(pitch.iter().map(|d| d.abs()).collect()),
        roll_error_median_deg: median(roll.iter().map(|d| d.abs()).collect()),
        reference_camera_pitch_deg: camera_below_road(&truth),
        pitch_offset_found_deg: found,
        pitch_offset_median_deg: median(pitch),
        roll_offset_median_deg: median(roll),
        gyro_bias_z: bias_z,
        reference_gyro_bias_z,
        log_bytes_per_minute: log.bytes as f64 / (span / 60.0),
        imu_bytes_per_minute: imu_bytes as f64 / (span / 60.0),
    })
}
