//! NMEA 2000 GNSS PGNs against canboat's analyzer on real buses (docs/conformance.md; the expected
//! JSON was produced by canboat 8.0.0-beta3 — see `canboat/PROVENANCE.md`).
//!
//! For each capture, the 129025/129026/129029 messages `dash2sim can decode` prints
//! must be the ones canboat prints, in the same order, from the same sources, with every
//! field equal to canboat's printed precision and the same fields absent.

use std::path::Path;

use dash2sim_tests::can::decode_capture;
use dash2sim_tests::data_dir;
use serde_json::Value;

const GNSS_PGNS: [u64; 3] = [129_025, 129_026, 129_029];

/// Half a unit in the last digit canboat prints for each numeric field.
fn tolerance(field: &str) -> Option<f64> {
    let printed = match field {
        "Latitude" | "Longitude" => 1e-7,
        "COG" => 0.1, // degrees, one decimal
        "SOG" | "HDOP" | "PDOP" | "Geoidal Separation" => 0.01,
        "Altitude" => 1e-6,
        "SID" | "Number of SVs" | "Reference Stations" => 0.0,
        _ => return None,
    };
    Some(printed / 2.0 + 1e-9)
}

fn gnss_messages(values: impl IntoIterator<Item = Value>) -> Vec<Value> {
    values.into_iter().filter(|v| v["pgn"].as_u64().is_some_and(|p| GNSS_PGNS.contains(&p))).collect()
}

fn read_jsonl(path: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    // serde_json keeps the last of canboat's duplicated keys ("Reserved"), which we ignore.
    text.lines().filter_map(|l| serde_json::from_str(l).ok()).collect()
}

/// canboat with `-nv` prints lookups and dates as `{"value": .., "name": ..}`.
fn expected_text(v: &Value) -> Option<&str> {
    v.get("name").and_then(Value::as_str).or_else(|| v.as_str())
}

/// A field where we and canboat differ.
#[derive(Debug)]
struct Disagreement {
    field: String,
    ours: f64,
    canboat: f64,
    /// The message's GNSS time (129029), to look it up elsewhere.
    time: Option<String>,
}

/// Compare one capture; returns (messages, fields agreeing, disagreements).
fn compare(capture: &Path, expected: &Path) -> (usize, usize, Vec<Disagreement>) {
    let (ours, problems, _) = decode_capture(capture, &[]);
    let ours = gnss_messages(ours);
    let theirs = gnss_messages(read_jsonl(expected));
    assert!(!theirs.is_empty(), "{} has no GNSS PGNs", expected.display());
    assert_eq!(ours.len(), theirs.len(), "{}: message count (problems: {problems:?})", capture.display());
    let mut fields = 0;
    let mut disagreements = Vec::new();
    for (i, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        let at = || format!("{} message {i} (PGN {})", capture.display(), b["pgn"]);
        assert_eq!(
            (&a["pgn"], &a["src"], &a["prio"], &a["dst"]),
            (&b["pgn"], &b["src"], &b["prio"], &b["dst"]),
            "{}",
            at()
        );
        let (a, b) = (a["fields"].as_object().expect("fields"), b["fields"].as_object().expect("fields"));
        for (name, want) in b {
            if name == "Reserved" || name == "list" {
                continue;
            }
            let got = a.get(name).unwrap_or_else(|| panic!("{}: {name} missing, canboat has {want}", at()));
            match (tolerance(name), want.as_f64(), got.as_f64()) {
                (Some(tol), Some(want), Some(got)) if (got - want).abs() > tol => {
                    let time = a.get("Time").and_then(Value::as_str).map(str::to_owned);
                    disagreements.push(Disagreement { field: name.clone(), ours: got, canboat: want, time });
                    continue;
                }
                (Some(_), Some(_), Some(_)) => {}
                _ => assert_eq!(got.as_str(), expected_text(want), "{}: {name}", at()),
            }
            fields += 1;
        }
        for name in a.keys() {
            assert!(b.contains_key(name), "{}: {name} present but canboat says not available", at());
        }
    }
    (ours.len(), fields, disagreements)
}

