//! `dash2sim mot eval` against motmetrics 1.4.0 on MOTChallenge TUD-Campus (see
//! `motmetrics/PROVENANCE.md`): every summary metric, and the event list frame by frame.

use dash2sim_linux::ingest::motchallenge::read_mot;
use dash2sim_tests::data_dir;
use dash2sim_verify::mot::{compare, summarize, EventKind};

#[test]
fn tud_campus_summary_equals_motmetrics() {
    let Some(dir) = data_dir("motmetrics") else { return };
    let gt = read_mot(&dir.join("TUD-Campus/gt.txt")).expect("gt");
    let test = read_mot(&dir.join("TUD-Campus/test.txt")).expect("test");
    let summary = summarize(&compare(&gt, &test, 0.5));
    let expected = dash2sim_tests::read_json(&dir.join("expected/motchallenge_summary_TUD-Campus.json"));
    let expected = expected["summary"]["TUD-Campus"].as_object().expect("summary");
    assert!(expected.len() >= 20);
    let mut worst = 0.0f64;
    for (name, want) in expected {
        let want = want.as_f64().expect("number");
        let got = summary.get(name).unwrap_or_else(|| panic!("{name} missing"));
        assert!((got - want).abs() <= 1e-6, "{name}: {got} vs motmetrics {want}");
        worst = worst.max((got - want).abs());
    }
    println!("{} metrics equal motmetrics, worst difference {worst:.1e}", expected.len());
    assert!((summary.get("mota").expect("mota") - 0.526_462).abs() < 1e-6);
    assert!((summary.get("idf1").expect("idf1") - 0.557_659).abs() < 1e-6);
}

/// frame, type, object, hypothesis, distance — one row of motmetrics' event CSV.
type ExpectedEvent = (i64, String, Option<i64>, Option<i64>, Option<f64>);

#[test]
fn tud_campus_events_equal_motmetrics() {
    let Some(dir) = data_dir("motmetrics") else { return };
    let gt = read_mot(&dir.join("TUD-Campus/gt.txt")).expect("gt");
    let test = read_mot(&dir.join("TUD-Campus/test.txt")).expect("test");
    let acc = compare(&gt, &test, 0.5);
    let text =
        std::fs::read_to_string(dir.join("expected/TUD-Campus_mot_events_motmetrics-1.4.0.csv")).expect("events");
    let id = |cell: &str| (!cell.is_empty()).then(|| cell.parse::<f64>().expect("id") as i64);
    // Within a frame motmetrics lists events in the order it makes them; so do we.
    let expected: Vec<ExpectedEvent> = text
        .lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (
                c[0].parse().expect("frame"),
                c[2].to_owned(),
                id(c[3]),
                id(c[4]),
                (!c[5].is_empty()).then(|| c[5].parse().expect("D")),
            )
        })
        .collect();
    let name = |k: EventKind| match k {
        EventKind::Match => "MATCH",
        EventKind::Switch => "SWITCH",
        EventKind::Miss => "MISS",
        EventKind::FalsePositive => "FP",
        EventKind::Ascend => "ASCEND",
        EventKind::Transfer => "TRANSFER",
        EventKind::Migrate => "MIGRATE",
    };
    let ours = acc.events();
    assert_eq!(ours.len(), expected.len());
    for (e, (frame, kind, o, h, d)) in ours.iter().zip(&expected) {
        assert_eq!((e.frame, name(e.kind), e.object, e.hypothesis), (*frame, kind.as_str(), *o, *h), "{e:?}");
        match (e.distance, d) {
            (Some(a), Some(b)) => assert!((a - b).abs() < 1e-12, "{e:?} vs {b}"),
            (a, b) => assert_eq!(a.is_some(), b.is_some(), "{e:?}"),
        }
    }
    println!("{} events equal motmetrics'", ours.len());
}

/// Issue #4: our tracker, fed the supplied tracker's boxes without their ids, must reach
/// at least that tracker's IDF1 (0.5577) on TUD-Campus.
#[test]
fn track2d_on_tud_campus_beats_the_supplied_tracker() {
    let Some(dir) = data_dir("motmetrics") else { return };
    let gt = read_mot(&dir.join("TUD-Campus/gt.txt")).expect("gt");
    let mut detections = read_mot(&dir.join("TUD-Campus/test.txt")).expect("test");
    for d in &mut detections {
        d.id = -1;
    }
    let (tracks, stats, skipped) = dash2sim_linux::record::track2d::track(&detections);
    assert!(skipped.is_empty());
    assert_eq!((stats.frames, stats.rejected_detections), (71, 0));
    let summary = summarize(&compare(&gt, &tracks, 0.5));
    let (idf1, mota) = (summary.get("idf1").expect("idf1"), summary.get("mota").expect("mota"));
    println!(
        "track2d on TUD-Campus: IDF1 {idf1:.4} (supplied tracker 0.5577), MOTA {mota:.4} (0.5265), {} switches",
        summary.get("num_switches").unwrap_or(f64::NAN)
    );
    assert!(idf1 >= 0.5577, "IDF1 {idf1}");
}
