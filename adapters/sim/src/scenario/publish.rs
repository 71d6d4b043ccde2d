//! A camera process for tests, demos and load runs: publishes a generated work-zone drive
//! over the shared-memory bridge at its real frame rate (or `--speedup` times faster) — per
//! frame its metadata (and, with `--images`, a 1920×1080 RGB image), the VO pose and the 3D
//! and 2D detections, and before each frame the IMU samples since the last — stamped with the
//! shared device clock at their capture times. With `--nmea-out` /
//! `--can-out` it is the rest of the vehicle too: the GNSS receiver's sentences and the
//! wheel-speed CAN frames (candump text) written to a serial device, FIFO or file at their
//! own rates.
//!
//! Two entry points run it: `dash2sim scenario publish` (the demo's camera process) and the
//! `camera_sim` example binary (the bridge's tests and load runs).

use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use dash2sim_core::box3d::Box3d;
use dash2sim_core::pipeline::ImageDetection;
use dash2sim_core::track2d::Detection;
use dash2sim_core::track3d::Detection3d;

use super::actors::Class;
use super::profile::{Profile, Receiver};
use super::road::Road;
use super::write::{receiver_output, wheel_speed_frames};
use super::{generate, Driver, Scenario, ScenarioConfig};
use crate::{Error, Result};
use dash2sim_linux::record::bridge::messages::MAX_DETECTIONS;
use dash2sim_linux::record::bridge::{device_now, CameraPublisher, MAX_IMAGE_BYTES};

/// What to publish and how fast. Two binaries take it as their arguments (`dash2sim scenario
/// publish` and the `camera_sim` example), through `dash2sim-args`'s `PublishArgs`.
#[derive(Clone, Debug)]
pub struct PublishRequest {
    /// Seed of the generated drive.
    pub seed: u64,
    /// How the ego drives through the work zone.
    pub driver: Driver,
    /// Length of the drive, s (1–600).
    pub seconds: f64,
    /// How far the sensors are from ideal: `ideal`, `typical` or `hard` (docs/scenario.md).
    pub profile: Profile,
    /// The GNSS receiver: `good` (σ 1–2 m) or `phone` (σ 3–10 m).
    pub receiver: Receiver,
    /// Frames per second (a multiple of the receiver's 5 Hz).
    pub fps: u32,
    /// Drive the road this many times (frame numbers and clocks go on; the road starts again).
    pub laps: u32,
    /// Report at least this many 3D detections a frame (up to 64), adding static cones beside
    /// the road where the drive has fewer: a load test's worst case.
    pub objects: usize,
    /// Publish this many times faster than real time.
    pub speedup: f64,
    /// Service prefix.
    pub prefix: String,
    /// Also publish a 1920×1080×3 image per frame on the image service.
    pub images: bool,
    /// Write the GNSS receiver's NMEA here at its rate (a pty, FIFO or file).
    pub nmea_out: Option<PathBuf>,
    /// Write the wheel-speed CAN frames here as candump lines at their rate (a FIFO or file).
    pub can_out: Option<PathBuf>,
}

/// When the line or frame at drive time `t` of lap `lap` is due.
struct Pace {
    start: Instant,
    /// The device clock at `start`.
    device_start: dash2sim_core::time::Timestamp,
    lap_s: f64,
    speedup: f64,
}

impl Pace {
    /// From `start` on, the run's own clock.
    fn offset_s(&self, lap: u32, t: f64) -> f64 {
        (f64::from(lap) * self.lap_s + t) / self.speedup
    }

    fn wait(&self, lap: u32, t: f64) {
        let due = self.start + Duration::from_secs_f64(self.offset_s(lap, t));
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
    }

    /// The device time a frame due at `t` was captured: a camera stamps its exposure, which
    /// runs on its own schedule, not the moment this process woke to publish it (a busy
    /// machine wakes it milliseconds late, and VO poses stamped so read as jerk).
    fn capture_time(&self, lap: u32, t: f64) -> dash2sim_core::time::Timestamp {
        self.device_start + dash2sim_core::time::Duration::from_micros((self.offset_s(lap, t) * 1e6).round() as i64)
    }
}

