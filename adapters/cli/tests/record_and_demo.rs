//! The `dash2sim` binary end to end — `record` (from files, live, from DBC-defined GNSS) and the `demo` (live, offline, on the real recordings): output shape, exit status and error messages.

mod common;

use std::path::Path;
use std::process::Command;

use common::*;

#[test]
fn demo_runs_the_product_through_real_processes_and_the_truth_and_the_finished_log_verify() {
    let dir = scratch("demo");
    // The default drive, live: a camera process over shared memory, NMEA and CAN over FIFOs.
    let out = dash2sim(&["demo", "--profile", "ideal", "-o", &dir.display().to_string(), "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert!(stderr(&out).contains("[3/7] recording live") && stderr(&out).contains("[7/7]"), "progress on stderr");
    let r = &s["recording"];
    assert_eq!(r["mode"], "live");
    assert_eq!(r["frames_published"], 401, "{r}");
    assert_eq!(r["frames_received"], r["frames_published"], "every published frame logged: {r}");
    assert_eq!((r["inputs_dropped"].as_u64(), r["issues"].as_u64()), (Some(0), Some(0)), "{r}");
    assert_eq!(r["pipeline"]["fixes"], 201, "every fix through the FIFO: {r}");
    assert_eq!(r["pipeline"]["speeds"], 2001, "every CAN speed frame through the FIFO: {r}");
    // Anchoring: observable early, a few metres online, decimetres and < 1 % scale finished.
    let (on, fin) = (&s["anchoring"]["online"], &s["anchoring"]["finished"]);
    assert!(on["observable_after_s"].as_f64().is_some_and(|t| t < 15.0), "{on}");
    assert!(on["ape_rmse_m"].as_f64().is_some_and(|e| e < 4.0), "{on}");
    assert!(fin["ape_rmse_m"].as_f64().is_some_and(|e| e < 0.5), "{fin}");
    assert!(fin["scale_error"].as_f64().is_some_and(|e| e.abs() < 0.01), "{fin}");
    // Tracks: every work-zone class; seen from the ego as good as the tracker fed the truth.
    for class in ["cone", "drum", "barricade", "sign", "arrow_board", "car", "truck"] {
        assert!(s["tracking"]["tracks_by_class"][class].as_u64().is_some_and(|n| n > 0), "{class}: {s}");
    }
    let t = &s["tracking"];
    assert!(
        (t["online"]["mota_seen_from_ego"].as_f64().expect("mota")
            - t["tracker_fed_true_pose"]["mota"].as_f64().expect("mota"))
        .abs()
            < 0.05,
        "{t}"
    );
    assert!(t["finished"]["mota"].as_f64() > t["online"]["mota"].as_f64(), "{t}");
    // The careful drive's truth verifies, and so does the finished log, in both modes.
    let v = &s["verification"];
    for who in ["ground_truth", "finished"] {
        for mode in ["channel_insensitive", "channel_sensitive"] {
            assert_eq!(v[who][mode]["verified"], true, "{who} {mode}: {}", v[who][mode]);
            assert!(v[who][mode]["score"].as_f64().is_some_and(|x| x > 90.0));
        }
    }
    assert!(v["online"]["channel_insensitive"]["score"].is_number());
    assert!(!v["windows_on_device"].as_array().expect("windows").is_empty(), "{v}");
    assert_eq!(s["log"]["damaged"], 0);
    // Every file it names exists.
    let files = s["files"].as_array().expect("files");
    assert!(files.len() >= 15, "{files:?}");
    for f in files {
        let p = Path::new(f["path"].as_str().expect("path"));
        assert!(p.exists(), "{} named but missing", p.display());
    }
    let db = rusqlite::Connection::open(s["nuplan"]["db"].as_str().expect("nuPlan db")).expect("sqlite");
    let poses: i64 = db.query_row("SELECT COUNT(*) FROM ego_pose", [], |r| r.get(0)).expect("ego_pose");
    assert!(poses > 700, "{poses}");
    // The log is what inspect and verify read.
    let log = dir.join("drive.d2slog").display().to_string();
    let inspect: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["inspect", &log, "--json"]).stdout).expect("json");
    for kind in [
        "GnssFix",
        "VehicleSpeed",
        "VoPose",
        "FrameMeta",
        "EgoPose",
        "AnchorEstimate",
        "ClockOffset",
        "Detection3d",
        "Tracks3d",
        "Track2d",
        "Verification",
        "Event",
    ] {
        assert!(inspect["by_type"][kind].as_u64().is_some_and(|n| n > 0), "{kind}: {inspect}");
    }
    let map = dir.join("road.map").display().to_string();
    let verify: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["verify", &log, "--map", &map, "--json"]).stdout).expect("json");
    let score = verify["score"].as_f64().expect("score");
    assert!((score - v["online"]["channel_insensitive"]["score"].as_f64().expect("score")).abs() < 1e-9, "{verify}");
}

