//! The demo's summary as a person reads it, printed from the same JSON `--json` gives.

use serde_json::Value;

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn verdict(v: &Value) -> &'static str {
    if v["verified"].as_bool().unwrap_or(false) {
        "verified"
    } else {
        "rejected"
    }
}

/// nuPlan's metrics in the order its score combines them, with a short label.
const METRICS: [(&str, &str); 8] = [
    ("no_at_fault_collisions", "no at-fault collisions"),
    ("drivable_area_compliance", "drivable area"),
    ("driving_direction_compliance", "driving direction"),
    ("ego_is_making_progress", "making progress"),
    ("ego_progress_along_expert_route", "progress along route"),
    ("time_to_collision_within_bound", "time to collision"),
    ("speed_limit_compliance", "speed limit"),
    ("ego_is_comfortable", "comfort"),
];

fn windows_text(windows: &Value) -> String {
    let Some(list) = windows.as_array() else { return "none".to_owned() };
    if list.is_empty() {
        return "none".to_owned();
    }
    let verified = |w: &Value| w["verified"].as_bool().unwrap_or(false);
    let verified_count = list.iter().filter(|w| verified(w)).count();
    let each: Vec<String> =
        list.iter().map(|w| format!("{} {:.1}", if verified(w) { "✓" } else { "✗" }, num(&w["score"]))).collect();
    format!("{verified_count} of {} verified ({})", list.len(), each.join(", "))
}

/// The device's windows, each with its decision within the ego's doubt and the truth's
/// verdict over the same stretch.
fn device_windows_text(windows: &Value) -> String {
    let Some(list) = windows.as_array().filter(|l| !l.is_empty()) else { return "none".to_owned() };
    let mark = |v: &Value| if v.as_bool().unwrap_or(false) { "✓" } else { "✗" };
    let agree = list.iter().filter(|w| w["device_verified"] == w["truth_verified"]).count();
    let each: Vec<String> = list
        .iter()
        .map(|w| {
            format!(
                "{} {:.1}{} (truth {})",
                mark(&w["device_verified"]),
                num(&w["device_score"]),
                w["device_decision"].as_str().map_or(String::new(), |d| format!(", {d}")),
                mark(&w["truth_verified"])
            )
        })
        .collect();
    format!("{agree} of {} agree with the truth's verdict ({})", list.len(), each.join(", "))
}

