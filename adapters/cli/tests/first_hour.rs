//! What a new user trips over in a first hour (issue #36), each detour reproduced: the
//! truth's time base and origin against a recorded log, a live recording with no origin,
//! errors that name their way out, a log's own events, a CAN module at another base id.

mod common;

use common::*;
use dash2sim_linux::log;

/// The value after `--option` (or `--option=`) in generate's hints.
fn hint<'a>(text: &'a str, option: &str) -> &'a str {
    let at = text.find(option).unwrap_or_else(|| panic!("no {option} in {text}"));
    let rest = text[at + option.len()..].trim_start_matches(['=', ' ']);
    rest.split(|c: char| c.is_whitespace() || c == ')').next().unwrap_or_default()
}

#[test]
fn generate_map_record_export_and_ape_against_the_truth_with_only_what_generate_says() {
    let dir = scratch("first-hour-ape");
    let drive = dir.join("drive");
    let d = |name: &str| drive.join(name).display().to_string();
    let out =
        dash2sim(&["scenario", "generate", "-o", &drive.display().to_string(), "--seed", "1", "--receiver", "good"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    let (origin, t_offset) = (hint(&said, "--origin"), hint(&said, "--t-offset"));
    // The origin with its height (the drive's ENU origin is 20 m above the ellipsoid).
    assert_eq!(origin, "60.2711,24.8572,20", "{said}");
    assert_eq!(t_offset, "-1780300800", "{said}");

    let map = dir.join("road.map").display().to_string();
    let out = dash2sim(&["map", "build", &d("road.osm"), "-o", &map, "--origin", origin]);
    assert!(out.status.success(), "{}", stderr(&out));
    let info = dash2sim(&["map", "info", &map, "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).expect("map info JSON");
    assert_eq!(info["origin"]["height_m"], 20.0, "the tile keeps the height");

    let rec = dir.join("rec.d2slog").display().to_string();
    let out = dash2sim(&[
        "record",
        "-o",
        &rec,
        "--vo",
        &d("vo.csv"),
        "--nmea",
        &d("gnss.serial.log"),
        "--can",
        &d("speed.can.log"),
        "--map",
        &map,
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let tum = dir.join("rec.tum").display().to_string();
    let out = dash2sim(&["export", &rec, "--tum", &tum]);
    assert!(out.status.success(), "{}", stderr(&out));

    // Without the offset the files do not overlap in time, and the error says so and how.
    let out = dash2sim(&["traj", "ape", &d("ego.tum"), &tum]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(e.contains("only 0 poses matched") && e.contains("do not overlap"), "{e}");
    assert!(e.contains("--t-offset"), "the flag that shifts the estimate: {e}");
    let range = e.split("any time offset from ").nth(1).expect("the offsets that would do");
    let bound = |i: usize| range.split(' ').nth(i).and_then(|v| v.parse::<f64>().ok()).expect("a number");
    assert!((bound(0)..=bound(2)).contains(&-1780300800.0), "{e}");

    // With it, the anchoring error: metres, not the 20 m of a height-0 origin.
    let max_diff = hint(&said, "--max-diff");
    let out = dash2sim(&[
        "traj",
        "ape",
        &d("ego.tum"),
        &tum,
        &format!("--t-offset={t_offset}"),
        "--max-diff",
        max_diff,
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let ape: serde_json::Value = serde_json::from_slice(&out.stdout).expect("ape JSON");
    assert!(ape["matched"].as_u64().is_some_and(|n| n > 100), "{ape}");
    let rmse = ape["stats"]["rmse"].as_f64().expect("rmse");
    assert!(rmse < 8.0, "APE {rmse} m");
    // The negative offset also parses as a separate argument.
    let out = dash2sim(&["traj", "ape", &d("ego.tum"), &tum, "--t-offset", t_offset, "--max-diff", max_diff]);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn a_live_recording_without_an_origin_takes_the_first_fix() {
    let dir = scratch("first-hour-live");
    let out = dash2sim(&["scenario", "generate", "-o", &dir.join("drive").display().to_string(), "--duration", "10"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let logs = dir.join("logs");
    let nmea = dir.join("drive/gnss.nmea").display().to_string();
    let out = dash2sim(&["record", "-o", &logs.display().to_string(), "--serial", &nmea, "--seconds", "2", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("summary JSON");
    assert!(summary["fixes"].as_u64().is_some_and(|n| n > 10), "{summary}");
    let files: Vec<_> = walk(&logs).into_iter().filter(|p| p.extension().is_some_and(|e| e == "d2slog")).collect();
    assert_eq!(files.len(), 1, "{files:?}");
    let log = log::read(&files[0]).expect("a log");
    let header = log.header.expect("a header");
    // The first GGA of the capture: 60.2711… N, 24.8572… E (the drive starts at its origin).
    let first = std::fs::read_to_string(&nmea).expect("nmea");
    let gga = first.lines().find(|l| l.starts_with("$GPGGA")).expect("a GGA");
    let f: Vec<&str> = gga.split(',').collect();
    let degrees = |v: &str, d: usize| v[..d].parse::<f64>().expect("deg") + v[d..].parse::<f64>().expect("min") / 60.0;
    let (lat, lon) = (degrees(f[2], 2), degrees(f[4], 3));
    assert!((header.origin[0] as f64 * 1e-7 - lat).abs() < 1e-6, "{:?} vs {lat}", header.origin);
    assert!((header.origin[1] as f64 * 1e-7 - lon).abs() < 1e-6, "{:?} vs {lon}", header.origin);
    assert!(log.records.iter().any(|r| matches!(r, dash2sim_core::binlog::Record::GnssFix(_))));

    // Nothing to take an origin from: the error names every way.
    let out = dash2sim(&["record", "-o", &logs.display().to_string(), "--camera", "dash2sim-nobody", "--seconds", "1"]);
    assert!(!out.status.success());
    let e = stderr(&out);
    for way in ["--origin", "--map", "--serial", "--gnss-signals"] {
        assert!(e.contains(way), "{way} missing from: {e}");
    }
}

#[test]
fn nothing_to_record_names_the_live_sources_too() {
    let dir = scratch("first-hour-nothing");
    let out = dash2sim(&["record", "-o", &dir.join("x.d2slog").display().to_string()]);
    assert!(!out.status.success());
    let e = stderr(&out);
    for way in
        ["--vo", "--nmea", "--can", "--detections", "--replay", "--camera", "--serial", "--can-iface", "--can-replay"]
    {
        assert!(e.contains(way), "{way} missing from: {e}");
    }
}

#[test]
fn inspect_events_shows_what_the_log_says() {
    let dir = scratch("first-hour-events");
    let out = demo_ideal_offline(&dir, "20");
    assert!(out.status.success(), "{}", stderr(&out));
    let log = dir.join("drive.d2slog").display().to_string();
    let plain = dash2sim(&["inspect", &log]);
    let text = String::from_utf8_lossy(&plain.stdout).into_owned();
    assert!(!text.contains("  events "), "events only when asked: {text}");
    let out = dash2sim(&["inspect", &log, "--events", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let events = v["events"].as_array().expect("events");
    assert!(!events.is_empty(), "{v}");
    assert_eq!(Some(events.len() as u64), v["by_type"]["Event"].as_u64(), "every event record listed");
    for e in events {
        assert!(["unknown", "debug", "info", "warning", "error", "fatal"].contains(&e["level"].as_str().unwrap_or("")));
        assert!(e["t_s"].as_f64().is_some() && e["text"].as_str().is_some_and(|t| !t.is_empty()), "{e}");
    }
    let human = dash2sim(&["inspect", &log, "--events"]);
    let text = String::from_utf8_lossy(&human.stdout).into_owned();
    let first = events[0]["text"].as_str().expect("text");
    assert!(text.contains(&format!("events      {}", events.len())) && text.contains(first), "{text}");
}

/// A CANmod.gps position frame (canmod-gps.dbc's gnss_pos) at `id`, as a candump line.
fn canmod_position(t: f64, id: u32, lat: f64, lon: f64) -> String {
    let lat_raw = ((lat + 90.0) / 1e-6).round() as u64;
    let lon_raw = ((lon + 180.0) / 1e-6).round() as u64;
    let bits: u64 = 1 | (lat_raw << 1) | (lon_raw << 29) | (5 << 58);
    let hex: String = bits.to_le_bytes().iter().map(|b| format!("{b:02X}")).collect();
    format!("({t:.6}) can0 {id:03X}#{hex}")
}

#[test]
fn a_can_gps_module_at_another_base_id_is_named_and_read_with_an_id_offset() {
    let dir = scratch("first-hour-can");
    let dbc = write(
        &dir,
        "canmod-gps.dbc",
        "VERSION \"\"\n\nBS_:\n\nBU_:\n\nBO_ 3 gnss_pos: 8 Vector__XXX\n \
         SG_ PositionValid : 0|1@1+ (1,0) [0|1] \"\" Vector__XXX\n \
         SG_ Latitude : 1|28@1+ (1e-06,-90) [-90|90] \"deg\" Vector__XXX\n \
         SG_ Longitude : 29|29@1+ (1e-06,-180) [-180|180] \"deg\" Vector__XXX\n \
         SG_ PositionAccuracy : 58|6@1+ (1,0) [0|63] \"m\" Vector__XXX\n",
    );
    // The module configured to start at 0x65: gnss_pos is 0x67 on this bus.
    let lines: Vec<String> = (0..20)
        .map(|i| canmod_position(1000.0 + f64::from(i) * 0.2, 0x67, 55.6761 + f64::from(i) * 1e-5, 12.5683))
        .collect();
    let capture = write(&dir, "bus.log", &(lines.join("\n") + "\n"));
    let signals = "lat=gnss_pos.Latitude,lon=gnss_pos.Longitude,valid=gnss_pos.PositionValid";
    let out_path = dir.join("can.d2slog").display().to_string();
    let record = |dbc: &str| {
        dash2sim(&["record", "-o", &out_path, "--can", &capture, "--dbc", dbc, "--gnss-signals", signals, "--json"])
    };
    let out = record(&dbc);
    assert!(!out.status.success(), "no fix is read at the DBC's ids");
    let e = stderr(&out);
    assert!(e.contains("no frame with id 0x003") && e.contains("ids seen: 0x067–0x067"), "{e}");
    assert!(e.contains("@+OFFSET"), "{e}");

    let out = record(&format!("{dbc}@+0x64"));
    assert!(out.status.success(), "{}", stderr(&out));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("summary JSON");
    assert_eq!(summary["fixes"], 20, "{summary}");
    let bad = record(&format!("{dbc}@+zz"));
    assert!(stderr(&bad).contains("id offset"), "{}", stderr(&bad));
}
