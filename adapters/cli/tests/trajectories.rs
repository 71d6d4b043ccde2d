//! The `dash2sim` binary end to end — trajectory evaluation (`traj ape|rpe`), offline anchoring (`anchor`) and every subcommand's `--help`: output shape, exit status and error messages.

mod common;

use common::*;

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