/// Print the generated drive's summary.
pub fn print(s: &Value) {
    let files = s["files"].as_array().cloned().unwrap_or_default();
    let folder = files
        .first()
        .and_then(|f| f["path"].as_str())
        .map_or(String::new(), |p| std::path::Path::new(p).parent().map_or(String::new(), |d| d.display().to_string()));
    println!(
        "dash2sim demo — {:.0} s work zone, seed {}, {} driver, {} sensor profile; everything in {folder}",
        num(&s["duration_s"]),
        s["seed"],
        s["driver"].as_str().unwrap_or("?"),
        s["profile"].as_str().unwrap_or("?")
    );
    let r = &s["recording"];
    let p = &r["pipeline"];
    if r["mode"] == "live" {
        println!(
            "  recording     live: camera process → shared memory (iceoryx2), GNSS as NMEA on a FIFO, wheel speed as CAN frames; {} of {} published frames logged, {} inputs dropped, {} refused, {:.1} s",
            r["frames_received"], r["frames_published"], r["inputs_dropped"], r["issues"], num(&r["wall_s"])
        );
    } else {
        println!("  recording     from the drive's files: {} inputs in receive-time order", r["inputs"]);
    }
    println!(
        "  pipeline      {} records: {} VO poses ({} anchored), {} fixes, {} speeds, {} 3D detections placed, {} 3D and {} 2D track states, {} of {} windows verified ({} undecided)",
        p["records"],
        p["vo_poses"],
        p["anchored_frames"],
        p["fixes"],
        p["speeds"],
        p["detections_placed"],
        p["track_states"],
        p["track2d_states"],
        p["windows_verified"],
        p["windows"],
        p["windows_undecided"]
    );
    let (on, fin) = (&s["anchoring"]["online"], &s["anchoring"]["finished"]);
    let observable =
        on["observable_after_s"].as_f64().map_or_else(|| "never".to_owned(), |t| format!("after {t:.1} s"));
    let online_scale = match (on["scale_at_end"].as_f64(), on["scale_error"].as_f64()) {
        (Some(scale), Some(e)) => {
            format!("scale {scale:.4} at the end ({:+.2} % against the VO's true scale)", 100.0 * e)
        }
        _ => "no observable scale".to_owned(),
    };
    println!(
        "  anchoring     online: observable {observable}, {} of {} frames anchored, APE {:.2} m RMSE ({:.2} m max), {online_scale}",
        on["anchored_frames"],
        on["frames"],
        num(&on["ape_rmse_m"]),
        num(&on["ape_max_m"])
    );
    println!(
        "                finished: {} street-imagery anchors (simulated from the true path), APE {:.2} m RMSE ({:.2} m max), scale {:.4} ± {:.3} % (error {:+.3} %)",
        fin["anchors_used"],
        num(&fin["ape_rmse_m"]),
        num(&fin["ape_max_m"]),
        num(&fin["scale"]),
        100.0 * num(&fin["scale_sigma_relative"]),
        100.0 * num(&fin["scale_error"])
    );
    let t = &s["tracking"];
    let classes: Vec<String> = t["tracks_by_class"]
        .as_object()
        .map(|m| m.iter().map(|(class, n)| format!("{n} {class}")).collect())
        .unwrap_or_default();
    println!("  3D tracks     {}", if classes.is_empty() { "none".to_owned() } else { classes.join(", ") });
    println!(
        "                online MOTA {:.3}, IDF1 {:.3} against the truth (seen from the ego {:.3} / {:.3}; the tracker fed the true pose {:.3} / {:.3}); finished MOTA {:.3}, IDF1 {:.3}",
        num(&t["online"]["mota"]),
        num(&t["online"]["idf1"]),
        num(&t["online"]["mota_seen_from_ego"]),
        num(&t["online"]["idf1_seen_from_ego"]),
        num(&t["tracker_fed_true_pose"]["mota"]),
        num(&t["tracker_fed_true_pose"]["idf1"]),
        num(&t["finished"]["mota"]),
        num(&t["finished"]["idf1"])
    );
    let v = &s["verification"];
    let columns = [
        &v["ground_truth"]["channel_insensitive"],
        &v["online"]["channel_insensitive"],
        &v["finished"]["channel_insensitive"],
        &v["ground_truth"]["channel_sensitive"],
        &v["online"]["channel_sensitive"],
        &v["finished"]["channel_sensitive"],
    ];
    println!(
        "  verification  nuPlan-style log replay (> 90 verified)   channel-insensitive          channel-sensitive"
    );
    println!(
        "                {:<26} {:>9}{:>9}{:>10}   {:>9}{:>9}{:>10}",
        "", "truth", "online", "finished", "truth", "online", "finished"
    );
    for (key, label) in METRICS {
        let cells: Vec<String> = columns.iter().map(|c| format!("{:.2}", num(&c["metrics"][key]))).collect();
        println!(
            "                {label:<26} {:>9}{:>9}{:>10}   {:>9}{:>9}{:>10}",
            cells[0], cells[1], cells[2], cells[3], cells[4], cells[5]
        );
    }
    let scores: Vec<String> = columns.iter().map(|c| format!("{:.1}", num(&c["score"]))).collect();
    println!(
        "                {:<26} {:>9}{:>9}{:>10}   {:>9}{:>9}{:>10}",
        "score", scores[0], scores[1], scores[2], scores[3], scores[4], scores[5]
    );
    let verdicts: Vec<&str> = columns.iter().map(|c| verdict(c)).collect();
    println!(
        "                {:<26} {:>9}{:>9}{:>10}   {:>9}{:>9}{:>10}",
        "", verdicts[0], verdicts[1], verdicts[2], verdicts[3], verdicts[4], verdicts[5]
    );
    println!("  windows       on the device: {}", device_windows_text(&v["windows_on_device"]));
    println!("                finished:      {}", windows_text(&v["windows_finished"]));
    let l = &s["log"];
    println!(
        "  4D log        {} records, {} bytes ({:.0} bytes per minute); finished {} bytes; MCAP {} messages",
        l["records"],
        l["bytes"],
        num(&l["bytes_per_minute"]),
        l["finished_bytes"],
        s["mcap_messages"]
    );
    if let Some(e) = s["nuplan"]["error"].as_str() {
        println!("  nuPlan        not written: {e}");
    }
    print_files(&files);
}

fn print_files(files: &[Value]) {
    println!("  files");
    for f in files {
        println!("    {:<60} {}", f["path"].as_str().unwrap_or("?"), f["what"].as_str().unwrap_or(""));
    }
}

