//! `dash2sim scenario generate` and `dash2sim scenario eval`.

use std::path::Path;

use dash2sim_core::track3d::Config3d;
use serde_json::json;

use super::evaluate::evaluate_tracking;
use super::profile::{Profile, Receiver};
use super::write::write_scenario;
use super::{generate, tracker_classes, tracker_config, ScenarioConfig};

/// Longest drive, seconds: ten minutes, on a road of 12 sections (13.8 km, a work zone in
/// each).
pub const MAX_DURATION_S: f64 = 600.0;

/// The drive `seed` of `duration_s` seconds under `profile` with `receiver`, or why not.
pub fn config(seed: u64, duration_s: f64, profile: Profile, receiver: Receiver) -> Result<ScenarioConfig, String> {
    if !(duration_s.is_finite() && (1.0..=MAX_DURATION_S).contains(&duration_s)) {
        return Err(format!("--duration {duration_s} must be between 1 and {MAX_DURATION_S} seconds"));
    }
    Ok(ScenarioConfig { duration_s, ..ScenarioConfig::drive(seed, profile, receiver) })
}

/// Generate scenario `seed` and write it to `dir`.
pub fn run_generate(
    seed: u64,
    duration_s: f64,
    profile: Profile,
    receiver: Receiver,
    dir: &Path,
) -> Result<(), String> {
    let scenario = generate(&config(seed, duration_s, profile, receiver)?);
    let files = write_scenario(&scenario, dir).map_err(|e| format!("writing {}: {e}", dir.display()))?;
    let count = |f: fn(&super::Frame) -> usize| scenario.frames.iter().map(f).sum::<usize>();
    println!(
        "scenario {seed} ({} profile, {} receiver): {} frames, {} objects, {} 3D and {} 2D detections, {} GNSS fixes ({} in multipath), {} speed samples, {} VO session(s)",
        profile.name(),
        receiver.name(),
        scenario.frames.len(),
        scenario.frames.first().map_or(0, |f| f.objects.len()),
        count(|f| f.detections_3d.len()),
        count(|f| f.detections_2d.len()),
        scenario.gnss.len(),
        scenario.gnss.iter().filter(|g| g.multipath).count(),
        scenario.speed.len(),
        scenario.vo.reinits() + 1
    );
    for file in files {
        println!("  {}", file.display());
    }
    Ok(())
}

/// Generate scenario `seed`, run the 3D tracker over it and print the report.
pub fn run_eval(seed: u64, duration_s: f64, profile: Profile, max_age: u32, as_json: bool) -> Result<(), String> {
    let scenario = generate(&config(seed, duration_s, profile, Receiver::Phone)?);
    let classes = tracker_classes();
    let report = evaluate_tracking::<64>(&scenario, Config3d { max_age, ..tracker_config(&classes) });
    let figures = [
        ("rmse_detections_m", report.rmse_detections),
        ("rmse_filtered_m", report.rmse_filtered),
        ("rmse_smoothed_m", report.rmse_smoothed),
        ("static_accuracy", report.static_accuracy()),
    ];
    if as_json {
        let mut out = json!({
            "seed": seed,
            "profile": profile.name(),
            "frames": report.frames,
            "objects": report.objects,
            "object_frames": report.object_frames,
            "detections": report.detections,
            "paired": report.paired,
            "rejected_detections": report.stats.rejected,
            "metrics": report.summary.to_json(),
        });
        for (name, value) in figures {
            out[name] = json!(value);
        }
        println!("{out}");
        return Ok(());
    }
    println!(
        "scenario {seed} ({} profile): {} frames, {} objects in view, {} object-frames, {} detections",
        profile.name(),
        report.frames,
        report.objects,
        report.object_frames,
        report.detections
    );
    for name in ["mota", "motp", "idf1", "num_switches", "num_fragmentations", "num_false_positives", "num_misses"] {
        println!("{name:>20}  {}", report.metric(name));
    }
    for (name, value) in figures {
        println!("{name:>20}  {value:.4}");
    }
    println!("{:>20}  {} (object-frames with both a matched detection and a matched track)", "paired", report.paired);
    println!(
        "{:>20}  {} of {} (implausible: off the ground or of an unknown class)",
        "rejected", report.stats.rejected, report.detections
    );
    Ok(())
}
