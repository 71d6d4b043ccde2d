//! The `dash2sim` binary end to end: output shape, exit status and error messages.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dash2sim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dash2sim")).args(args).output().expect("binary runs")
}

fn fixture(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/drive").join(name).display().to_string()
}

/// A scratch folder unique to one test.
fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("dash2sim-cli-{}-{test}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p.display().to_string()
}

/// `scenario generate` of drive `seed` on the ideal profile (the tests that pin its
/// figures test the tools, not the sensors) into `dir`.
fn generate_ideal(dir: &Path, seed: &str, duration: &str) -> Output {
    let dir = dir.display().to_string();
    dash2sim(&["scenario", "generate", "--profile", "ideal", "-o", &dir, "--seed", seed, "--duration", duration])
}

/// `demo --offline --json` of seed 1 on the ideal profile into `dir`.
fn demo_ideal_offline(dir: &Path, duration: &str) -> Output {
    let dir = dir.display().to_string();
    dash2sim(&["demo", "--profile", "ideal", "-o", &dir, "--duration", duration, "--offline", "--json"])
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn ape_json_has_alignment_stats_and_count() {
    let out = dash2sim(&[
        "traj",
        "ape",
        &fixture("truth.tum"),
        &fixture("gnss.tum"),
        "--align",
        "sim3",
        "--max-diff",
        "0.026",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert_eq!(v["alignment"]["R"].as_array().map(Vec::len), Some(3));
    assert_eq!(v["alignment"]["t"].as_array().map(Vec::len), Some(3));
    assert!(v["alignment"]["s"].as_f64().is_some_and(|s| (s - 1.0).abs() < 0.05));
    for key in ["rmse", "mean", "median", "std", "min", "max", "sse"] {
        assert!(v["stats"][key].as_f64().is_some_and(f64::is_finite), "stats.{key}");
    }
    assert_eq!(v["n"].as_u64(), Some(400));
}

#[test]
fn rpe_in_metres_and_all_pairs() {
    // Both files carry identity orientations, so the relative error is the error of
    // 20 m displacements: a few decimetres of GNSS noise.
    let args = [
        "traj",
        "rpe",
        &fixture("truth.tum"),
        &fixture("gnss.tum"),
        "--max-diff",
        "0.026",
        "--delta",
        "20",
        "--unit",
        "m",
    ];
    let consecutive = dash2sim(&[&args[..], &["--json"]].concat());
    let all = dash2sim(&[&args[..], &["--all-pairs", "--json"]].concat());
    assert!(consecutive.status.success() && all.status.success(), "{}", stderr(&all));
    let c: serde_json::Value = serde_json::from_slice(&consecutive.stdout).expect("JSON");
    let a: serde_json::Value = serde_json::from_slice(&all.stdout).expect("JSON");
    let (nc, na) = (c["n"].as_u64().expect("n"), a["n"].as_u64().expect("n"));
    // ~530 m of path: 26 consecutive 20 m segments; all pairs start at almost every pose.
    assert!((20..=30).contains(&nc) && na > 300, "{nc} {na}");
    assert!(a["stats"]["mean"].as_f64().is_some_and(|m| m > 0.01 && m < 1.0), "{a}");
}

#[test]
fn malformed_line_is_reported_with_file_and_line() {
    let dir = scratch("malformed");
    let bad = write(&dir, "bad.tum", "# ok\n0 0 0 0 0 0 0 1\n1 0 0 zero 0 0 0 1\n");
    let out = dash2sim(&["traj", "ape", &bad, &bad]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("bad.tum:3: not a number: \"zero\""), "{}", stderr(&out));
}

#[test]
fn non_finite_values_out_of_order_and_empty_files_are_errors() {
    let dir = scratch("bad-values");
    let good = write(&dir, "good.tum", "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n3 3 1 0 0 0 0 1\n");
    for (name, text, expect) in [
        ("nan.tum", "0 0 0 0 0 0 0 1\n1 NaN 0 0 0 0 0 1\n", "nan.tum:2: not a finite number"),
        ("inf.tum", "0 0 0 0 0 0 0 1\n1 inf 0 0 0 0 0 1\n", "inf.tum:2: not a finite number"),
        ("order.tum", "0 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n1 2 0 0 0 0 0 1\n", "order.tum:3: timestamp 1 is earlier"),
        ("empty.tum", "", "empty.tum: no poses in file"),
        ("short.tum", "0 0 0 0 0 0 1\n", "short.tum:1: expected 8 values, found 7"),
    ] {
        let path = write(&dir, name, text);
        let out = dash2sim(&["traj", "ape", &good, &path]);
        assert!(!out.status.success(), "{name} accepted");
        assert!(stderr(&out).contains(expect), "{name}: {}", stderr(&out));
    }
}

#[test]
fn too_few_matched_poses_is_an_error() {
    let dir = scratch("few");
    let a = write(&dir, "a.tum", "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n");
    let b = write(&dir, "b.tum", "0 0 0 0 0 0 0 1\n1.5 1 0 0 0 0 0 1\n2.5 2 0 0 0 0 0 1\n");
    let out = dash2sim(&["traj", "ape", &a, &b]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("only 1 poses matched"), "{}", stderr(&out));
    let out = dash2sim(&["traj", "ape", "--format", "kitti", &a, &b]);
    assert!(!out.status.success(), "a TUM file is not a KITTI file");
    assert!(stderr(&out).contains("expected 12 values"), "{}", stderr(&out));
}

#[test]
fn degenerate_alignment_is_an_error_not_nan() {
    let dir = scratch("collinear");
    let line = write(&dir, "line.tum", "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n3 3 0 0 0 0 0 1\n");
    let out = dash2sim(&["traj", "ape", &line, &line, "--align", "sim3"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("degenerate"), "{}", stderr(&out));
}

#[test]
fn missing_file_and_bad_options() {
    let out = dash2sim(&["traj", "ape", "/nonexistent/a.tum", "/nonexistent/b.tum"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("/nonexistent/a.tum"), "{}", stderr(&out));
    let out = dash2sim(&["traj", "rpe", &fixture("truth.tum"), &fixture("vo.tum"), "--delta", "0.5"]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("whole number of frames"), "{}", stderr(&out));
    let out = dash2sim(&["traj", "ape", &fixture("truth.tum"), &fixture("vo.tum"), "--align", "bogus"]);
    assert!(!out.status.success());
}

#[test]
fn every_subcommand_has_help() {
    for args in [
        &["--help"][..],
        &["traj", "--help"],
        &["traj", "ape", "--help"],
        &["traj", "rpe", "--help"],
        &["anchor", "--help"],
        &["nmea", "decode", "--help"],
        &["can", "--help"],
        &["can", "decode", "--help"],
        &["mot", "eval", "--help"],
        &["track2d", "--help"],
    ] {
        let out = dash2sim(args);
        assert!(out.status.success(), "{args:?}");
        assert!(String::from_utf8_lossy(&out.stdout).contains("Usage"), "{args:?}");
    }
}

#[test]
fn anchor_writes_a_metric_track_close_to_the_truth() {
    let dir = scratch("anchor");
    let out_path = dir.join("anchored.tum").display().to_string();
    let out = dash2sim(&[
        "anchor",
        "--vo",
        &fixture("vo.tum"),
        "--gnss",
        &fixture("gnss.tum"),
        "--speed",
        &fixture("speed.csv"),
        "-o",
        &out_path,
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    assert!(summary["observable_after_s"].as_f64().is_some_and(|s| s < 10.0), "{summary}");
    // The fixture's VO unit is 0.5 m (drifting by +1 %/min over 40 s).
    let s = summary["estimate"]["s"].as_f64().expect("scale");
    assert!((s / 0.50333 - 1.0).abs() < 0.005, "scale {s}");
    // And the anchored track is no worse than the raw GNSS fixes.
    let ape = |est: &str, max_diff: &str| -> f64 {
        let o = dash2sim(&["traj", "ape", &fixture("truth.tum"), est, "--max-diff", max_diff, "--json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        serde_json::from_slice::<serde_json::Value>(&o.stdout).expect("JSON")["stats"]["rmse"].as_f64().expect("rmse")
    };
    let anchored = ape(&out_path, "0.001");
    let raw = ape(&fixture("gnss.tum"), "0.026");
    assert!(anchored <= 1.05 * raw, "anchored {anchored} m vs raw GNSS {raw} m");
}

#[test]
fn anchor_rejects_bad_speed_files() {
    let dir = scratch("speed");
    let bad = write(&dir, "speed.csv", "t,v\n0,1\n1,x\n");
    let out = dash2sim(&["anchor", "--vo", &fixture("vo.tum"), "--gnss", &fixture("gnss.tum"), "--speed", &bad]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("speed.csv:3"), "{}", stderr(&out));
}

/// `$body*HH` with a correct checksum.
fn nmea(body: &str) -> String {
    format!("${body}*{:02X}", body.bytes().fold(0u8, |a, b| a ^ b))
}

#[test]
fn nmea_decode_reports_bad_input_by_line_and_keeps_the_rest() {
    let dir = scratch("nmea");
    let lines = [
        nmea("GPGGA,120000.00,4807.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,"),
        nmea("GPRMC,120000.00,A,4807.0380,N,01131.0000,E,022.4,084.4,230394,003.1,W"),
        "$GPGGA,120001.00,4807.0390,N,01131.0010,E,1,08,0.9,545.5,M,46.9,M,,*00".to_owned(),
        "$GPRMC,120001.00,A,4807.03".to_owned(),
        nmea("GPGGA,120002.00,9507.0380,N,01131.0000,E,1,08,0.9,545.4,M,46.9,M,,"),
        "garbage !@# \u{1}\u{2} not nmea".to_owned(),
        nmea("GPGGA,120003.00,4807.0400,N,01131.0020,E,1,08,0.9,545.6,M,46.9,M,,"),
        nmea("GPRMC,120003.00,A,4807.0400,N,01131.0020,E,022.4,084.4,230394,003.1,W"),
    ];
    let file = write(&dir, "bad.nmea", &(lines.join("\r\n") + "\r\n"));
    let out = dash2sim(&["nmea", "decode", &file, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    for expected in [
        "bad.nmea:3: bad checksum",
        "bad.nmea:4: field 4 is malformed",
        "bad.nmea:5: field 2 is out of range",
        "bad.nmea:6: non-printable byte",
    ] {
        assert!(err.contains(expected), "missing {expected:?} in {err}");
    }
    let objects: Vec<serde_json::Value> =
        String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).expect("JSON line")).collect();
    let fixes: Vec<_> = objects.iter().filter(|o| o["class"] == "TPV" && o.get("lat").is_some()).collect();
    assert_eq!(fixes.len(), 2, "the two good epochs survive: {objects:?}");
    assert_eq!(fixes[1]["time"], "1994-03-23T12:00:03.000Z");
    assert!((fixes[1]["speed"].as_f64().expect("speed") - 22.4 * 1852.0 / 3600.0).abs() < 1e-9);
    let summary = objects.last().expect("summary");
    assert_eq!(summary["class"], "SUMMARY");
    assert_eq!(summary["rejected"]["bad_checksum"], 1);
    assert_eq!(summary["rejected"]["bad_fields"], 2);
    assert_eq!(summary["rejected"]["binary"], 1);
}

#[test]
fn can_decode_reports_bad_lines_and_lost_fast_packets_and_keeps_the_rest() {
    let dir = scratch("can");
    let dbc = write(
        &dir,
        "speed.dbc",
        "VERSION \"\"\n\nBS_:\n\nBU_: XXX\n\nBO_ 180 SPEED: 8 XXX\n SG_ SPEED : 47|16@0+ (0.01,0) [0|250] \"km/h\" XXX\n",
    );
    let log = [
        "(1410714882.622188) can0 09F80102#36729A16021AB80D",
        "(1410714882.700000) can0 09F80102#3672",
        "this is not candump",
        "(1410714882.800000) can0 0DF80502#202FEBC73F704B43",
        "(1410714882.900000) can0 0DF80502#2124C0751E3CEB42",
        "(1410714884.000000) can0 7E8#03410D3900000000",
        "(1410714884.100000) can0 0B4#00000000001E1400",
        "(1410714884.200000) can0 0CFEF100#FF0032FFFFFFFFFF",
        "(1410714884.300000) can0 123##1001122",
    ];
    let file = write(&dir, "bus.log", &(log.join("\n") + "\n"));
    let out = dash2sim(&["can", "decode", &file, "--dbc", &dbc, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    for expected in [
        "bus.log:2: PGN 129025 needs 8 bytes, got 2",
        "bus.log:3: malformed CAN id",
        "bus.log:6: PGN 129029 from 2: fast-packet message dropped after 2 frames: frames stopped (timeout)",
        "bus.log:9: CAN FD frames are not supported",
    ] {
        assert!(err.contains(expected), "missing {expected:?} in {err}");
    }
    let objects: Vec<serde_json::Value> =
        String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).expect("JSON line")).collect();
    assert_eq!(objects.len(), 5, "{objects:?}");
    let position = &objects[0];
    assert_eq!(
        (&position["t"], &position["bus"], &position["id"]),
        (&1_410_714_882.622_188.into(), &"can0".into(), &"0x09F80102".into())
    );
    assert_eq!(
        (&position["src"], &position["pgn"], &position["fields"]["Latitude"]),
        (&2.into(), &129_025.into(), &37.922_053_4.into())
    );
    assert_eq!((&objects[1]["pid"], &objects[1]["fields"]["Vehicle Speed"]), (&13.into(), &57.into()));
    assert_eq!((&objects[2]["message"], &objects[2]["fields"]["SPEED"]), (&"SPEED".into(), &77.0.into()));
    assert_eq!(
        (&objects[3]["pgn"], &objects[3]["fields"]["Wheel-Based Vehicle Speed"]),
        (&65_265.into(), &(50.0 / 3.6).into())
    );
    let summary = &objects[4];
    assert_eq!(
        (&summary["class"], &summary["frames"], &summary["bad_lines"]),
        (&"SUMMARY".into(), &7.into(), &2.into())
    );
    assert_eq!((&summary["bad_frames"], &summary["fast_packet"]["timed_out"]), (&1.into(), &1.into()));
}

#[test]
fn can_decode_names_a_bad_dbc_and_a_missing_capture() {
    let dir = scratch("can-errors");
    let dbc = write(&dir, "bad.dbc", "BO_ banana");
    let log = write(&dir, "bus.log", "(1.0) can0 123#00\n");
    let out = dash2sim(&["can", "decode", &log, "--dbc", &dbc]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("bad.dbc: not a valid DBC file"), "{}", stderr(&out));
    let out = dash2sim(&["can", "decode", &dir.join("missing.log").display().to_string()]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("missing.log"), "{}", stderr(&out));
}

#[test]
fn mot_eval_scores_and_names_bad_lines() {
    let dir = scratch("mot");
    let gt =
        write(&dir, "gt.txt", "1,1,10,10,20,40,1,-1,-1,-1\n1,2,100,10,20,40,1,-1,-1,-1\n2,1,12,10,20,40,1,-1,-1,-1\n");
    let test = write(
        &dir,
        "test.txt",
        "1,7,10,10,20,40,-1,-1,-1,-1\n2,7,12,10,20,40,-1,-1,-1,-1\n2,8,300,10,20,40,-1,-1,-1,-1\n",
    );
    let out = dash2sim(&["mot", "eval", &gt, &test, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    // 3 objects, 2 matched (id 7 on object 1 twice), 1 miss, 1 false positive.
    assert_eq!(
        (&summary["num_matches"], &summary["num_misses"], &summary["num_false_positives"]),
        (&2.0.into(), &1.0.into(), &1.0.into())
    );
    assert_eq!(summary["mota"], serde_json::json!(1.0 - 2.0 / 3.0));
    let bad = write(&dir, "bad.txt", "1,1,10,10,20,40,1\n2,1,10,10,0,40,1\n");
    let out = dash2sim(&["mot", "eval", &gt, &bad]);
    assert!(!out.status.success());
    assert!(stderr(&out).contains("bad.txt:2: box has zero or negative size"), "{}", stderr(&out));
    let bad = write(&dir, "nan.txt", "1,1,x,10,20,40\n");
    let out = dash2sim(&["mot", "eval", &gt, &bad]);
    assert!(stderr(&out).contains("nan.txt:1: column 3 \"x\" is not a number"), "{}", stderr(&out));
}

#[test]
fn track2d_keeps_one_id_along_a_moving_box_and_skips_rows_out_of_order() {
    let dir = scratch("track2d");
    let mut lines: Vec<String> = (1..=5).map(|f| format!("{f},-1,{},10,20,40,0.9,-1,-1,-1", 10 + 2 * f)).collect();
    lines.push("2,-1,14,10,20,40,0.9,-1,-1,-1".to_owned());
    let dets = write(&dir, "dets.txt", &(lines.join("\n") + "\n"));
    let tracks = dir.join("tracks.txt").display().to_string();
    let out = dash2sim(&["track2d", &dets, "-o", &tracks]);
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(stderr(&out).contains("row 6: frame 2 after frame 5, skipped"), "{}", stderr(&out));
    let text = std::fs::read_to_string(&tracks).expect("tracks");
    let rows: Vec<Vec<&str>> = text.lines().map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 5, "{text}");
    assert!(rows.iter().all(|r| r[1] == "1"), "one id: {text}");
    let x: f64 = rows[4][2].parse().expect("x");
    assert!((x - 20.0).abs() < 0.5, "follows the box: {x}");
}

#[test]
fn scenario_files_round_trip_through_the_other_commands() {
    let dir = scratch("scenario");
    let out = generate_ideal(&dir, "3", "12");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |name: &str| dir.join(name).display().to_string();
    for name in ["ego.tum", "vo.tum", "gnss.tum", "gnss.nmea", "speed.csv", "objects.csv", "detections3d.csv"] {
        assert!(dir.join(name).is_file(), "{name} missing");
    }
    // Every GNSS fix (5 Hz for 12 s, both ends) decodes as NMEA with nothing rejected.
    let out = dash2sim(&["nmea", "decode", &path("gnss.nmea"), "--json"]);
    let text = String::from_utf8_lossy(&out.stdout);
    let summary: serde_json::Value = text.lines().last().and_then(|l| serde_json::from_str(l).ok()).expect("summary");
    assert_eq!(summary["fixes"], 61, "{summary}");
    assert!(summary["rejected"].as_object().expect("counts").values().all(|v| v == 0), "{summary}");
    assert!(stderr(&out).is_empty(), "{}", stderr(&out));
    // The GNSS track is metres (not kilometres) off the ego truth.
    let out = dash2sim(&["traj", "ape", &path("ego.tum"), &path("gnss.tum"), "--max-diff", "0.1", "--json"]);
    let ape: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let rmse = ape["stats"]["rmse"].as_f64().expect("rmse");
    assert!((2.0..40.0).contains(&rmse) && ape["matched"] == 61, "{ape}");
    // The 2D ground truth is a valid MOTChallenge file: against itself it scores perfectly.
    let out = dash2sim(&["mot", "eval", &path("gt2d.txt"), &path("gt2d.txt"), "--json"]);
    let m: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!((m["mota"].as_f64(), m["num_switches"].as_f64()), (Some(1.0), Some(0.0)), "{m}");
    // The 2D detections feed track2d.
    let tracks = path("tracks2d.txt");
    assert!(dash2sim(&["track2d", &path("det2d.txt"), "-o", &tracks]).status.success());
    let m: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["mot", "eval", &path("gt2d.txt"), &tracks, "--json"]).stdout).expect("json");
    assert!(m["num_matches"].as_f64().is_some_and(|n| n > 50.0), "{m}");
    // One node every 10 m of road and one way.
    let osm = std::fs::read_to_string(dir.join("road.osm")).expect("osm");
    assert_eq!(osm.matches("<node ").count(), 116, "1150 m of road");
    assert!(osm.contains("<tag k=\"lanes:forward\" v=\"2\"/>"));
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("scenario.json")).expect("json")).expect("json");
    assert_eq!((info["seed"].as_u64(), info["counts"]["frames"].as_u64()), (Some(3), Some(121)));
}

#[test]
fn scenario_eval_reports_the_figures_and_bad_durations_are_refused() {
    // The tracker's own figures, on the ideal profile's detections.
    let out = dash2sim(&["scenario", "eval", "--profile", "ideal", "--seed", "2", "--duration", "30", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(r["profile"], "ideal");
    let get = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
    assert!(get("rmse_filtered_m") < get("rmse_detections_m") && get("static_accuracy") > 0.9, "{r}");
    assert!(r["metrics"]["idf1"].as_f64().is_some_and(|v| v > 0.5), "{r}");
    for bad in ["0", "nan", "1000"] {
        let out = dash2sim(&["scenario", "eval", "--duration", bad]);
        assert!(!out.status.success() && stderr(&out).contains("--duration"), "{bad}: {}", stderr(&out));
    }
}

#[test]
fn map_build_and_info_describe_the_tile_and_refuse_a_corrupted_one() {
    let dir = scratch("map");
    let osm = write(
        &dir,
        "small.osm",
        r#"<osm version="0.6">
  <node id="1" lat="60.0000" lon="24.0000"/>
  <node id="2" lat="60.0010" lon="24.0000"/>
  <node id="3" lat="60.0010" lon="24.0020"/>
  <way id="5"><nd ref="1"/><nd ref="2"/><nd ref="3"/><tag k="highway" v="primary"/><tag k="lanes" v="2"/><tag k="maxspeed" v="50"/></way>
  <way id="6"><nd ref="2"/><nd ref="404"/><tag k="highway" v="residential"/><tag k="width" v="abc"/></way>
  <way id="7"><nd ref="1"/><nd ref="3"/><tag k="highway" v="footway"/></way>
</osm>"#,
    );
    let map = dir.join("small.map").display().to_string();
    let out = dash2sim(&["map", "build", &osm, "-o", &map, "--origin", "60,24"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("way 6 references missing node 404") && err.contains("way 6: width"), "{err}");
    let out = dash2sim(&["map", "info", &map, "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(info["osm"], serde_json::json!({"nodes": 3, "ways": 3, "highway_ways": 3, "relations": 0}));
    assert_eq!((info["origin"]["lat"].as_f64(), info["lanes"].as_u64()), (Some(60.0), Some(2)));
    // Two lanes along 111 m north then 111 m east.
    let km = info["lane_km"].as_f64().expect("km");
    assert!((km - 2.0 * 0.2225).abs() < 0.01, "{km}");
    assert_eq!(info["bytes"].as_u64(), std::fs::metadata(&map).ok().map(|m| m.len()));
    // One flipped byte: a clear error, not a crash.
    let mut bytes = std::fs::read(&map).expect("tile");
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    let bad = write(&dir, "bad.map", "");
    std::fs::write(&bad, &bytes).expect("write");
    let out = dash2sim(&["map", "info", &bad]);
    assert!(!out.status.success() && stderr(&out).contains("CRC-32C mismatch"), "{}", stderr(&out));
    let out = dash2sim(&["map", "build", &osm, "-o", &map, "--origin", "91,0"]);
    assert!(!out.status.success() && stderr(&out).contains("--origin"), "{}", stderr(&out));
}

#[test]
fn verify_scores_a_generated_drive_and_names_bad_inputs() {
    let dir = scratch("verify");
    let drive = dir.join("drive");
    let out = generate_ideal(&drive, "1", "10");
    assert!(out.status.success(), "{}", stderr(&out));
    let map = dir.join("road.map").display().to_string();
    let road = drive.join("road.osm").display().to_string();
    let out = dash2sim(&["map", "build", &road, "-o", &map, "--origin", "60.2711,24.8572"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (ego, objects) = (drive.join("ego.tum").display().to_string(), drive.join("objects.csv").display().to_string());
    let poses = dir.join("poses.csv").display().to_string();
    for sensitive in [false, true] {
        let mut args = vec!["verify", "--map", &map, "--ego", &ego, "--objects", &objects, "--json", "--poses", &poses];
        if sensitive {
            args.push("--channel-sensitive");
        }
        let out = dash2sim(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        // The first 10 s: lane keeping at 22 m/s behind traffic, before the work zone.
        assert_eq!(report["verified"], true, "{report}");
        assert!(report["score"].as_f64().is_some_and(|s| s > 90.0), "{report}");
        let metrics = report["metrics"].as_object().expect("metrics");
        assert_eq!(metrics.len(), 8);
        assert_eq!(report["poses"], 101);
        assert_eq!(report["channel_sensitive"], sensitive);
    }
    let csv = std::fs::read_to_string(&poses).expect("per-pose CSV");
    assert_eq!(csv.lines().count(), 102, "header and one row per pose");
    assert!(csv.lines().nth(1).is_some_and(|l| l.split(',').count() == 14));

    // Bad inputs: a clear error naming the file and line, never a crash.
    let bad_ego = write(&dir, "bad.tum", "0.0 1 2 0 0 0 0 1\n0.1 1 2 zero 0 0 0 1\n");
    let out = dash2sim(&["verify", "--map", &map, "--ego", &bad_ego]);
    assert!(!out.status.success() && stderr(&out).contains("bad.tum:2"), "{}", stderr(&out));
    let bad_objects = write(&dir, "bad.csv", "frame,t_s,id,class,x,y,z,yaw,l,w,h,vx,vy,static,visible\n0,0.0,1,cone,1,2,0,0,0.4,0.4,1,0,0,1,1\n1,0.1,1,cone,x,2,0,0,0.4,0.4,1,0,0,1,1\n");
    let out = dash2sim(&["verify", "--map", &map, "--ego", &ego, "--objects", &bad_objects]);
    assert!(!out.status.success() && stderr(&out).contains("bad.csv:3: x is not a finite number"), "{}", stderr(&out));
    let out = dash2sim(&["verify", "--map", &ego, "--ego", &ego]);
    assert!(!out.status.success() && stderr(&out).contains("bad magic"), "{}", stderr(&out));
    let out = dash2sim(&["verify", "--map", &map, "--ego", &ego, "--width", "0"]);
    assert!(!out.status.success() && stderr(&out).contains("--width"), "{}", stderr(&out));
}

#[test]
fn map_build_cuts_at_a_bbox_and_survives_odd_ways() {
    let dir = scratch("map-odd");
    // A self-intersecting figure-eight, lanes=0, a one-node way, a way with every node missing.
    let osm = write(
        &dir,
        "odd.osm",
        r#"<osm version="0.6">
  <node id="1" lat="60.0000" lon="24.0000"/>
  <node id="2" lat="60.0010" lon="24.0020"/>
  <node id="3" lat="60.0010" lon="24.0000"/>
  <node id="4" lat="60.0000" lon="24.0020"/>
  <node id="5" lat="60.0030" lon="24.0030"/>
  <way id="5"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/><tag k="highway" v="primary"/><tag k="lanes" v="0"/></way>
  <way id="6"><nd ref="3"/><tag k="highway" v="residential"/></way>
  <way id="7"><nd ref="8"/><nd ref="9"/><tag k="highway" v="residential"/></way>
  <way id="8"><nd ref="3"/><nd ref="5"/><tag k="highway" v="residential"/></way>
</osm>"#,
    );
    let map = dir.join("odd.map").display().to_string();
    let out = dash2sim(&["map", "build", &osm, "-o", &map]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("way 5: lanes") && err.contains("way 6: fewer than 2") && err.contains("way 7"), "{err}");
    let lanes: serde_json::Value = serde_json::from_slice(&dash2sim(&["map", "lanes", &map]).stdout).expect("json");
    assert_eq!(
        lanes["lanes"].as_array().map(Vec::len),
        Some(4),
        "2 for the figure-eight (lanes=0 → default), 2 for way 8"
    );
    // --bbox keeps way 5 (inside) and cuts way 8 at the box: node 5 is outside.
    let cut = dir.join("cut.map").display().to_string();
    let out = dash2sim(&["map", "build", &osm, "-o", &cut, "--bbox", "23.999,59.999,24.0025,60.0015"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let lanes: serde_json::Value = serde_json::from_slice(&dash2sim(&["map", "lanes", &cut]).stdout).expect("json");
    assert_eq!(lanes["lanes"].as_array().map(Vec::len), Some(2));
    let info: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["map", "info", &cut, "--json"]).stdout).expect("json");
    assert_eq!(info["osm"]["ways"], 4, "source counts describe the file, not the cut");
    for bad in ["1,2,3", "24.1,60,24.0,61", "a,b,c,d"] {
        let out = dash2sim(&["map", "build", &osm, "-o", &cut, "--bbox", bad]);
        assert!(!out.status.success() && stderr(&out).contains("--bbox"), "{bad}: {}", stderr(&out));
    }
}

#[test]
fn import_inspect_export_a_drive_and_report_damage_without_failing() {
    let dir = scratch("binlog");
    let drive = dir.join("drive");
    let out = generate_ideal(&drive, "2", "12");
    assert!(out.status.success(), "{}", stderr(&out));
    let file = |name: &str| drive.join(name).display().to_string();
    let log = dir.join("drive.d2slog").display().to_string();
    let out = dash2sim(&[
        "import",
        "-o",
        &log,
        "--nmea",
        &file("gnss.nmea"),
        "--nmea-offset",
        "-1780300800",
        "--traj",
        &file("ego.tum"),
        "--objects",
        &file("objects.csv"),
        "--origin",
        "60.2711,24.8572",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = dash2sim(&["inspect", &log, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(report["by_type"]["EgoPose"], 121, "{report}");
    assert_eq!(report["by_type"]["GnssFix"], 61, "{report}");
    assert_eq!(report["damaged"], 0);
    assert!(report["t_start"].as_f64().is_some_and(|t| t.abs() < 0.2), "{report}");
    assert!(report["records"].as_u64().is_some_and(|n| n > 121 + 61));

    let (tum, geojson, mcap) = (
        dir.join("ego.tum").display().to_string(),
        dir.join("drive.geojson").display().to_string(),
        dir.join("drive.mcap").display().to_string(),
    );
    let map = dir.join("road.map").display().to_string();
    let out = dash2sim(&["map", "build", &file("road.osm"), "-o", &map, "--origin", "60.2711,24.8572"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = dash2sim(&["export", &log, "--tum", &tum, "--geojson", &geojson, "--mcap", &mcap, "--map", &map]);
    assert!(out.status.success(), "{}", stderr(&out));
    // The exported TUM is the imported one, to the millimetre.
    let out = dash2sim(&["traj", "ape", &file("ego.tum"), &tum, "--json"]);
    let ape: serde_json::Value = serde_json::from_slice(&out.stdout).expect("ape json");
    assert!(ape["stats"]["max"].as_f64().is_some_and(|m| m < 1e-3), "{ape}");
    let g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&geojson).expect("geojson")).expect("json");
    let features = g["features"].as_array().expect("features");
    assert_eq!(features[0]["geometry"]["type"], "LineString");
    assert!(features.iter().filter(|f| f["geometry"]["type"] == "Point").count() > 20, "the work zone's objects");
    // verify LOG replays the log's ego poses with its tracks as agents: the same verdict
    // as the trajectory and objects it was imported from.
    let score = |args: &[&str]| -> serde_json::Value {
        let out = dash2sim(args);
        assert!(out.status.success(), "{}", stderr(&out));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        v["metrics"].clone()
    };
    let from_log = score(&["verify", &log, "--map", &map, "--json"]);
    let from_files =
        score(&["verify", "--map", &map, "--ego", &file("ego.tum"), "--objects", &file("objects.csv"), "--json"]);
    assert_eq!(from_log, from_files);
    let mcap_bytes = std::fs::read(&mcap).expect("mcap");
    assert!(mcap_bytes.starts_with(b"\x89MCAP0\r\n") && mcap_bytes.ends_with(b"\x89MCAP0\r\n"));

    // Damage: cut the tail and flip a byte in the middle — reported, exit status 0.
    let mut bytes = std::fs::read(&log).expect("log");
    bytes.truncate(bytes.len() - 7);
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x40;
    let damaged = write(&dir, "damaged.d2slog", "");
    std::fs::write(&damaged, &bytes).expect("write");
    let out = dash2sim(&["inspect", &damaged, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert!(r["damaged"].as_u64().is_some_and(|d| d >= 2), "{r}");
    assert!(r["records"].as_u64() < report["records"].as_u64() && r["records"].as_u64() > Some(100), "{r}");
    // Not a log at all: an error.
    let out = dash2sim(&["inspect", &file("ego.tum")]);
    assert!(!out.status.success() && stderr(&out).contains("not a dash2sim log"), "{}", stderr(&out));
    let out = dash2sim(&["import", "-o", &log]);
    assert!(!out.status.success() && stderr(&out).contains("nothing to import"), "{}", stderr(&out));
}

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
    // It hit the taper's drums: the finished log sees the collision, or a time to collision
    // under the bound (the drum it hits has left the camera's view; on the typical sweep the
    // finished logs see the collision itself in 8 of the 93 careless drives that collide).
    let metrics = &v["finished"]["channel_insensitive"]["metrics"];
    let close = |m: &str| metrics[m].as_f64().is_some_and(|s| s < 1.0);
    assert!(close("no_at_fault_collisions") || close("time_to_collision_within_bound"), "{v}");
    let out = dash2sim(&["demo", "-o", &dir.display().to_string(), "--duration", "5"]);
    assert!(!out.status.success() && stderr(&out).contains("--duration"));
}

#[test]
fn finish_reports_bad_anchor_lines_verifies_per_window_and_refuses_a_log_without_vo() {
    let dir = scratch("finish");
    let out = demo_ideal_offline(&dir, "20");
    assert!(out.status.success(), "{}", stderr(&out));
    let anchors = dir.join("anchors.csv");
    let mut text = std::fs::read_to_string(&anchors).expect("anchors");
    let good = text.lines().filter(|l| !l.starts_with('#')).count() - 1;
    text += "12.5,nan,24.9,10,0.3\n";
    std::fs::write(&anchors, &text).expect("write");
    let (log, map, finished) = (dir.join("drive.d2slog"), dir.join("road.map"), dir.join("again.d2slog"));
    let path = |p: &Path| p.display().to_string();
    let out = dash2sim(&[
        "finish",
        &path(&log),
        "-o",
        &path(&finished),
        "--anchors",
        &path(&anchors),
        "--map",
        &path(&map),
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let bad_line = text.lines().count();
    assert!(stderr(&out).contains(&format!("anchors.csv:{bad_line}: field 2 `nan` is not finite")), "{}", stderr(&out));
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(r["anchors"]["used"], good, "{r}");
    assert_eq!(r["anchors"]["refused"][0]["line"], bad_line, "{r}");
    let windows = r["verification"]["windows"].as_array().expect("windows");
    assert!(!windows.is_empty() && windows.iter().all(|w| w["channel_sensitive"]["score"].is_number()), "{r}");
    // The finished log is a log: inspect reads it, verify scores it as finish did.
    let inspect: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["inspect", &path(&finished), "--json"]).stdout).expect("json");
    assert!(inspect["by_type"]["EgoPose"].as_u64().is_some_and(|n| n > 150), "{inspect}");
    let verify: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["verify", &path(&finished), "--map", &path(&map), "--json"]).stdout)
            .expect("json");
    let drive = &r["verification"]["drive"]["channel_insensitive"]["score"];
    assert!((verify["score"].as_f64().expect("score") - drive.as_f64().expect("score")).abs() < 1e-9, "{verify}");
    // Human output.
    let out = dash2sim(&["finish", &path(&log), "-o", &path(&finished), "--map", &path(&map)]);
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("verification  drive"));
    // A log without VO poses: nothing to re-anchor.
    let gnss_only = dir.join("gnss-only.d2slog");
    let nmea = dir.join("drive/gnss.nmea");
    assert!(dash2sim(&["import", "-o", &path(&gnss_only), "--nmea", &path(&nmea)]).status.success());
    let out = dash2sim(&["finish", &path(&gnss_only), "-o", &path(&finished)]);
    assert!(!out.status.success() && stderr(&out).contains("no trajectory to re-anchor"), "{}", stderr(&out));
    // A bad anchors header names the line.
    std::fs::write(&anchors, "lat,lon\n").expect("write");
    let out = dash2sim(&["finish", &path(&log), "-o", &path(&finished), "--anchors", &path(&anchors)]);
    assert!(!out.status.success() && stderr(&out).contains("anchors.csv:1: header"), "{}", stderr(&out));
}

#[test]
fn export_nuplan_writes_the_devkits_tables_and_layers_and_refuses_bad_input() {
    let dir = scratch("nuplan");
    let out = demo_ideal_offline(&dir, "30");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |p: &Path| p.display().to_string();
    let (log, map, nuplan) = (dir.join("finished.d2slog"), dir.join("road.map"), dir.join("nuplan"));
    let out = dash2sim(&["export", &path(&log), "--nuplan", &path(&nuplan), "--map", &path(&map)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let dbs: Vec<PathBuf> =
        std::fs::read_dir(nuplan.join("db")).expect("db").map(|e| e.expect("entry").path()).collect();
    assert_eq!(dbs.len(), 1, "{dbs:?}");
    let name = dbs[0].file_name().and_then(|n| n.to_str()).unwrap_or_default().to_owned();
    assert!(name.starts_with("2026.06.01.07.59") && name.ends_with("_dash2sim_finished.db"), "{name}");
    let db = rusqlite::Connection::open(&dbs[0]).expect("sqlite");
    let one = |sql: &str| -> i64 { db.query_row(sql, [], |r| r.get(0)).expect(sql) };
    // The clock: exactly 20 Hz, one ego pose per tick, 30 s of drive.
    let ticks = one("SELECT COUNT(*) FROM lidar_pc");
    assert_eq!(ticks, one("SELECT COUNT(*) FROM ego_pose"));
    assert!((590..=602).contains(&ticks), "{ticks}");
    assert_eq!(one("SELECT MAX(timestamp) - MIN(timestamp) FROM lidar_pc"), (ticks - 1) * 50_000);
    assert_eq!(one("SELECT COUNT(DISTINCT timestamp) FROM lidar_pc"), ticks);
    assert_eq!(one("SELECT COUNT(*) FROM lidar_pc WHERE next_token IS NULL"), 1);
    assert_eq!(one("SELECT COUNT(*) FROM scene"), 6);
    assert_eq!(one("SELECT LENGTH(token) FROM scene LIMIT 1"), 8);
    assert_eq!(one("SELECT COUNT(*) FROM lidar WHERE channel = 'MergedPointCloud'"), 1);
    // The work zone's objects, by nuPlan category, every box on a tick of the clock.
    for category in ["traffic_cone", "barrier", "czone_sign"] {
        let n = one(&format!(
            "SELECT COUNT(*) FROM track t JOIN category c ON t.category_token = c.token WHERE c.name = '{category}'"
        ));
        assert!(n > 0, "{category}");
    }
    assert_eq!(
        one(
            "SELECT COUNT(*) FROM lidar_box b LEFT JOIN lidar_pc p ON b.lidar_pc_token = p.token WHERE p.token IS NULL"
        ),
        0
    );
    // Every scene has a route of real roadblocks.
    let routes: Vec<String> = db
        .prepare("SELECT roadblock_ids FROM scene ORDER BY name")
        .expect("query")
        .query_map([], |r| r.get(0))
        .expect("rows")
        .collect::<Result<_, _>>()
        .expect("routes");
    assert!(
        routes.iter().all(|r| r.split(' ').all(|id| id.parse::<i64>().is_ok_and(|id| id >= 1_000_000))),
        "{routes:?}"
    );
    // The map: a GeoPackage with the layers nuPlan reads, in UTM 35N, lanes' ids apart from
    // roadblocks'.
    let gpkg = rusqlite::Connection::open(nuplan.join("maps/dash2sim-road/9.17.1964/map.gpkg")).expect("gpkg");
    let g = |sql: &str| -> i64 { gpkg.query_row(sql, [], |r| r.get(0)).expect(sql) };
    assert_eq!(g("PRAGMA application_id"), 0x4750_4B47);
    assert_eq!(g("SELECT COUNT(*) FROM gpkg_contents WHERE data_type = 'features'"), 14);
    assert_eq!(g("SELECT srs_id FROM gpkg_geometry_columns WHERE table_name = 'lanes_polygons'"), 32635);
    assert!(g("SELECT MAX(fid) FROM lanes_polygons") < 1_000_000);
    assert!(g("SELECT MIN(fid) FROM lane_groups_polygons") > 1_000_000);
    assert!(g("SELECT COUNT(*) FROM generic_drivable_areas") > 100);
    let maps: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(nuplan.join("maps/nuplan-maps-v1.0.json")).expect("json"))
            .expect("json");
    assert_eq!(maps["dash2sim-road"]["version"], "9.17.1964");

    // `verify --from/--to` scores one scenario's window, as the nuPlan cross-check asks it.
    let all: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["verify", &path(&log), "--map", &path(&map), "--json"]).stdout)
            .expect("json");
    let start = one("SELECT MIN(timestamp) FROM lidar_pc") as f64 * 1e-6;
    let (from, to) = (format!("{:.3}", start + 5.0), format!("{:.3}", start + 20.0));
    let window: serde_json::Value = serde_json::from_slice(
        &dash2sim(&["verify", &path(&log), "--map", &path(&map), "--json", "--from", &from, "--to", &to]).stdout,
    )
    .expect("json");
    let (n_all, n_window) = (all["poses"].as_u64().expect("poses"), window["poses"].as_u64().expect("poses"));
    assert!(n_window < n_all && (140..=160).contains(&n_window), "{n_window} of {n_all}");
    let out = dash2sim(&["verify", &path(&log), "--map", &path(&map), "--from", "0", "--to", "1"]);
    assert!(!out.status.success() && stderr(&out).contains("no ego poses between"), "{}", stderr(&out));

    // Bad input: nothing is left behind.
    let fresh = dir.join("refused");
    let out =
        dash2sim(&["export", &path(&log), "--nuplan", &path(&fresh), "--map", &path(&map), "--scenario-seconds", "10"]);
    assert!(!out.status.success() && stderr(&out).contains("nuPlan needs at least 5"), "{}", stderr(&out));
    let far = write(
        &dir,
        "far.osm",
        r#"<osm version="0.6"><node id="1" lat="0.0" lon="0.0"/><node id="2" lat="0.001" lon="0.0"/>
<way id="3"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way></osm>"#,
    );
    let out = dash2sim(&["export", &path(&log), "--nuplan", &path(&fresh), "--map", &far]);
    assert!(!out.status.success() && stderr(&out).contains("the map does not cover the drive"), "{}", stderr(&out));
    let gnss_only = dir.join("gnss-only.d2slog");
    assert!(dash2sim(&["import", "-o", &path(&gnss_only), "--nmea", &path(&dir.join("drive/gnss.nmea"))])
        .status
        .success());
    let out = dash2sim(&["export", &path(&gnss_only), "--nuplan", &path(&fresh), "--map", &path(&map)]);
    assert!(!out.status.success() && stderr(&out).contains("no ego poses"), "{}", stderr(&out));
    let out = dash2sim(&["export", &path(&log), "--nuplan", &path(&fresh)]);
    assert!(!out.status.success() && stderr(&out).contains("--nuplan needs --map"), "{}", stderr(&out));
    let left: Vec<_> = walk(&fresh).into_iter().filter(|p| p.is_file()).collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = entry.path();
        if p.is_dir() {
            out.extend(walk(&p));
        }
        out.push(p);
    }
    out
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
    let files: Vec<_> = std::fs::read_dir(&out).expect("log dir").map(|e| e.expect("entry").path()).collect();
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
    if !out.status.success() && err.contains("CAN interface vcan0") {
        eprintln!("SKIPPED: no CAN interface vcan0 on this machine (no AF_CAN/vcan): {}", err.trim());
        return;
    }
    assert!(out.status.success(), "{err}");
}

#[test]
fn map_check_counts_compliant_poses_and_times_them() {
    let dir = scratch("map-check");
    let drive = dir.join("drive");
    let out = generate_ideal(&drive, "2", "5");
    assert!(out.status.success(), "{}", stderr(&out));
    let map = dir.join("road.map").display().to_string();
    let osm = drive.join("road.osm").display().to_string();
    assert!(dash2sim(&["map", "build", &osm, "-o", &map, "--origin", "60.2711,24.8572"]).status.success());
    let ego = drive.join("ego.tum").display().to_string();
    let out = dash2sim(&["map", "check", &map, "--poses", &ego, "--passes", "2", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    // The generated drive stays on its road: every pose complies.
    assert_eq!(v["poses"], 51);
    assert_eq!(v["compliant"], 51, "{v}");
    assert!(v["us_per_pose"].as_f64().is_some_and(|t| t > 0.0));
    // The same poses 40 m to the side are off the road.
    let text = std::fs::read_to_string(drive.join("ego.tum")).expect("tum");
    let shifted: String = text
        .lines()
        .map(|l| {
            let mut f: Vec<String> = l.split(' ').map(str::to_owned).collect();
            f[2] = (f[2].parse::<f64>().expect("y") + 40.0).to_string();
            f.join(" ") + "\n"
        })
        .collect();
    let off = write(&dir, "off.tum", &shifted);
    let out = dash2sim(&["map", "check", &map, "--poses", &off, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["compliant"], 0, "{v}");
    let out = dash2sim(&["map", "check", &map, "--poses", &write(&dir, "empty.tum", "")]);
    assert!(!out.status.success() && stderr(&out).contains("no poses"), "{}", stderr(&out));
    let out = dash2sim(&["map", "check", &map, "--poses", &ego, "--passes", "0"]);
    assert!(!out.status.success() && stderr(&out).contains("--passes"));
}

#[test]
fn plot_draws_the_map_the_three_trajectories_and_the_objects_and_refuses_a_log_without_poses() {
    let dir = scratch("plot");
    let out = demo_ideal_offline(&dir, "30");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |p: &Path| p.display().to_string();
    // The demo drew its drive.
    let png = std::fs::read(dir.join("plot.png")).expect("the demo's plot.png");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let (w, h) = (
        u32::from_be_bytes([png[16], png[17], png[18], png[19]]),
        u32::from_be_bytes([png[20], png[21], png[22], png[23]]),
    );
    assert_eq!((w, h), (1200, 1400));

    let svg_path = dir.join("again.svg");
    let (log, finished, map) = (dir.join("drive.d2slog"), dir.join("finished.d2slog"), dir.join("road.map"));
    let out =
        dash2sim(&["plot", &path(&log), "--map", &path(&map), "--finished", &path(&finished), "-o", &path(&svg_path)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(said.contains("online and") && said.contains("cone"), "{said}");
    let svg = std::fs::read_to_string(&svg_path).expect("svg");
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    // The layers a person looks for, each named in a legend; the panels; scale bar, north.
    let texts: Vec<String> = svg
        .split("<text")
        .skip(1)
        .filter_map(|t| Some(t.split_once('>')?.1.split_once("</text>")?.0.trim().to_owned()))
        .collect();
    for label in [
        "map lanes (drivable area)",
        "GNSS fixes (raw)",
        "online anchored ego",
        "finished ego",
        "cone",
        "drum",
        "barricade",
        "car",
        "vehicle speed (wheel / CAN)",
        "time to collision",
        "score / 100",
        "speed",
        "N",
    ] {
        assert!(texts.iter().any(|t| t == label), "no {label:?} among {texts:?}");
    }
    assert!(
        texts.iter().any(|t| t.strip_suffix(" m").is_some_and(|n| n.parse::<u32>().is_ok_and(|n| n >= 10))),
        "no scale bar among {texts:?}"
    );
    // Grey lane areas, red fixes, orange and blue lines are all there.
    for colour in ["#CDCDCD", "#D62728", "#FF7F0E", "#1F77B4"] {
        assert!(svg.contains(colour), "no {colour} in the SVG");
    }
    // Without a map or a finished log, those layers are absent, not empty.
    let bare = dir.join("bare.svg");
    assert!(dash2sim(&["plot", &path(&log), "-o", &path(&bare)]).status.success());
    let bare = std::fs::read_to_string(&bare).expect("svg");
    assert!(!bare.contains("map lanes") && !bare.contains("finished ego") && bare.contains("online anchored ego"));

    // Bad input: a log without ego poses, an unknown picture format.
    let gnss_only = dir.join("gnss-only.d2slog");
    assert!(dash2sim(&["import", "-o", &path(&gnss_only), "--nmea", &path(&dir.join("drive/gnss.nmea"))])
        .status
        .success());
    let out = dash2sim(&["plot", &path(&gnss_only), "-o", &path(&dir.join("x.svg"))]);
    assert!(!out.status.success() && stderr(&out).contains("no ego poses to plot"), "{}", stderr(&out));
    let out = dash2sim(&["plot", &path(&log), "-o", &path(&dir.join("x.gif"))]);
    assert!(!out.status.success() && stderr(&out).contains("must end in .svg or .png"), "{}", stderr(&out));
}

/// The shared data folder (`$DASH2SIM_DATA`, else `../shared` beside the checkout), if
/// there; with `DASH2SIM_REQUIRE_DATA=1` it must be.
fn shared_data() -> Option<PathBuf> {
    let dir = std::env::var_os("DASH2SIM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(std::env::var("DASH2SIM_REQUIRE_DATA").as_deref() != Ok("1"), "{} does not exist", dir.display());
    eprintln!("SKIPPED: {} not found", dir.display());
    None
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
    assert!(!out.status.success() && stderr(&out).contains("no DBC files given"), "{}", stderr(&out));
}

/// Rows of a Parquet file and its Arrow schema, read with the parquet crate's own reader.
fn parquet_table(path: &Path) -> (usize, Vec<arrow_array::RecordBatch>) {
    let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let reader = parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
        .expect("parquet")
        .build()
        .expect("reader");
    let batches: Vec<_> = reader.map(|b| b.expect("batch")).collect();
    (batches.iter().map(|b| b.num_rows()).sum(), batches)
}

#[test]
fn export_parquet_writes_a_table_per_record_kind_in_si_units_and_utc() {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Float64Type, TimestampMicrosecondType};
    let dir = scratch("parquet");
    let demo = dir.join("demo");
    let out = dash2sim(&[
        "demo",
        "--profile",
        "ideal",
        "--offline",
        "-q",
        "--duration",
        "20",
        "-o",
        &demo.display().to_string(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let log = demo.join("finished.d2slog").display().to_string();
    let out_dir = dir.join("pq");
    let out = dash2sim(&["export", &log, "--parquet", &out_dir.display().to_string(), "--log-id", "seed-1"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let inspect: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["inspect", &log, "--json"]).stdout).expect("json");
    let by_type = &inspect["by_type"];
    for (table, kind) in [
        ("ego", "EgoPose"),
        ("gnss", "GnssFix"),
        ("speed", "VehicleSpeed"),
        ("anchors", "AnchorEstimate"),
        ("verification", "Verification"),
        ("events", "Event"),
    ] {
        let (rows, _) = parquet_table(&out_dir.join(format!("{table}.parquet")));
        assert_eq!(rows as u64, by_type[kind].as_u64().unwrap_or(0), "{table}");
    }
    let (states, _) = parquet_table(&out_dir.join("tracks3d.parquet"));
    assert!(states as u64 >= by_type["Tracks3d"].as_u64().unwrap_or(0) && states > 0);
    // The ego in metres and UTC: the TUM export's first pose.
    let tum_path = dir.join("ego.tum");
    assert!(dash2sim(&["export", &log, "--tum", &tum_path.display().to_string()]).status.success());
    let tum = std::fs::read_to_string(&tum_path).expect("tum");
    let first: Vec<f64> = tum
        .lines()
        .find(|l| !l.starts_with('#'))
        .expect("a pose")
        .split(' ')
        .map(|x| x.parse().expect("number"))
        .collect();
    let (_, batches) = parquet_table(&out_dir.join("ego.parquet"));
    let b = &batches[0];
    let t = b.column_by_name("t").expect("t").as_primitive::<TimestampMicrosecondType>().value(0);
    let x = b.column_by_name("x_m").expect("x").as_primitive::<Float64Type>().value(0);
    assert!((t as f64 * 1e-6 - first[0]).abs() < 1e-6 && (x - first[1]).abs() < 1e-9, "{t} {x} vs {first:?}");
    assert_eq!(b.column_by_name("log_id").expect("id").as_string::<i32>().value(0), "seed-1");
    // A folder that cannot be made is named.
    let blocker = write(&dir, "file", "");
    let out = dash2sim(&["export", &log, "--parquet", &format!("{blocker}/pq")]);
    assert!(!out.status.success() && stderr(&out).contains(&blocker), "{}", stderr(&out));
}
