//! Anchoring on real data (comma2k19, I-280): the fused 6-DoF poses are the truth; a VO
//! track is made from them with a known Sim(3) and slow drift, then anchored online with
//! the real u-blox fixes and the real CAN speed. Targets from issue #2.

use dash2sim_core::anchor::{AnchorConfig, AnchorMode};
use dash2sim_core::sim3::rotation_z;
use dash2sim_core::time::Duration;
use dash2sim_tests::drive::{self, VoModel};
use dash2sim_tests::{data_dir, read_json};

fn raw_gnss_ape(dir: &std::path::Path) -> f64 {
    let evo = read_json(&dir.join("expected/evo_ape_gnss_vs_pose.json"));
    evo["cases"]["maxdiff0.026_none"]["ape_translation_stats"]["rmse"].as_f64().expect("rmse")
}

#[test]
fn anchoring_meets_the_scale_ate_and_observability_targets() {
    let Some(dir) = data_dir("comma2k19") else { return };
    let inputs = drive::load(&dir);
    let model = VoModel::arbitrary();
    let out = drive::run(&inputs, &model, &inputs.gnss, true, AnchorConfig::default());
    let raw = raw_gnss_ape(&dir);
    let last = out.frames.last().expect("frames");
    eprintln!("observable after {:?} s", out.observable_after_s);
    for s in [5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 59.9] {
        eprintln!(
            "t={s:>4} s scale error {:?}",
            drive::scale_error_at(&out, s).map(|e| format!("{:+.3} %", 100.0 * e))
        );
    }
    eprintln!("ATE rmse {:.3} m (raw GNSS APE {raw:.3} m)", out.ate_rmse_m);
    eprintln!("latency {:?} s, wheel factor {:?}", last.quality.latency_s, last.quality.wheel_factor);
    eprintln!("anchors used {} rejected {}", last.quality.anchors_used, last.quality.anchors_rejected);

    let observable = out.observable_after_s.expect("becomes observable");
    assert!(observable < 10.0, "observable only after {observable} s");
    assert!(drive::worst_scale_error_after(&out, 10.0) < 0.01, "scale error above 1 % after 10 s");
    let end = drive::scale_error_at(&out, 59.9).expect("estimate at the end").abs();
    assert!(end < 0.003, "final scale error {end}");
    assert!(out.ate_rmse_m <= 1.05 * raw, "ATE {} vs raw GNSS {raw}", out.ate_rmse_m);
    let latency = last.quality.latency_s.expect("latency estimated");
    assert!((0.04..=0.11).contains(&latency), "latency {latency}");
    let factor = last.quality.wheel_factor.expect("wheel calibrated");
    assert!((1.004..1.013).contains(&factor), "wheel factor {factor} (CAN reads ~0.85 % low)");
}

/// A deterministic generator for test perturbations (splitmix64).
fn splitmix(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    (z ^ (z >> 31)) as f64 / u64::MAX as f64
}