#[test]
fn demo_of_a_careless_driver_is_rejected_and_bad_arguments_are_named() {
    let dir = scratch("demo-careless");
    let out = dash2sim(&[
        "demo",
        "--profile",
        "ideal",
        "-o",
        &dir.display().to_string(),
        "--driver",
        "careless",
        "--offline",
        "--quiet",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).is_empty(), "--quiet: {}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(text.contains("careless driver") && text.contains("no at-fault collisions"), "{text}");
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("summary.json")).expect("summary")).expect("json");
    assert_eq!(s["recording"]["mode"], "offline");
    let v = &s["verification"];
    for who in ["ground_truth", "online", "finished"] {
        assert_eq!(v[who]["channel_insensitive"]["verified"], false, "{who}: {}", v[who]);
    }
    // It hit the taper's drums, and the finished log sees the collision: the drum it hits has
    // left the camera's view, but a static object stands where it was seen (on the typical
    // sweep the finished logs see the collision in 84 of the 93 careless drives that collide,
    // 8 before static objects stood).
    assert!(v["finished"]["channel_insensitive"]["metrics"]["no_at_fault_collisions"].as_f64() < Some(1.0), "{v}");
    let out = dash2sim(&["demo", "-o", &dir.display().to_string(), "--duration", "5"]);
    assert!(!out.status.success() && stderr(&out).contains("--duration"));
}

#[test]
fn live_record_closes_its_log_cleanly_on_sigterm() {
    let dir = scratch("live-sigterm");
    let out = dir.join("log");
    let prefix = format!("dash2sim-test/sigterm/{}", std::process::id());
    let mut child = Command::new(env!("CARGO_BIN_EXE_dash2sim"))
        .args(["record", "-o", &out.display().to_string(), "--camera", &prefix, "--origin", "60.2711,24.8572"])
        .env("IOX2_LOG_LEVEL", "Error")
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("record");
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let killed = Command::new("kill").args(["-TERM", &child.id().to_string()]).status().expect("kill");
    assert!(killed.success());
    let status = child.wait().expect("record exits");
    assert!(status.success(), "SIGTERM ends the recording cleanly: {status:?}");
    let files: Vec<_> = std::fs::read_dir(&out)
        .expect("log dir")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "d2slog"))
        .collect();
    assert_eq!(files.len(), 1);
    let log = dash2sim_linux::log::read(&files[0]).expect("a log");
    assert_eq!(log.stats.damaged, 0);
    let last = log.records.last().expect("records");
    assert!(
        matches!(last, dash2sim_core::binlog::Record::Event(e) if e.text.starts_with(b"pipeline finished")),
        "the closing summary is the last record: {last:?}"
    );
}

#[test]
fn live_socketcan_records_or_says_why_it_was_skipped() {
    let dir = scratch("live-vcan");
    let out = dash2sim(&[
        "record",
        "-o",
        &dir.join("log").display().to_string(),
        "--can-iface",
        "vcan0",
        "--origin",
        "60.2711,24.8572",
        "--seconds",
        "1",
    ]);
    let err = stderr(&out);
    if !out.status.success() && err.contains("--can-iface: vcan0") {
        eprintln!("SKIPPED: no CAN interface vcan0 on this machine (no AF_CAN/vcan): {}", err.trim());
        return;
    }
    assert!(out.status.success(), "{err}");
}

#[test]
fn demo_data_names_the_missing_recordings_and_runs_the_rest() {
    let dir = scratch("demo-data");
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).expect("dir");
    let out = dash2sim(&["demo", "--data", &empty.display().to_string(), "-o", &dir.join("out").display().to_string()]);
    assert!(!out.status.success());
    let err = stderr(&out);
    for name in ["comma2k19 is missing", "css is missing", "no recording could run"] {
        assert!(err.contains(name), "{name}: {err}");
    }
    let Some(data) = shared_data() else { return };
    // A folder with an incomplete comma2k19 and the whole CSS drive.
    let partial = dir.join("partial");
    std::fs::create_dir_all(partial.join("comma2k19/expected")).expect("dir");
    std::fs::copy(data.join("comma2k19/raw_can.candump.log"), partial.join("comma2k19/raw_can.candump.log"))
        .expect("copy");
    std::os::unix::fs::symlink(
        data.join("css-electronics-canedge").canonicalize().expect("css folder"),
        partial.join("css-electronics-canedge"),
    )
    .expect("symlink");
    let out_dir = dir.join("partial-out");
    let out = dash2sim(&["demo", "--data", &partial.display().to_string(), "-o", &out_dir.display().to_string(), "-q"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("comma2k19 is missing") && err.contains("global_pose_camera_enu.tum"), "{err}");
    assert!(!err.contains("raw_can.candump.log"), "what is there is not named missing: {err}");
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(text.contains("comma2k19: not run") && text.contains("2161 fixes (cantools: 2161 valid)"), "{text}");
    let s: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("summary.json")).expect("summary")).expect("json");
    assert!(s["recordings"][0]["missing"].is_array() && s["recordings"][1]["recording"]["speeds"] == 4785, "{s}");
    // Both, from the data folder as given.
    let out = dash2sim(&["demo", "--data", &data.display().to_string(), "-o", &dir.join("both").display().to_string()]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(text.contains("comma2k19 —") && text.contains("css —") && !text.contains("not run"), "{text}");
}

