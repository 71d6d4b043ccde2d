//! The demo's report as a person reads it (`--json` prints the same report as JSON).

use dash2sim_sim::datasets::{comma, css, OutputFile};
use dash2sim_sim::demo::data::{DataRecording, DataReport};
use dash2sim_sim::demo::{DemoReport, RecordingReport, WindowVerdict};
use dash2sim_sim::fidelity::drive::WindowPair;
use dash2sim_verify::VerifyReport;

/// A figure as the summary shows it: what JSON cannot hold (NaN, ±∞) shows as NaN.
fn num(x: f64) -> f64 {
    if x.is_finite() {
        x
    } else {
        f64::NAN
    }
}

/// An optional figure: none shows as NaN.
fn opt(x: Option<f64>) -> f64 {
    x.map_or(f64::NAN, num)
}

fn verdict(report: Option<&VerifyReport>) -> &'static str {
    if report.is_some_and(|r| r.verified) {
        "verified"
    } else {
        "rejected"
    }
}

fn mark(verified: bool) -> &'static str {
    if verified {
        "✓"
    } else {
        "✗"
    }
}

/// One of nuPlan's metrics, read from the report's.
type Metric = fn(&dash2sim_verify::Metrics) -> f64;

/// nuPlan's metrics in the order its score combines them, with a short label.
const METRICS: [(Metric, &str); 8] = [
    (|m| m.no_at_fault_collisions, "no at-fault collisions"),
    (|m| m.drivable_area_compliance, "drivable area"),
    (|m| m.driving_direction_compliance, "driving direction"),
    (|m| m.ego_is_making_progress, "making progress"),
    (|m| m.ego_progress_along_expert_route, "progress along route"),
    (|m| m.time_to_collision_within_bound, "time to collision"),
    (|m| m.speed_limit_compliance, "speed limit"),
    (|m| m.ego_is_comfortable, "comfort"),
];

fn windows_text(windows: &[WindowVerdict]) -> String {
    if windows.is_empty() {
        return "none".to_owned();
    }
    let verified_count = windows.iter().filter(|w| w.verified).count();
    let each: Vec<String> = windows.iter().map(|w| format!("{} {:.1}", mark(w.verified), num(w.score))).collect();
    format!("{verified_count} of {} verified ({})", windows.len(), each.join(", "))
}

/// The device's windows, each with its decision within the ego's doubt and the truth's
/// verdict over the same stretch.
fn device_windows_text(windows: &[WindowPair]) -> String {
    if windows.is_empty() {
        return "none".to_owned();
    }
    let agree = windows.iter().filter(|w| w.device_verified == w.truth_verified).count();
    let each: Vec<String> = windows
        .iter()
        .map(|w| {
            format!(
                "{} {:.1}{} (truth {})",
                mark(w.device_verified),
                num(w.device_score),
                w.device_decision.map_or(String::new(), |d| format!(", {}", d.name())),
                mark(w.truth_verified)
            )
        })
        .collect();
    format!("{agree} of {} agree with the truth's verdict ({})", windows.len(), each.join(", "))
}