#[test]
fn gnss_pgns_equal_canboat_on_three_real_buses() {
    let (Some(canboat), Some(gpsd)) = (data_dir("canboat"), data_dir("gpsd")) else { return };
    let cases = [
        (
            canboat.join("samples/candumpSample1.txt"),
            canboat.join("expected-decoded/candumpSample1.txt.analyzer-json-nv.jsonl"),
        ),
        (
            canboat.join("samples/candumpSample2.txt"),
            canboat.join("expected-decoded/candumpSample2.txt.analyzer-json-nv.jsonl"),
        ),
        (
            gpsd.join("nmea2000/logfile_20140914_365495765_can.log"),
            gpsd.join("nmea2000/logfile_20140914_365495765_can.log.canboat-analyzer.jsonl"),
        ),
    ];
    let mut total = (0, 0);
    for (i, (capture, expected)) in cases.iter().enumerate() {
        let (messages, fields, disagreements) = compare(capture, expected);
        println!("{}: {messages} messages, {fields} fields equal canboat", capture.display());
        for d in &disagreements {
            println!("  differs: {d:?}");
        }
        if i < 2 {
            assert!(disagreements.is_empty(), "{disagreements:?}");
        } else {
            check_against_gpsd(capture, &disagreements);
        }
        total = (total.0 + messages, total.1 + fields);
    }
    println!("total: {} messages, {} fields", total.0, total.1);
    // 1445 + 97 + 3056 GNSS messages in these captures.
    assert_eq!(total.0, 4598);
}

/// In the gpsd capture canboat prints, for 4 of 200 PGN 129029 messages, the altitude
/// of the message before (the frames on the bus carry the new one: e.g. line 2719,
/// `23B931038C579302` → 0x0293578C = 43.210636 m). gpsd, decoding the same frames
/// independently, agrees with us: its TPV for that second has our altHAE.
fn check_against_gpsd(capture: &Path, disagreements: &[Disagreement]) {
    assert_eq!(disagreements.len(), 4, "{disagreements:?}");
    let chk = std::fs::read_to_string(capture.with_extension("log.chk")).expect("gpsd .chk");
    for d in disagreements {
        assert_eq!(d.field, "Altitude");
        let time = d.time.as_deref().expect("129029 has a time");
        let stamp = format!("\"time\":\"2014-09-14T{}Z\"", &time[..time.len() - 1]);
        let gpsd_says = format!("\"altHAE\":{:.4}", d.ours);
        assert!(
            chk.lines().any(|l| l.contains("\"TPV\"") && l.contains(&stamp) && l.contains(&gpsd_says)),
            "gpsd has no TPV at {time} with {gpsd_says} (canboat: {})",
            d.canboat
        );
    }
}

#[test]
fn fast_packet_reassembly_matches_canboat_counts() {
    let Some(gpsd) = data_dir("gpsd") else { return };
    let capture = gpsd.join("nmea2000/logfile_20140914_365495765_can.log");
    let (messages, problems, summary) = decode_capture(&capture, &[]);
    let gnss = messages.iter().filter(|m| m["pgn"] == 129_029).count();
    // 1409 frames → 200 complete messages (canboat also prints 200); four
    // messages lost frames on the bus and are reported, with their line, as timed out.
    assert_eq!(gnss, 200);
    assert_eq!(summary.dropped_messages, 4);
    assert_eq!(problems.len(), 4);
    assert!(problems.iter().all(|(line, text)| *line > 0 && text.contains("timeout")), "{problems:?}");
}

#[test]
fn crlf_and_lf_logs_read_the_same_frames() {
    use dash2sim_can::candump::CandumpReader;
    use dash2sim_can::FrameSource;
    let Some(canboat) = data_dir("canboat") else { return };
    let read = |name: &str| {
        let text = std::fs::read(canboat.join("samples").join(name)).expect("sample");
        let mut reader = CandumpReader::new(&text[..]);
        let mut records = Vec::new();
        while let Some(record) = reader.next_frame() {
            records.push(record.expect("every line is a frame"));
        }
        records
    };
    let (lf, crlf) = (read("candump-fast.txt"), read("candump-fast-cr.txt"));
    assert_eq!(lf.len(), 23);
    assert_eq!(lf, crlf);
}
