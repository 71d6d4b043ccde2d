//! The `dash2sim` binary end to end — the capture decoders (`nmea decode`, `can decode`) and the 2D tools (`mot eval`, `track2d`): output shape, exit status and error messages.

mod common;

use common::*;

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