/// Print the generated drive's summary.
pub fn print(s: &DemoReport) {
    let folder = s.files.first().map_or(String::new(), |f| {
        std::path::Path::new(&f.path).parent().map_or(String::new(), |d| d.display().to_string())
    });
    println!(
        "dash2sim demo — {:.0} s work zone, seed {}, {} driver, {} sensor profile; everything in {folder}",
        num(s.duration_s),
        s.seed,
        s.driver.name(),
        s.profile.name()
    );
    match &s.recording {
        RecordingReport::Live { frames_published, frames_received, inputs_dropped, issues, wall_s, .. } => println!(
            "  recording     live: camera process → shared memory (iceoryx2), GNSS as NMEA on a FIFO, wheel speed as CAN frames; {frames_received} of {frames_published} published frames logged, {inputs_dropped} inputs dropped, {issues} refused, {:.1} s",
            num(*wall_s)
        ),
        RecordingReport::Offline { inputs, .. } => {
            println!("  recording     from the drive's files: {inputs} inputs in receive-time order");
        }
    }
    let p = s.recording.pipeline();
    println!(
        "  pipeline      {} records: {} VO poses ({} anchored), {} fixes, {} speeds, {} 3D detections placed, {} 3D and {} 2D track states, {} of {} windows verified ({} undecided)",
        p.records,
        p.vo_poses,
        p.anchored_frames,
        p.fixes,
        p.speeds,
        p.detections_placed,
        p.track_states,
        p.track2d_states,
        p.windows_verified,
        p.windows,
        p.windows_undecided
    );
    let (on, fin) = (&s.anchoring.online, &s.anchoring.finished);
    let observable = on.observable_after_s.map_or_else(|| "never".to_owned(), |t| format!("after {:.1} s", num(t)));
    let online_scale = match (on.scale_at_end, on.scale_error) {
        (Some(scale), Some(e)) => {
            format!("scale {:.4} at the end ({:+.2} % against the VO's true scale)", num(scale), 100.0 * num(e))
        }
        _ => "no observable scale".to_owned(),
    };
    println!(
        "  anchoring     online: observable {observable}, {} of {} frames anchored, APE {:.2} m RMSE ({:.2} m max), {online_scale}",
        on.anchored_frames,
        on.frames,
        num(on.ape_rmse_m),
        num(on.ape_max_m)
    );
    println!(
        "                finished: {} street-imagery anchors (simulated from the true path), APE {:.2} m RMSE ({:.2} m max), scale {:.4} ± {:.3} % (error {:+.3} %)",
        fin.anchors_used,
        num(fin.ape_rmse_m),
        num(fin.ape_max_m),
        num(fin.scale),
        100.0 * num(fin.scale_sigma_relative),
        100.0 * num(fin.scale_error)
    );
    let t = &s.tracking;
    let classes: Vec<String> = t.tracks_by_class.iter().map(|(class, n)| format!("{n} {class}")).collect();
    println!("  3D tracks     {}", if classes.is_empty() { "none".to_owned() } else { classes.join(", ") });
    println!(
        "                online MOTA {:.3}, IDF1 {:.3} against the truth (seen from the ego {:.3} / {:.3}; the tracker fed the true pose {:.3} / {:.3}); finished MOTA {:.3}, IDF1 {:.3}",
        num(t.online.mota),
        num(t.online.idf1),
        num(t.online.mota_seen_from_ego),
        num(t.online.idf1_seen_from_ego),
        num(t.tracker_fed_true_pose.mota),
        num(t.tracker_fed_true_pose.idf1),
        num(t.finished.mota),
        num(t.finished.idf1)
    );
    let v = &s.verification;
    let columns = [
        v.ground_truth.channel_insensitive.as_ref(),
        v.online.channel_insensitive.as_ref(),
        v.finished.channel_insensitive.as_ref(),
        v.ground_truth.channel_sensitive.as_ref(),
        v.online.channel_sensitive.as_ref(),
        v.finished.channel_sensitive.as_ref(),
    ];
    println!(
        "  verification  nuPlan-style log replay (> 90 verified)   channel-insensitive          channel-sensitive"
    );
    let row = |label: &str, cells: [String; 6]| {
        println!(
            "                {label:<26} {:>9}{:>9}{:>10}   {:>9}{:>9}{:>10}",
            cells[0], cells[1], cells[2], cells[3], cells[4], cells[5]
        );
    };
    row("", ["truth", "online", "finished", "truth", "online", "finished"].map(str::to_owned));
    for (metric, label) in METRICS {
        row(label, columns.map(|c| format!("{:.2}", c.map_or(f64::NAN, |r| num(metric(&r.metrics))))));
    }
    row("score", columns.map(|c| format!("{:.1}", c.map_or(f64::NAN, |r| num(r.score)))));
    row("", columns.map(|c| verdict(c).to_owned()));
    println!("  windows       on the device: {}", device_windows_text(&v.windows_on_device));
    println!("                finished:      {}", windows_text(&v.windows_finished));
    let l = &s.log;
    println!(
        "  4D log        {} records, {} bytes ({:.0} bytes per minute); finished {} bytes; MCAP {} messages",
        l.records,
        l.bytes,
        num(l.bytes_per_minute),
        l.finished_bytes,
        s.mcap_messages
    );
    if let dash2sim_sim::demo::NuplanOutcome::NotWritten { error } = &s.nuplan {
        println!("  nuPlan        not written: {error}");
    }
    print_files(&s.files);
}