/// Write `lines(lap)` (time, text) to `path` at their times, lap after lap, in a thread.
/// A reader that goes away ends the writing, not the run.
fn write_paced(
    path: PathBuf,
    pace: Pace,
    laps: u32,
    lines: impl Fn(u32) -> Result<Vec<(f64, String)>> + Send + 'static,
) -> std::thread::JoinHandle<Result<()>> {
    std::thread::spawn(move || {
        let mut out = std::fs::OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .map_err(|e| Error::file(&path, e))?;
        for lap in 0..laps {
            for (t, line) in lines(lap)? {
                pace.wait(lap, t);
                if out.write_all(line.as_bytes()).and_then(|()| out.flush()).is_err() {
                    return Ok(());
                }
            }
        }
        Ok(())
    })
}

/// Static cones beside the road for `--objects`: every 3 m of it, 7 m and 10 m to either
/// side of the lane the drive starts in (off the lanes it uses, so they never block it).
fn roadside_cones(road: &Road, lane: f64) -> Vec<[f64; 2]> {
    let n = (road.length() / 3.0) as usize;
    (0..n)
        .flat_map(|i| [-10.0, -7.0, 7.0, 10.0].map(|d| road.point(i as f64 * 3.0, lane + d)))
        .map(|(x, y)| [x, y])
        .collect()
}

/// The frame's detections in the camera frame, with roadside cones added up to `objects`.
fn camera_detections(scenario: &Scenario, frame: usize, cones: &[[f64; 2]], objects: usize) -> Vec<Detection3d> {
    let camera = &scenario.config.camera;
    let Some(f) = scenario.frames.get(frame) else { return Vec::new() };
    // Detections are generated in the ego frame; the camera reports them in its own.
    let mut detections: Vec<Detection3d> = f
        .detections_3d
        .iter()
        .map(|d| {
            let mut d = *d;
            d.bbox.x -= camera.mount_forward;
            d.bbox.z -= camera.mount_height;
            d
        })
        .collect();
    let (cos, sin) = (f.ego.heading.cos(), f.ego.heading.sin());
    let mut seen: Vec<(f64, f64, f64)> = cones
        .iter()
        .map(|[x, y]| {
            let (dx, dy) = (x - f.ego.x, y - f.ego.y);
            (cos * dx + sin * dy - camera.mount_forward, -sin * dx + cos * dy)
        })
        .filter(|(x, y)| *x > 2.0 && *x < 60.0 && y.abs() < 12.0)
        .map(|(x, y)| (x, y, x.hypot(y)))
        .collect();
    seen.sort_by(|a, b| a.2.total_cmp(&b.2));
    let wanted = objects.min(MAX_DETECTIONS).saturating_sub(detections.len());
    detections.extend(seen.into_iter().take(wanted).map(|(x, y, range)| Detection3d {
        class: Class::Cone as u16,
        bbox: Box3d { x, y, z: 0.35 - camera.mount_height, yaw: 0.0, l: 0.35, w: 0.35, h: 0.7 },
        score: 0.9,
        position_covariance: Some(scenario.config.detector.position_covariance(range, y.atan2(x))),
    }));
    detections
}

