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
use crate::{Error, Field, Result};
use dash2sim_linux::record::bridge::messages::MAX_DETECTIONS;
use dash2sim_linux::record::bridge::{device_now, CameraPublisher, MAX_IMAGE_BYTES};

/// What to publish and how fast. Two binaries take it as their arguments (`dash2sim scenario
/// publish` and the `camera_sim` example), through `dash2sim-args`'s `PublishArgs`.
#[derive(Clone, Debug, PartialEq)]
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
    /// Also write this many CAN frames a second of a message the pipeline does not use
    /// (J1939 EEC1, engine speed) to `can_out`, in bursts every 10 ms: a busy vehicle bus.
    pub bus_load: u32,
}

/// What a run published: each kind as sent (the bridge's publishes that succeeded, the
/// bytes and lines the serial and CAN outputs took), for a load run's accounting.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Published {
    /// Frame metadata messages.
    pub frames: u64,
    /// VO poses (none while the VO has lost track).
    pub vo_poses: u64,
    /// 3D detection messages (one a frame).
    pub detections3d: u64,
    /// 3D detections in them.
    pub objects3d: u64,
    /// 2D detection messages (one a frame).
    pub detections2d: u64,
    /// IMU samples.
    pub imu_samples: u64,
    /// NMEA bytes written.
    pub nmea_bytes: u64,
    /// NMEA lines (sentences) written.
    pub nmea_sentences: u64,
    /// CAN frames written (wheel speed and the bus load).
    pub can_frames: u64,
    /// Lines the serial or CAN output did not take: due while their reader had gone (a
    /// logger killed and not yet back).
    pub unsent_lines: u64,
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

/// Lines, bytes written, and lines not taken by [`write_paced`].
#[derive(Clone, Copy, Debug, Default)]
struct Written {
    lines: u64,
    bytes: u64,
    unsent: u64,
}

/// `path` opened again for writing if a reader has it open (a FIFO whose logger came back),
/// without waiting for one.
fn reopen(path: &std::path::Path) -> Option<std::fs::File> {
    use rustix::fs::{fcntl_setfl, open, Mode, OFlags};
    let fd = open(path, OFlags::WRONLY | OFlags::NONBLOCK | OFlags::CLOEXEC, Mode::empty()).ok()?;
    // Blocking again: a line waits for a reader that is slow, not one that is gone.
    fcntl_setfl(&fd, OFlags::WRONLY).ok()?;
    Some(std::fs::File::from(fd))
}

/// Write `lines(lap)` (time, text) to `path` at their times, lap after lap, in a thread.
/// A reader that goes away (a logger killed) does not end the run: the lines due until a
/// reader opens the FIFO again are not sent, and counted.
fn write_paced(
    path: PathBuf,
    pace: Pace,
    laps: u32,
    lines: impl Fn(u32) -> Result<Vec<(f64, String)>> + Send + 'static,
) -> std::thread::JoinHandle<Result<Written>> {
    std::thread::spawn(move || {
        let mut out = Some(
            std::fs::OpenOptions::new()
                .write(true)
                .create(true)
                .truncate(true)
                .open(&path)
                .map_err(|e| Error::file(&path, e))?,
        );
        let mut written = Written::default();
        for lap in 0..laps {
            for (t, line) in lines(lap)? {
                pace.wait(lap, t);
                if out.is_none() {
                    out = reopen(&path);
                }
                // A line is shorter than a pipe's atomic write (4 KB): it goes whole or not at all.
                match out.as_mut().map(|o| o.write_all(line.as_bytes()).and_then(|()| o.flush())) {
                    Some(Ok(())) => {
                        written.lines += 1;
                        written.bytes += line.len() as u64;
                    }
                    Some(Err(_)) | None => {
                        out = None;
                        written.unsent += 1;
                    }
                }
            }
        }
        Ok(written)
    })
}