#[test]
fn record_reads_gnss_from_dbc_signals_and_names_bad_signal_lists() {
    let dir = scratch("gnss-signals");
    let dbc = write(
        &dir,
        "gps.dbc",
        "VERSION \"\"\n\nBS_:\n\nBU_:\n\n\
         BO_ 2 gnss_time: 6 Vector__XXX\n SG_ Epoch : 8|40@1+ (0.001,1577840400) [0|0] \"sec\" Vector__XXX\n\n\
         BO_ 3 gnss_pos: 8 Vector__XXX\n SG_ PositionValid : 0|1@1+ (1,0) [0|1] \"\" Vector__XXX\n \
         SG_ Latitude : 1|28@1+ (1e-06,-90) [-90|90] \"deg\" Vector__XXX\n \
         SG_ Longitude : 29|29@1+ (1e-06,-180) [-180|180] \"deg\" Vector__XXX\n \
         SG_ PositionAccuracy : 58|6@1+ (1,0) [0|63] \"m\" Vector__XXX\n",
    );
    // Two epochs of CANmod.gps at 60.1 N 24.9 E, 3 m accuracy, the logger 2 s behind GNSS.
    let mut lines = String::new();
    for (k, utc) in [1_700_000_000.0f64, 1_700_000_001.0].iter().enumerate() {
        let time = (((utc - 1_577_840_400.0) * 1e3).round() as u64) << 8 | 1;
        let lat = ((60.1f64 + 90.0) * 1e6).round() as u64;
        let lon = ((24.9f64 + 180.0 + 1e-5 * k as f64) * 1e6).round() as u64;
        let pos = 1 | lat << 1 | lon << 29 | 3 << 58;
        let hex = |v: u64, n: usize| v.to_le_bytes()[..n].iter().map(|b| format!("{b:02X}")).collect::<String>();
        let t = utc - 2.0;
        lines += &format!("({t:.6}) can1 002#{}\n({:.6}) can1 003#{}\n", hex(time, 6), t + 0.001, hex(pos, 8));
    }
    let can = write(&dir, "gps.log", &lines);
    let log = dir.join("gps.d2slog").display().to_string();
    let signals = "lat=gnss_pos.Latitude,lon=gnss_pos.Longitude,valid=gnss_pos.PositionValid,accuracy=gnss_pos.PositionAccuracy,time=gnss_time.Epoch";
    let out = dash2sim(&["record", "-o", &log, "--can", &can, "--dbc", &dbc, "--gnss-signals", signals, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(s["fixes"], 2, "{s}");
    let inspect = dash2sim(&["inspect", &log, "--json"]);
    let i: serde_json::Value = serde_json::from_slice(&inspect.stdout).expect("json");
    // The log is in GNSS time: its first fix at UTC 1 700 000 000 s, received 2 s earlier
    // on the logger's clock.
    assert!(i["t_start"].as_f64().is_some_and(|t| (t - 1_700_000_000.0).abs() < 0.01), "{i}");
    for (bad, says) in [
        ("lon=gnss_pos.Longitude", "lat=MESSAGE.SIGNAL is required"),
        ("lat=gnss_pos.Latitude,lon=gnss_pos.Longitude,speed=gnss_pos.Latitude", "unknown key \"speed\""),
        ("lat=gnss_pos.Latitude,lon=gnss_time.Epoch", "lat and lon must be in one message"),
        (
            "lat=gnss_pos.Latitude,lon=gnss_pos.Longitude,valid=gnss_time.Epoch",
            "valid must be in the latitude's message",
        ),
        ("lat=gnss_pos.Nope,lon=gnss_pos.Longitude", "has no signal \"Nope\""),
        ("lat=gnss_pos,lon=gnss_pos.Longitude", "expected MESSAGE.SIGNAL"),
    ] {
        let out = dash2sim(&["record", "-o", &log, "--can", &can, "--dbc", &dbc, "--gnss-signals", bad]);
        assert!(!out.status.success() && stderr(&out).contains(says), "{bad}: {}", stderr(&out));
    }
    let out = dash2sim(&["record", "-o", &log, "--can", &can, "--gnss-signals", signals]);
    let e = stderr(&out);
    assert!(!out.status.success() && e.contains("--dbc: ") && e.contains("no DBC files were given"), "{e}");
}
