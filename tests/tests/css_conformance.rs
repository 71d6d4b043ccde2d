//! Real cars through `dash2sim can decode`, against the CSVs CSS Electronics' data was
//! decoded into with cantools (see `css-electronics-canedge/PROVENANCE.md`):
//!
//! - the 40-minute Danish drive (5 files): OBD-II PID 0x0D speed, and every CANmod.gps
//!   message (status, time, position, altitude, attitude, odometer, speed, geofence)
//!   decoded with `canmod-gps.dbc`;
//! - the parked Iowa J1939 truck: CANmod.gps again, and CCVS1 wheel-based speed (PGN 65265);
//! - the FCBF0606 J1939 log: CCVS1 from source 0x47.
//!
//! Every expected row must be matched, in order, to the printed precision of the CSV.

use std::path::{Path, PathBuf};

use dash2sim_tests::can::{decode_capture, printed_tolerance, read_csv};
use dash2sim_tests::data_dir;
use serde_json::Value;

const CANMOD_MESSAGES: [&str; 8] = [
    "gnss_status",
    "gnss_time",
    "gnss_pos",
    "gnss_altitude",
    "gnss_attitude",
    "gnss_odo",
    "gnss_speed",
    "gnss_geofence",
];

/// Messages of several consecutive capture files.
fn decode_all(files: &[PathBuf], dbcs: &[PathBuf]) -> Vec<Value> {
    let mut all = Vec::new();
    for file in files {
        let (messages, problems, summary) = decode_capture(file, dbcs);
        assert_eq!((summary.bad_lines, summary.bad_frames), (0, 0), "{}: {problems:?}", file.display());
        all.extend(messages);
    }
    all
}

/// Compare `rows` (first column `t_log_s`) with `(t, values)` pairs; returns cells compared.
fn compare_rows(what: &str, header: &[String], rows: &[Vec<String>], ours: &[(f64, Vec<Option<f64>>)]) -> usize {
    assert_eq!(ours.len(), rows.len(), "{what}: row count");
    let mut cells = 0;
    for (i, (row, (t, values))) in rows.iter().zip(ours).enumerate() {
        assert!((t - row[0].parse::<f64>().expect("t_log_s")).abs() < 1e-6, "{what} row {i}: t {t} vs {}", row[0]);
        for (j, (cell, value)) in row[1..].iter().zip(values).enumerate() {
            match value {
                None => assert!(cell.is_empty(), "{what} row {i} {}: not available, expected {cell}", header[j + 1]),
                Some(v) => {
                    let want: f64 = cell.parse().unwrap_or_else(|_| panic!("{what} row {i}: {cell:?}"));
                    assert!(
                        (v - want).abs() <= printed_tolerance(cell),
                        "{what} row {i} {}: {v} vs {cell}",
                        header[j + 1]
                    );
                }
            }
            cells += 1;
        }
    }
    cells
}

fn t(m: &Value) -> f64 {
    m["t"].as_f64().expect("timestamped log")
}

/// Every CANmod.gps message of `messages` against `<set>.<message>.csv`.
fn compare_canmod(expected: &Path, set: &str, messages: &[Value]) -> usize {
    let mut cells = 0;
    for name in CANMOD_MESSAGES {
        let (header, rows) = read_csv(&expected.join(format!("{set}.{name}.csv")));
        let ours: Vec<_> = messages
            .iter()
            .filter(|m| m["message"] == name)
            .map(|m| (t(m), header[1..].iter().map(|signal| m["fields"][signal].as_f64()).collect()))
            .collect();
        let n = compare_rows(&format!("{set}.{name}"), &header, &rows, &ours);
        println!("{set}.{name}: {} rows, {n} values equal cantools", rows.len());
        cells += n;
    }
    cells
}

/// CCVS1 wheel speeds of `messages` against `<set>.j1939_ccvs_wheel_speed.csv`.
fn compare_ccvs(expected: &Path, set: &str, messages: &[Value]) -> usize {
    let (header, rows) = read_csv(&expected.join(format!("{set}.j1939_ccvs_wheel_speed.csv")));
    let ours: Vec<_> = messages
        .iter()
        .filter(|m| m["pgn"] == 65_265)
        .map(|m| {
            let kmh = m["fields"]["Wheel-Based Vehicle Speed"].as_f64().map(|mps| mps * 3.6);
            (t(m), vec![m["src"].as_f64(), kmh])
        })
        .collect();
    let n = compare_rows(&format!("{set}.ccvs"), &header, &rows, &ours);
    println!("{set}.j1939_ccvs_wheel_speed: {} rows equal", rows.len());
    n
}

#[test]
fn danish_drive_obd_speed_and_canmod_gps() {
    let Some(css) = data_dir("css-electronics-canedge") else { return };
    let mut files: Vec<PathBuf> = std::fs::read_dir(css.join("candump"))
        .expect("candump dir")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("3BA199E2_00000164_")))
        .collect();
    files.sort();
    assert_eq!(files.len(), 5);
    let messages = decode_all(&files, &[css.join("dbc/canmod-gps.dbc")]);
    let expected = css.join("expected");

    let (header, rows) = read_csv(&expected.join("3BA199E2_session164.obd_pid0d_speed.csv"));
    let speeds: Vec<_> = messages
        .iter()
        .filter(|m| m["pid"] == 13 && m["bus"] == "can0")
        .map(|m| (t(m), vec![m["fields"]["Vehicle Speed"].as_f64()]))
        .collect();
    compare_rows("obd_pid0d_speed", &header, &rows, &speeds);
    let max = speeds.iter().filter_map(|(_, v)| v[0]).fold(0.0, f64::max);
    println!("OBD-II PID 0x0D: {} responses equal, max {max} km/h", rows.len());
    assert_eq!(max, 88.0);

    let cells = compare_canmod(&expected, "3BA199E2_session164", &messages);
    assert_eq!(cells, 2272 * 32, "8 messages × 2272 fixes, 32 signals in all");
}

#[test]
fn j1939_trucks_wheel_speed_and_canmod_gps() {
    let Some(css) = data_dir("css-electronics-canedge") else { return };
    let expected = css.join("expected");
    let messages = decode_all(&[css.join("candump/11111111_00000012_00000001.log")], &[css.join("dbc/canmod-gps.dbc")]);
    compare_canmod(&expected, "11111111_00000012", &messages);
    assert!(compare_ccvs(&expected, "11111111_00000012", &messages) > 1000);
    let messages = decode_all(&[css.join("candump/FCBF0606_00003482_00000001-60B621D9.log")], &[]);
    assert_eq!(compare_ccvs(&expected, "FCBF0606_00003482", &messages), 184 * 2);
}