/// `bus_load` frames a second of J1939 EEC1 (engine speed 1500 rpm) over `seconds`, in
/// bursts every 10 ms.
fn bus_load_frames(bus_load: u32, seconds: f64) -> Vec<(f64, dash2sim_core::can::CanFrame)> {
    let Some(id) = dash2sim_core::can::frame::id_from_raw(0x0CF0_0400, true) else { return Vec::new() };
    let Some(frame) = dash2sim_core::can::CanFrame::data_frame(id, &[0xF0, 0x7D, 0x7D, 0xE0, 0x2E, 0x00, 0xF0, 0x7D])
    else {
        return Vec::new();
    };
    let bursts = (seconds * 100.0).floor() as u64;
    let mut sent = 0u64;
    let mut frames = Vec::new();
    for burst in 0..bursts {
        // Frames due by the end of this burst's 10 ms.
        let due = (u64::from(bus_load) * (burst + 1)) / 100;
        frames.extend((sent..due).map(|_| (burst as f64 * 0.01, frame)));
        sent = due;
    }
    frames
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

/// Publish the drive `args` names: what was published.
pub fn run(args: &PublishRequest) -> Result<Published> {
    let longest = super::command::MAX_DURATION_S;
    if !(args.seconds.is_finite() && (1.0..=longest).contains(&args.seconds)) {
        return Err(Error::request(Field::Seconds, format!("{} s must be between 1 and {longest}", args.seconds)));
    }
    if !(args.speedup.is_finite() && args.speedup > 0.0) {
        return Err(Error::request(Field::Speedup, format!("{} must be positive", args.speedup)));
    }
    if args.fps == 0 || !args.fps.is_multiple_of(5) || args.fps > 60 {
        return Err(Error::request(
            Field::Fps,
            format!("{} must be a multiple of 5 (the receiver's rate), at most 60", args.fps),
        ));
    }
    if args.laps == 0 {
        return Err(Error::request(Field::Laps, "at least 1 is needed"));
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
    let nmea_writer = writers.len();
    if let Some(path) = &args.can_out {
        let mut frames = wheel_speed_frames(&scenario).map_err(Error::other)?;
        frames.extend(bus_load_frames(args.bus_load, scenario.speed.last().map_or(args.seconds, |(t, _)| *t)));
        frames.sort_by(|a, b| a.0.total_cmp(&b.0));
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
    let mut published = Published::default();
    for lap in 0..args.laps {
        let mut imu = scenario.imu.iter().peekable();
        for (i, frame) in scenario.frames.iter().enumerate() {
            pace().wait(lap, frame.ego.t);
            // The IMU's samples up to this frame, each with its own time: a camera SoC reads
            // the sensor's FIFO in batches, once a frame.
            while let Some((t_imu, sample)) = imu.next_if(|(t_imu, _)| *t_imu <= frame.ego.t) {
                camera.imu(pace().capture_time(lap, *t_imu), sample).map_err(Error::other)?;
                published.imu_samples += 1;
            }
            let t = pace().capture_time(lap, frame.ego.t);
            let sequence = u64::from(lap) * frames_per_lap + u64::from(frame.index);
            camera.frame(sequence, t, 8_000, image.as_deref()).map_err(Error::other)?;
            published.frames += 1;
            // While the VO has lost track there is no pose to publish.
            if let Some((pose, session)) = scenario.vo.at_frame(i) {
                camera.vo(sequence, t, pose, session).map_err(Error::other)?;
                published.vo_poses += 1;
            }
            let detections = camera_detections(&scenario, i, &cones, args.objects);
            camera.detections3d(sequence, t, &detections).map_err(Error::other)?;
            published.detections3d += 1;
            published.objects3d += detections.len().min(MAX_DETECTIONS) as u64;
            let detections2d: Vec<ImageDetection> = frame
                .detections_2d
                .iter()
                .map(|d| ImageDetection { class: 0, detection: Detection { bbox: d.bbox, score: d.score } })
                .collect();
            camera.detections2d(sequence, t, &detections2d).map_err(Error::other)?;
            published.detections2d += 1;
        }
    }
    for (i, writer) in writers.into_iter().enumerate() {
        let written = writer.join().map_err(|_| Error::invalid("a writer thread panicked"))??;
        if i < nmea_writer {
            published.nmea_bytes = written.bytes;
            // Two sentences a line (GGA and RMC).
            published.nmea_sentences = 2 * written.lines;
        } else {
            published.can_frames = written.lines;
        }
        published.unsent_lines += written.unsent;
    }
    Ok(published)
}