/// Publish the drive `args` names; the number of frames published.
pub fn run(args: &PublishRequest) -> Result<u64> {
    let longest = super::command::MAX_DURATION_S;
    if !(args.seconds.is_finite() && (1.0..=longest).contains(&args.seconds)) {
        return Err(Error::invalid(format!("--seconds {} must be between 1 and {longest}", args.seconds)));
    }
    if !(args.speedup.is_finite() && args.speedup > 0.0) {
        return Err(Error::invalid(format!("--speedup {} must be positive", args.speedup)));
    }
    if args.fps == 0 || !args.fps.is_multiple_of(5) || args.fps > 60 {
        return Err(Error::invalid(format!(
            "--fps {} must be a multiple of 5 (the receiver's rate), at most 60",
            args.fps
        )));
    }
    if args.laps == 0 {
        return Err(Error::invalid("--laps must be at least 1"));
    }
    let scenario = generate(&ScenarioConfig {
        driver: args.driver,
        duration_s: args.seconds,
        frame_rate_hz: f64::from(args.fps),
        ..ScenarioConfig::drive(args.seed, args.profile, args.receiver)
    });
    let camera = CameraPublisher::new(&args.prefix, args.images).map_err(Error::other)?;
    let image = args.images.then(|| vec![0x80u8; MAX_IMAGE_BYTES]);
    let cones = if args.objects > 0 {
        roadside_cones(&scenario.road, scenario.frames.first().map_or(0.0, |f| f.ego.d))
    } else {
        Vec::new()
    };
    let (start, device_start) = (Instant::now(), device_now());
    let lap_s = args.seconds + 1.0 / f64::from(args.fps);
    let pace = || Pace { start, device_start, lap_s, speedup: args.speedup };
    let mut writers = Vec::new();
    if let Some(path) = &args.nmea_out {
        let receiver = scenario.clone();
        writers.push(write_paced(path.clone(), pace(), args.laps, move |lap| {
            let lines = receiver_output(&receiver, f64::from(lap) * lap_s).map_err(Error::other)?;
            Ok(lines.into_iter().map(|(t, [gga, rmc])| (t, format!("{gga}\r\n{rmc}\r\n"))).collect())
        }));
    }
    if let Some(path) = &args.can_out {
        let frames = wheel_speed_frames(&scenario).map_err(Error::other)?;
        writers.push(write_paced(path.clone(), pace(), args.laps, move |lap| {
            frames
                .iter()
                .map(|(t, frame)| {
                    let mut line = Vec::new();
                    let stamp = dash2sim_core::time::Timestamp::from_micros(
                        ((f64::from(lap) * lap_s + t) * 1e6).round() as i64,
                    );
                    dash2sim_can::candump::write_log_line(&mut line, stamp, "can0", frame).map_err(Error::other)?;
                    Ok((*t, String::from_utf8_lossy(&line).into_owned()))
                })
                .collect()
        }));
    }
    let frames_per_lap = scenario.frames.len() as u64;
    let mut published = 0u64;
    for lap in 0..args.laps {
        let mut imu = scenario.imu.iter().peekable();
        for (i, frame) in scenario.frames.iter().enumerate() {
            pace().wait(lap, frame.ego.t);
            // The IMU's samples up to this frame, each with its own time: a camera SoC reads
            // the sensor's FIFO in batches, once a frame.
            while let Some((t_imu, sample)) = imu.next_if(|(t_imu, _)| *t_imu <= frame.ego.t) {
                camera.imu(pace().capture_time(lap, *t_imu), sample).map_err(Error::other)?;
            }
            let t = pace().capture_time(lap, frame.ego.t);
            let sequence = u64::from(lap) * frames_per_lap + u64::from(frame.index);
            camera.frame(sequence, t, 8_000, image.as_deref()).map_err(Error::other)?;
            // While the VO has lost track there is no pose to publish.
            if let Some((pose, session)) = scenario.vo.at_frame(i) {
                camera.vo(sequence, t, pose, session).map_err(Error::other)?;
            }
            camera
                .detections3d(sequence, t, &camera_detections(&scenario, i, &cones, args.objects))
                .map_err(Error::other)?;
            let detections2d: Vec<ImageDetection> = frame
                .detections_2d
                .iter()
                .map(|d| ImageDetection { class: 0, detection: Detection { bbox: d.bbox, score: d.score } })
                .collect();
            camera.detections2d(sequence, t, &detections2d).map_err(Error::other)?;
            published += 1;
        }
    }
    for writer in writers {
        writer.join().map_err(|_| Error::invalid("a writer thread panicked"))??;
    }
    Ok(published)
}
