//! Conformance with evo 1.38.1: every case in `evo/expected/evo_1.38.1_expected.json`.
//!
//! Alignment (R, t, s) and every statistic must agree within 1e-9 relative.

use std::path::Path;

use dash2sim_core::sim3::Sim3;
use dash2sim_core::traj::{Delta, RpePairs, Statistics};
use dash2sim_linux::trajectory::{Format, Trajectory};
use dash2sim_tests::{data_dir, read_json, rel_diff};
use dash2sim_verify::evaluate::{self, Align, Relation};
use serde_json::Value;

const REL_TOL: f64 = 1e-9;

fn assert_close(what: &str, got: f64, want: f64) {
    // Entries that are zero up to rounding (e.g. 5e-17) are compared absolutely.
    let ok = rel_diff(got, want) <= REL_TOL || (got - want).abs() <= 1e-15;
    assert!(ok, "{what}: got {got:e}, evo {want:e} (rel {:e})", rel_diff(got, want));
}

fn assert_stats(what: &str, got: &Statistics, want: &Value) {
    for (name, v) in [
        ("rmse", got.rmse),
        ("mean", got.mean),
        ("median", got.median),
        ("std", got.std),
        ("min", got.min),
        ("max", got.max),
        ("sse", got.sse),
    ] {
        let w = want[name].as_f64().unwrap_or_else(|| panic!("{what}: no {name}"));
        assert_close(&format!("{what} {name}"), v, w);
    }
}

fn assert_alignment(what: &str, got: &Sim3, want: &Value) {
    for i in 0..3 {
        for j in 0..3 {
            let w = want["R"][i][j].as_f64().expect("R entry");
            assert_close(&format!("{what} R[{i}][{j}]"), got.rotation[(i, j)], w);
        }
        assert_close(&format!("{what} t[{i}]"), got.translation[i], want["t"][i].as_f64().expect("t entry"));
    }
    assert_close(&format!("{what} s"), got.scale, want["s"].as_f64().expect("s"));
}

fn load(dir: &Path, format: Format, reference: &str, estimate: &str) -> (Trajectory, Trajectory) {
    evaluate::load_pair(&dir.join(reference), &dir.join(estimate), format, evaluate::Association::within(0.01))
        .expect("files load and associate")
}

fn rpe_pairs(delta: Delta) -> RpePairs {
    RpePairs { delta, all_pairs: false, from_reference: false }
}

#[test]
fn every_evo_case_is_reproduced() {
    let Some(dir) = data_dir("evo") else { return };
    let expected = read_json(&dir.join("expected/evo_1.38.1_expected.json"));
    let cases = expected["cases"].as_object().expect("cases");
    assert!(cases.len() >= 4, "expected file lists {} cases", cases.len());
    let mut checked = 0;
    for (name, case) in cases {
        let format = match case["format"].as_str() {
            Some("kitti") => Format::Kitti,
            Some("tum") => Format::Tum,
            Some("euroc") => Format::Euroc,
            other => panic!("{name}: unknown format {other:?}"),
        };
        let (r, e) = load(&dir, format, case["ref"].as_str().expect("ref"), case["est"].as_str().expect("est"));
        assert_eq!(r.len() as u64, case["num_ref_poses_after_assoc"].as_u64().expect("count"), "{name}: matched poses");

        for (key, align) in
            [("ape_trans_se3", Align::Se3), ("ape_trans_sim3", Align::Sim3), ("ape_trans_scale_only", Align::Scale)]
        {
            let got = evaluate::ape(&r, &e, align, Relation::Trans).expect("ape");
            assert_stats(&format!("{name} {key}"), &got.stats, &case[key]["stats"]);
            let want = &case[key]["umeyama_est_to_ref"];
            if align == Align::Scale {
                // evo reports the full Umeyama result but applies only its scale.
                assert_close(&format!("{name} {key} s"), got.alignment.scale, want["s"].as_f64().expect("s"));
            } else {
                assert_alignment(&format!("{name} {key}"), &got.alignment, want);
            }
            checked += 1;
        }
        let got = evaluate::ape(&r, &e, Align::None, Relation::Trans).expect("ape");
        assert_stats(&format!("{name} not aligned"), &got.stats, &case["ape_trans_not_aligned"]);

        for (suffix, delta) in [("delta1frames", Delta::Frames(1)), ("delta10.0meters", Delta::Metres(10.0))] {
            for (prefix, relation) in
                [("rpe_translation_part", Relation::Trans), ("rpe_rotation_angle_deg", Relation::AngleDeg)]
            {
                let key = format!("{prefix}_{suffix}");
                let want = &case[&key];
                match evaluate::rpe(&r, &e, Align::None, relation, rpe_pairs(delta)) {
                    Ok(got) => assert_stats(&format!("{name} {key}"), &got.stats, want),
                    Err(err) => assert!(
                        want["error"].as_str().is_some_and(|m| m.contains("empty index list")),
                        "{name} {key}: we failed ({err}) where evo gave {want}"
                    ),
                }
                if want.get("error").is_some() {
                    assert!(
                        evaluate::rpe(&r, &e, Align::None, relation, rpe_pairs(delta)).is_err(),
                        "{name} {key}: evo found no pairs"
                    );
                }
                checked += 1;
            }
        }
    }
    eprintln!("checked {checked} evo results");
}

#[test]
fn every_evo_cli_result_is_reproduced() {
    let Some(dir) = data_dir("evo") else { return };
    let expected = read_json(&dir.join("expected/evo_1.38.1_expected.json"));
    let cli = expected["cli_results"].as_object().expect("cli_results");
    let mut checked = 0;
    for (name, result) in cli {
        let info = &result["info"];
        let title = info["title"].as_str().expect("title");
        let (reference, estimate) = (info["ref_name"].as_str().expect("ref"), info["est_name"].as_str().expect("est"));
        let format = if reference.starts_with("KITTI") { Format::Kitti } else { Format::Tum };
        let align = if title.contains("Sim(3)") {
            Align::Sim3
        } else if title.contains("SE(3)") {
            Align::Se3
        } else if title.contains("scale corrected") {
            Align::Scale
        } else {
            Align::None
        };
        let relation = if title.contains("full transformation") {
            Relation::Full
        } else if title.contains("rotation angle in degrees") {
            Relation::AngleDeg
        } else {
            Relation::Trans
        };
        let (r, e) = load(&dir, format, reference, estimate);
        let got = if title.starts_with("RPE") {
            let delta = if title.contains("delta = 10.0 (m)") {
                Delta::Metres(10.0)
            } else {
                assert!(title.contains("delta = 1 (frames)"), "{name}: unexpected title {title}");
                Delta::Frames(1)
            };
            evaluate::rpe(&r, &e, align, relation, rpe_pairs(delta)).expect("rpe")
        } else {
            evaluate::ape(&r, &e, align, relation).expect("ape")
        };
        assert_stats(name, &got.stats, &result["stats"]);
        checked += 1;
    }
    assert!(checked >= 10, "only {checked} CLI results");
    eprintln!("checked {checked} evo CLI results");
}

#[test]
fn monocular_scale_is_recovered() {
    let Some(dir) = data_dir("evo") else { return };
    let (r, e) = load(&dir, Format::Tum, "freiburg1_xyz-groundtruth.txt", "freiburg1_xyz-ORB_kf_mono.txt");
    let got = evaluate::ape(&r, &e, Align::Sim3, Relation::Trans).expect("ape");
    assert!((got.alignment.scale - 1.1056223637370346).abs() < 1e-9);
}