fn percent(v: &Value) -> String {
    v.as_f64().map_or_else(|| "n/a".to_owned(), |x| format!("{:+.3} %", 100.0 * x))
}

/// Print the real recordings' summary (`demo --data`).
pub fn print_data(s: &Value) {
    println!("dash2sim demo --data {}", s["data"].as_str().unwrap_or("?"));
    for r in s["recordings"].as_array().into_iter().flatten() {
        let name = r["name"].as_str().unwrap_or("?");
        if let Some(missing) = r["missing"].as_array() {
            let list: Vec<&str> = missing.iter().filter_map(Value::as_str).collect();
            println!("\n{name}: not run — missing {}", list.join(", "));
            continue;
        }
        if let Some(e) = r["error"].as_str() {
            println!("\n{name}: failed — {e}");
            continue;
        }
        println!("\n{name} — {}", r["what"].as_str().unwrap_or(""));
        println!("  VO            {}", r["vo"].as_str().unwrap_or(""));
        let rec = &r["recording"];
        let p = &rec["pipeline"];
        match name {
            "comma2k19" => {
                println!(
                    "  recording     {:.0} s: {} of {} u-blox fixes, {} speeds, {} VO poses ({} anchored); {} bytes ({:.0} per minute)",
                    num(&r["duration_s"]), p["fixes"], rec["fixes_in_csv"], p["speeds"], p["vo_poses"],
                    p["anchored_frames"], rec["log_bytes"], num(&rec["bytes_per_minute"])
                );
                println!(
                    "  GNSS alone    APE {:.2} m RMS, {:.2} m max (evo, against comma's fused poses)",
                    num(&r["gnss_alone"]["ape_rmse_m"]),
                    num(&r["gnss_alone"]["ape_max_m"])
                );
                let (o, f) = (&r["online"]["compared"], &r["finished"]["compared"]);
                println!(
                    "  online        observable after {:.1} s; APE {:.2} m RMS, {:.2} m max; anchor scale error at the end {}",
                    num(&o["observable_after_s"]), num(&o["ape_rmse_m"]), num(&o["ape_max_m"]),
                    percent(&r["online"]["anchor_scale_error_at_end"])
                );
                println!(
                    "  finished      APE {:.2} m RMS, {:.2} m max ({:.3} m after Sim(3)); scale error {} (σ {}), GNSS latency {:.0} ms",
                    num(&f["ape_rmse_m"]), num(&f["ape_max_m"]), num(&f["ape_after_sim3_m"]), percent(&f["scale_error"]),
                    percent(&r["finished"]["scale_sigma_relative"]).trim_start_matches('+'),
                    1e3 * num(&r["finished"]["gnss_latency_s"])
                );
            }
            _ => {
                let c = &r["clock"];
                let v = &r["speed_check"];
                println!(
                    "  recording     {} candump files, {} frames: {} fixes (cantools: {} valid), {} positions without a fix (cantools: {}), {} speeds of {}; {} bytes ({:.0} per minute)",
                    r["candump_files"], r["can_frames"], rec["fixes"], rec["fixes_valid_by_cantools"],
                    rec["positions_without_fix"], rec["positions_without_fix_by_cantools"], rec["speeds"],
                    rec["speeds_in_reference"], rec["log_bytes"], num(&rec["bytes_per_minute"])
                );
                println!(
                    "  drive         {:.1} min, {:.2} km along the fixes (the module's trip odometer: {:.2} km)",
                    num(&r["drive"]["duration_s"]) / 60.0,
                    num(&r["drive"]["distance_km"]),
                    num(&r["drive"]["module_odometer_km"])
                );
                println!(
                    "  clock         logger − GNSS {:+.3} s at the first fix, {:+.3} s at the end ({:+.3} to {:+.3} s over {} offset records)",
                    num(&c["logger_minus_gnss_first_s"]), num(&c["logger_minus_gnss_last_s"]),
                    num(&c["logger_minus_gnss_min_s"]), num(&c["logger_minus_gnss_max_s"]), c["offset_records"]
                );
                println!(
                    "  speed check   fixes vs OBD PID 0x0D: mean |Δ| {:.2} km/h, correlation {:.4} ({} pairs)",
                    num(&v["mean_abs_diff_kmh"]),
                    num(&v["correlation"]),
                    v["pairs"]
                );
            }
        }
        print_files(r["files"].as_array().map_or(&[][..], Vec::as_slice));
    }
}