#[test]
fn fifty_metre_outliers_do_not_move_the_track() {
    let Some(dir) = data_dir("comma2k19") else { return };
    let inputs = drive::load(&dir);
    let model = VoModel::arbitrary();
    let clean = drive::run(&inputs, &model, &inputs.gnss, true, AnchorConfig::default());
    let mut gnss = inputs.gnss.clone();
    let mut rng = 7u64;
    let t0 = inputs.truth.stamps[0];
    let mut injected = 0;
    // Ten multipath jumps of 50 m, spread over 5..58 s, in random horizontal directions.
    for k in 0..10 {
        let t = t0 + 5.0 + 5.3 * k as f64 + splitmix(&mut rng);
        let i = gnss.stamps.iter().position(|&s| s >= t).expect("fix after t");
        let heading = splitmix(&mut rng) * std::f64::consts::TAU;
        gnss.poses[i].translation += rotation_z(heading) * dash2sim_core::nalgebra::Vector3::new(50.0, 0.0, 0.0);
        injected += 1;
    }
    let dirty = drive::run(&inputs, &model, &gnss, true, AnchorConfig::default());
    let last = dirty.frames.last().expect("frames");
    assert_eq!(last.quality.anchors_rejected, injected, "every injected outlier rejected, nothing else");
    let mut worst_online = 0.0f64;
    for (a, b) in clean.anchored.iter().zip(&dirty.anchored) {
        if let (Some(a), Some(b)) = (a, b) {
            worst_online = worst_online.max((a - b).norm());
        }
    }
    // The final estimate applied to the whole VO track, with and without outliers.
    let vo = model.make_vo(&inputs.truth);
    let (fc, fd) = (clean.frames.last().and_then(|f| f.estimate).expect("estimate"), last.estimate.expect("estimate"));
    let final_shift =
        vo.positions().map(|x| (fc.transform_point(x) - fd.transform_point(x)).norm()).fold(0.0, f64::max);
    eprintln!("outliers: worst online difference {worst_online:.3} m, final track moved {final_shift:.3} m");
    assert!(worst_online < 2.0, "an online estimate jumped by {worst_online} m");
    assert!(final_shift < 0.2, "final track moved {final_shift} m");
}

#[test]
fn gravity_aligned_mode_on_a_yaw_only_vo_frame() {
    let Some(dir) = data_dir("comma2k19") else { return };
    let inputs = drive::load(&dir);
    let model = VoModel { rotation: rotation_z(-1.9), scale: 0.37, ..VoModel::arbitrary() };
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let four = drive::run(&inputs, &model, &inputs.gnss, true, config);
    let seven = drive::run(&inputs, &model, &inputs.gnss, true, AnchorConfig::default());
    let raw = raw_gnss_ape(&dir);
    eprintln!(
        "gravity-aligned: observable after {:?} s, ATE {:.3} m, end scale error {:+.3} %; full 7-DoF on the same VO: observable after {:?} s, ATE {:.3} m",
        four.observable_after_s,
        four.ate_rmse_m,
        100.0 * drive::scale_error_at(&four, 59.9).unwrap_or(f64::NAN),
        seven.observable_after_s,
        seven.ate_rmse_m
    );
    assert!(four.observable_after_s.expect("observable") < 10.0);
    assert!(four.ate_rmse_m <= 1.05 * raw);
    assert!(drive::worst_scale_error_after(&four, 10.0) < 0.01);
}

#[test]
fn each_part_of_the_anchorer_earns_its_place() {
    let Some(dir) = data_dir("comma2k19") else { return };
    let inputs = drive::load(&dir);
    let model = VoModel::arbitrary();
    let full = drive::run(&inputs, &model, &inputs.gnss, true, AnchorConfig::default());
    let no_latency = drive::run(
        &inputs,
        &model,
        &inputs.gnss,
        true,
        AnchorConfig { latency_step: Duration::ZERO, ..AnchorConfig::default() },
    );
    let no_wheels = drive::run(&inputs, &model, &inputs.gnss, false, AnchorConfig::default());
    let end = |o: &drive::Outcome| 100.0 * drive::scale_error_at(o, 59.9).unwrap_or(f64::NAN);
    eprintln!(
        "| variant | observable after (s) | ATE (m) | scale error at 60 s (%) | worst scale error after 10 s (%) |"
    );
    for (name, o) in [("full", &full), ("no latency estimation", &no_latency), ("no wheel speed", &no_wheels)] {
        eprintln!(
            "| {name} | {:.2} | {:.3} | {:+.3} | {:.3} |",
            o.observable_after_s.unwrap_or(f64::NAN),
            o.ate_rmse_m,
            end(o),
            100.0 * drive::worst_scale_error_after(o, 10.0)
        );
    }
    assert!(full.ate_rmse_m < 0.8 * no_latency.ate_rmse_m, "latency estimation must clearly lower the ATE");
    assert!(end(&full).abs() < end(&no_wheels).abs(), "wheel speed must improve the final scale");
}