fn print_files(files: &[OutputFile]) {
    println!("  files");
    for f in files {
        println!("    {:<60} {}", f.path, f.what);
    }
}

fn percent(x: Option<f64>) -> String {
    x.filter(|x| x.is_finite()).map_or_else(|| "n/a".to_owned(), |x| format!("{:+.3} %", 100.0 * x))
}

/// Print the real recordings' summary (`demo --data`).
pub fn print_data(s: &DataReport) {
    println!("dash2sim demo --data {}", s.data);
    for recording in &s.recordings {
        match recording {
            DataRecording::Missing { name, missing, .. } => {
                println!("\n{name}: not run — missing {}", missing.join(", "));
            }
            DataRecording::Failed { name, error, .. } => println!("\n{name}: failed — {error}"),
            DataRecording::Comma(r) => print_comma(r),
            DataRecording::Css(r) => print_css(r),
        }
    }
}

fn print_comma(r: &comma::Report) {
    println!("\n{} — {}", r.name, r.what);
    println!("  VO            {}", r.vo);
    let rec = &r.recording;
    let p = &rec.pipeline.stats;
    println!(
        "  recording     {:.0} s: {} of {} u-blox fixes, {} speeds, {} VO poses ({} anchored); {} bytes ({:.0} per minute)",
        num(r.duration_s), p.fixes, rec.fixes_in_csv, p.speeds, p.vo_poses,
        p.anchored_frames, rec.log_bytes, num(rec.bytes_per_minute)
    );
    println!(
        "  GNSS alone    APE {:.2} m RMS, {:.2} m max (evo, against comma's fused poses)",
        opt(r.gnss_alone.ape_rmse_m),
        opt(r.gnss_alone.ape_max_m)
    );
    let (o, f) = (&r.online.compared, &r.finished.compared);
    println!(
        "  online        observable after {:.1} s; APE {:.2} m RMS, {:.2} m max; anchor scale error at the end {}",
        num(o.first_s),
        num(o.ape_rmse),
        num(o.ape_max),
        percent(r.online.anchor_scale_error_at_end)
    );
    println!(
        "  finished      APE {:.2} m RMS, {:.2} m max ({:.3} m after Sim(3)); scale error {} (σ {}), GNSS latency {:.0} ms",
        num(f.ape_rmse), num(f.ape_max), num(f.ape_aligned), percent(Some(f.scale_error)),
        percent(Some(r.finished.scale_sigma_relative)).trim_start_matches('+'),
        1e3 * num(r.finished.gnss_latency_s)
    );
    print_files(&r.files);
}

fn print_css(r: &css::Report) {
    println!("\n{} — {}", r.name, r.what);
    println!("  VO            {}", r.vo);
    let (rec, c, v) = (&r.recording, &r.clock, &r.speed_check);
    println!(
        "  recording     {} candump files, {} frames: {} fixes (cantools: {} valid), {} positions without a fix (cantools: {}), {} speeds of {}; {} bytes ({:.0} per minute)",
        r.candump_files, r.can_frames, rec.fixes, rec.fixes_valid_by_cantools,
        rec.positions_without_fix, rec.positions_without_fix_by_cantools, rec.speeds,
        rec.speeds_in_reference, rec.log_bytes, num(rec.bytes_per_minute)
    );
    println!(
        "  drive         {:.1} min, {:.2} km along the fixes (the module's trip odometer: {:.2} km)",
        num(r.drive.duration_s) / 60.0,
        num(r.drive.distance_km),
        opt(r.drive.module_odometer_km)
    );
    println!(
        "  clock         logger − GNSS {:+.3} s at the first fix, {:+.3} s at the end ({:+.3} to {:+.3} s over {} offset records)",
        opt(c.logger_minus_gnss_first_s), opt(c.logger_minus_gnss_last_s),
        opt(c.logger_minus_gnss_min_s), opt(c.logger_minus_gnss_max_s), c.offset_records
    );
    println!(
        "  speed check   fixes vs OBD PID 0x0D: mean |Δ| {:.2} km/h, correlation {:.4} ({} pairs)",
        num(v.mean_abs_diff_kmh),
        num(v.correlation),
        v.pairs
    );
    print_files(&r.files);
}
