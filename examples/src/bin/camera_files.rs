//! A camera process that publishes recorded camera outputs from a folder — `vo.csv`,
//! `detections3d.csv`, `det2d.txt` and `imu.csv`, the files `dash2sim record` reads
//! (docs/cli.md) — over
//! the shared-memory bridge at their frame rate, then prints `N frames published`.
//!
//! The Rust one of three such programs: `examples/camera-c/camera_files.c` (the C ABI) and
//! `adapters/python/examples/camera_files.py` (`dash2sim.camera`) do the same, and the
//! contract test (`adapters/cli/tests/camera_publishers.rs`) checks that `dash2sim record`
//! logs the same bytes from each.
//!
//! Every frame number that has a VO pose or 3D detections is published, in order: its
//! metadata, its VO pose (if the VO had one), its 3D and its 2D detections (empty lists
//! where the detector found nothing), after the IMU samples stamped up to it (a camera SoC
//! reads its IMU's FIFO once a frame). A frame's device time is the VO's stamp (else the 3D
//! detections'), moved to now on the device clock (`--file-times` keeps the files' times); an
//! IMU sample's is moved by as much.
//!
//! `cargo run --release -p dash2sim-examples --bin camera_files -- DRIVE_DIR`

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Parser;
use dash2sim_core::pipeline::profile::class_id;
use dash2sim_core::time::Timestamp;
use dash2sim_core::track3d::Detection3d;
use dash2sim_linux::ingest::detections;
use dash2sim_linux::record::bridge::{device_now, CameraPublisher, DEFAULT_PREFIX};
use dash2sim_linux::record::sources::{read_detections2d, read_imu_csv, read_vo_csv};

/// How long the publisher stays open after the last frame.
const LINGER: Duration = Duration::from_millis(500);

/// Publish a folder of VO poses and detections as a camera process would.
#[derive(Debug, Parser)]
#[command(name = "camera_files", version, about)]
struct Args {
    /// The folder with vo.csv, detections3d.csv, det2d.txt and imu.csv (`dash2sim scenario generate`
    /// writes one; a missing file publishes nothing of its kind).
    dir: PathBuf,
    /// Service prefix.
    #[arg(long, default_value = DEFAULT_PREFIX)]
    prefix: String,
    /// Publish this many times faster than the files' frame rate.
    #[arg(long, default_value_t = 1.0)]
    speedup: f64,
    /// Stamp frames with the files' times rather than moving them to now.
    #[arg(long)]
    file_times: bool,
}

fn run(args: &Args) -> Result<usize, Box<dyn std::error::Error>> {
    let file = |name: &str| Some(args.dir.join(name)).filter(|p: &PathBuf| p.exists());
    let vo = file("vo.csv").map(|p| read_vo_csv(&p)).transpose()?.unwrap_or_default();
    let boxes3d = file("detections3d.csv").map(|p| detections::read(&p)).transpose()?.unwrap_or_default();
    let boxes2d = file("det2d.txt").map(|p: PathBuf| read_detections2d(&p)).transpose()?.unwrap_or_default();
    let imu = file("imu.csv").map(|p| read_imu_csv(&p)).transpose()?.unwrap_or_default();

    let mut times: BTreeMap<u64, f64> = vo.iter().map(|row| (row.frame, row.t)).collect();
    let mut frames3d: BTreeMap<u64, Vec<Detection3d>> = BTreeMap::new();
    for row in boxes3d {
        times.entry(row.frame).or_insert(row.t);
        frames3d.entry(row.frame).or_default().push(Detection3d {
            class: class_id(&row.class).unwrap_or(u16::MAX),
            bbox: row.bbox,
            score: row.score,
            position_covariance: row.covariance,
        });
    }
    let poses: BTreeMap<u64, _> = vo.iter().map(|row| (row.frame, row)).collect();
    let frames: BTreeSet<u64> = times.keys().copied().collect();

    let camera = CameraPublisher::new(&args.prefix, false)?;
    let first = times.values().next().copied().unwrap_or(0.0);
    let (start, device_start) = (Instant::now(), device_now());
    let moved = |t_s: f64| -> Result<Timestamp, String> {
        let t = micros(t_s, &args.dir)?;
        Ok(if args.file_times { t } else { device_start + (t - micros(first, &args.dir)?) })
    };
    let mut imu = imu.iter().peekable();
    for &frame in &frames {
        let t_s = times[&frame];
        let due = start + Duration::from_secs_f64(((t_s - first) / args.speedup).max(0.0));
        std::thread::sleep(due.saturating_duration_since(Instant::now()));
        while let Some((t_imu, sample)) = imu.next_if(|(t_imu, _)| *t_imu <= t_s) {
            camera.imu(moved(*t_imu)?, sample)?;
        }
        let t = moved(t_s)?;
        camera.frame(frame, t, 0, None)?;
        if let Some(row) = poses.get(&frame) {
            camera.vo(frame, t, &row.pose, row.session)?;
        }
        camera.detections3d(frame, t, frames3d.get(&frame).map_or(&[], Vec::as_slice))?;
        camera.detections2d(frame, t, boxes2d.get(&frame).map_or(&[], Vec::as_slice))?;
    }
    // Samples live in the publisher's shared memory: closing it at once could take the last
    // frame's away before the logger has read them.
    std::thread::sleep(LINGER);
    Ok(frames.len())
}

fn micros(t_s: f64, dir: &Path) -> Result<Timestamp, String> {
    Timestamp::from_secs_f64(t_s).ok_or_else(|| format!("{}: time {t_s} is out of range", dir.display()))
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(n) => {
            println!("{n} frames published");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("camera_files: {e}");
            ExitCode::FAILURE
        }
    }
}
