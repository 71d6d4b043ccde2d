//! A camera process for tests and demos: publishes a generated work-zone drive over the
//! shared-memory bridge at its real frame rate (or `--speedup` times faster) — per frame its
//! metadata (and, with `--images`, a 1920×1080 RGB image, zero-copy), the VO pose and the 3D
//! and 2D detections — stamped with the shared device clock, and prints `N frames published`.
//!
//! `cargo run --release -p dash2sim-examples --bin camera_sim -- --seconds 10`

use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::Parser;
use dash2sim_core::pipeline::ImageDetection;
use dash2sim_core::track2d::Detection;
use dash2sim_linux::bridge::{device_now, CameraPublisher, DEFAULT_PREFIX, MAX_IMAGE_BYTES};
use dash2sim_linux::scenario::sensors::GnssModel;
use dash2sim_linux::scenario::{generate, ScenarioConfig};

/// Publish a generated work-zone drive as a camera process would.
#[derive(Debug, Parser)]
#[command(name = "camera_sim", version, about)]
struct Args {
    /// Seed of the generated drive.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Length of the drive, s (1–50).
    #[arg(long, default_value_t = 20.0)]
    seconds: f64,
    /// Publish this many times faster than real time.
    #[arg(long, default_value_t = 1.0)]
    speedup: f64,
    /// Service prefix.
    #[arg(long, default_value = DEFAULT_PREFIX)]
    prefix: String,
    /// Also publish a 1920×1080×3 image per frame on the image service.
    #[arg(long)]
    images: bool,
}

fn run(args: &Args) -> Result<u64, String> {
    if !(args.seconds.is_finite() && (1.0..=50.0).contains(&args.seconds)) {
        return Err(format!("--seconds {} must be between 1 and 50", args.seconds));
    }
    if !(args.speedup.is_finite() && args.speedup > 0.0) {
        return Err(format!("--speedup {} must be positive", args.speedup));
    }
    let scenario = generate(&ScenarioConfig {
        seed: args.seed,
        duration_s: args.seconds,
        gnss: GnssModel::good(),
        ..ScenarioConfig::default()
    });
    let camera = CameraPublisher::new(&args.prefix, args.images).map_err(|e| e.to_string())?;
    let image = args.images.then(|| vec![0x80u8; MAX_IMAGE_BYTES]);
    let camera_offset = scenario.config.camera.mount_forward;
    let start = Instant::now();
    let mut published = 0u64;
    for (frame, pose) in scenario.frames.iter().zip(&scenario.vo.poses) {
        let due = start + Duration::from_secs_f64(frame.ego.t / args.speedup);
        if let Some(wait) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(wait);
        }
        let t = device_now();
        let sequence = u64::from(frame.index);
        camera.frame(sequence, t, 8_000, image.as_deref()).map_err(|e| e.to_string())?;
        camera.vo(sequence, t, pose).map_err(|e| e.to_string())?;
        // Detections are generated in the ego frame; the camera reports them in its own.
        let detections3d: Vec<_> = frame
            .detections_3d
            .iter()
            .map(|d| {
                let mut d = *d;
                d.bbox.x -= camera_offset;
                d.bbox.z -= scenario.config.camera.mount_height;
                d
            })
            .collect();
        camera.detections3d(sequence, t, &detections3d).map_err(|e| e.to_string())?;
        let detections2d: Vec<ImageDetection> = frame
            .detections_2d
            .iter()
            .map(|d| ImageDetection { class: 0, detection: Detection { bbox: d.bbox, score: d.score } })
            .collect();
        camera.detections2d(sequence, t, &detections2d).map_err(|e| e.to_string())?;
        published += 1;
    }
    Ok(published)
}

fn main() -> ExitCode {
    let args = Args::parse();
    match run(&args) {
        Ok(n) => {
            println!("{n} frames published");
            ExitCode::SUCCESS
        }
        Err(e) => {
            eprintln!("camera_sim: {e}");
            ExitCode::FAILURE
        }
    }
}
