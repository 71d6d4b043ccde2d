//! `dash2sim finish` on the comma2k19 minute (issue #14): the log `record` writes from the
//! real u-blox fixes, the real Toyota CAN speed and VO made from comma's fused poses
//! through an unknown Sim(3) with drift, finished offline and compared with the fused poses.
//!
//! Targets: finished ATE below the online anchorer's 1.30 m and scale error ≤ 0.1 %; with
//! anchors made from the fused poses every 50 m with σ 0.3 m noise, ATE ≤ 0.15 m absolute
//! and ≤ 0.084 m after Sim(3) alignment. The ablation the test prints is the table in
//! `docs/finishing.md`.

use dash2sim_core::binlog::{quantise, GnssFix, Record};
use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_finish::anchors;
use dash2sim_finish::solve::Settings;
use dash2sim_finish::{finish, Finished};
use dash2sim_linux::log::LogContents;
use dash2sim_linux::trajectory::Trajectory;
use dash2sim_sim::datasets::comma::{compare, mount, record_minute, truth_at, ORIGIN, UERE};
use dash2sim_sim::datasets::device_times;
use dash2sim_sim::scenario::vo::VoModel;
use dash2sim_tests::recorded::scratch;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// How a finished drive compares with the fused poses.
#[derive(Debug)]
struct Judged {
    ate: f64,
    ate_aligned: f64,
    /// Scale of the Sim(3) that best maps the finished track onto the truth, minus one.
    scale_error: f64,
    /// RMS over the anchor estimates of their scale against the VO model's, relative.
    segment_scale_rms: f64,
}

fn judge(finished: &[Record], truth: &Trajectory, model: &VoModel) -> Judged {
    let device = device_times(finished).expect("UTC");
    let t0 = truth.stamps[0];
    let compared = compare(finished, &device, truth).expect("comparison");
    assert!(compared.matched > 1000, "{} finished poses matched the truth", compared.matched);
    let scale_errors: Vec<f64> = finished
        .iter()
        .zip(&device)
        .filter_map(|(r, t)| match r {
            Record::AnchorEstimate(a) => Some(a.scale_e6 as f64 * 1e-6 / model.scale_at(t - t0) - 1.0),
            _ => None,
        })
        .collect();
    Judged {
        ate: compared.ape_rmse,
        ate_aligned: compared.ape_aligned,
        scale_error: compared.scale_error,
        segment_scale_rms: (scale_errors.iter().map(|e| e * e).sum::<f64>() / scale_errors.len().max(1) as f64).sqrt(),
    }
}

/// Anchors from the fused poses every `spacing` m along the drive with N(0, σ) noise per
/// axis, at the log times of the VO poses (the rear axle is the camera with this mount).
fn anchors_from_truth(log: &LogContents, truth: &Trajectory, spacing: f64, sigma: f64, seed: u64) -> String {
    let frame = LocalFrame::new(Geodetic::new(ORIGIN[0], ORIGIN[1], ORIGIN[2]).expect("origin"));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, sigma).expect("σ");
    let device = device_times(&log.records).expect("UTC");
    let mut text = String::from("t,lat,lon,alt,sigma_m\n");
    let (mut travelled, mut last, mut next) = (0.0, None::<Vector3<f64>>, 0.0);
    for (r, &t) in log.records.iter().zip(&device) {
        let Record::VoPose(p) = r else { continue };
        let Some(x) = truth_at(truth, t) else { continue };
        travelled += last.map_or(0.0, |l| (x - l).norm());
        last = Some(x);
        if travelled >= next {
            next += spacing;
            let noisy = x + Vector3::new(noise.sample(&mut rng), noise.sample(&mut rng), noise.sample(&mut rng));
            let g = frame.enu_to_geodetic(&noisy).expect("geodetic");
            text +=
                &format!("{:.6},{:.10},{:.10},{:.4},{sigma}\n", p.t_us as f64 * 1e-6, g.lat_deg, g.lon_deg, g.height_m);
        }
    }
    text
}

/// The log with its fixes replaced by the truth (at the receive time's pose) plus iid
/// noise of σ_h / σ_v, HDOP set so that σ = HDOP × UERE: a coarse receiver.
fn coarse_gnss(log: &LogContents, truth: &Trajectory, sigma_h: f64, sigma_v: f64, seed: u64) -> LogContents {
    let frame = LocalFrame::new(Geodetic::new(ORIGIN[0], ORIGIN[1], ORIGIN[2]).expect("origin"));
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (h, v) = (Normal::new(0.0, sigma_h).expect("σ"), Normal::new(0.0, sigma_v).expect("σ"));
    let device = device_times(&log.records).expect("UTC");
    let mut records = Vec::new();
    for (r, &t) in log.records.iter().zip(&device) {
        match r {
            Record::GnssFix(f) => {
                let Some(x) = truth_at(truth, t) else { continue };
                let noisy = x + Vector3::new(h.sample(&mut rng), h.sample(&mut rng), v.sample(&mut rng));
                let g = frame.enu_to_geodetic(&noisy).expect("geodetic");
                records.push(Record::GnssFix(GnssFix {
                    lat_e7: quantise(g.lat_deg, 1e-7),
                    lon_e7: quantise(g.lon_deg, 1e-7),
                    alt_mm: quantise(g.height_m, 1e-3),
                    hdop_e2: quantise(sigma_h / UERE, 1e-2),
                    ..*f
                }));
            }
            other => records.push(other.clone()),
        }
    }
    LogContents { records, damage: Vec::new(), signing: log.signing.clone(), ..*log }
}

fn without_speed(log: &LogContents) -> LogContents {
    LogContents {
        records: log.records.iter().filter(|r| !matches!(r, Record::VehicleSpeed(_))).cloned().collect(),
        damage: Vec::new(),
        signing: log.signing.clone(),
        ..*log
    }
}

fn run(log: &LogContents, anchor_text: Option<&str>) -> Finished {
    let file = anchor_text.map(|text| anchors::parse(text).expect("anchors"));
    finish(&log.compact(), "comma", file.as_ref().map(|f| ("anchors.csv", f)), None, mount(), Settings::default(), UERE)
        .expect("finish")
}

#[test]
fn finishing_the_comma2k19_minute_beats_the_online_anchorer_and_meets_the_papers_figure_with_anchors() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let work = scratch("comma-finish");
    let model = VoModel::arbitrary();
    let recorded = record_minute(&dir, &work, &model, 1).expect("record");
    let (log, truth) = (&recorded.log, &recorded.truth);
    // "σ 0.3 m" read two ways: 0.3 m per axis (0.52 m in 3D), and 0.3 m of 3D error
    // (0.17 m per axis).
    let per_axis = anchors_from_truth(log, truth, 50.0, 0.3, 7);
    let anchors_50m = anchors_from_truth(log, truth, 50.0, 0.3 / 3f64.sqrt(), 7);
    let coarse = coarse_gnss(log, truth, 10.0, 15.0, 11);

    let variants: [(&str, LogContents, Option<&str>); 7] = [
        ("real GNSS alone", without_speed(log), None),
        ("real GNSS + wheel speed", log_clone(log), None),
        ("real GNSS + wheel speed + anchors every 50 m (σ 0.3 m in 3D)", log_clone(log), Some(&anchors_50m)),
        ("coarse GNSS (iid σ 10 m / 15 m) alone", without_speed(&coarse), None),
        ("coarse GNSS + wheel speed", log_clone(&coarse), None),
        ("coarse GNSS + wheel speed + anchors every 50 m (σ 0.3 m in 3D)", log_clone(&coarse), Some(&anchors_50m)),
        ("real GNSS + wheel speed + anchors every 50 m (σ 0.3 m per axis)", log_clone(log), Some(&per_axis)),
    ];
    println!("| inputs | scale error | ATE (m) | ATE after Sim(3) (m) | segment scale RMS | anchors used | stated scale σ | stated position σ (m) |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut judged = Vec::new();
    for (name, log, anchor_text) in &variants {
        let finished = run(log, *anchor_text);
        let j = judge(&finished.records.to_vec(), truth, &model);
        let a = &finished.report.anchoring;
        println!(
            "| {name} | {:+.3} % | {:.3} | {:.3} | {:.3} % | {} | {:.3} % | {:.2} |",
            100.0 * j.scale_error,
            j.ate,
            j.ate_aligned,
            100.0 * j.segment_scale_rms,
            finished.report.anchors.used,
            100.0 * a.scale_sigma_relative,
            a.position_sigma_m,
        );
        judged.push(j);
        // The solve converges rather than running out of iterations (issue #58: with the
        // rotation damping held fixed it used all 50 here, short of GTSAM's optimum).
        assert!(a.iterations < Settings::default().max_iterations, "{name}: {} iterations", a.iterations);
    }
    let default = &judged[1];
    assert!(default.ate < 1.30, "finished ATE {} not below the online anchorer's 1.30 m", default.ate);
    assert!(default.scale_error.abs() <= 1e-3, "scale error {}", default.scale_error);
    let anchored = &judged[2];
    assert!(anchored.ate <= 0.15, "ATE with anchors {}", anchored.ate);
    assert!(anchored.ate_aligned <= 0.084, "ATE after Sim(3) with anchors {}", anchored.ate_aligned);
    assert!(anchored.scale_error.abs() <= 1e-3, "scale error with anchors {}", anchored.scale_error);
    assert_eq!(finished_anchors_used(&variants[2].1, &anchors_50m), anchors_50m.lines().count() - 1);
    // With 0.3 m per axis the targets are not reached (docs/finishing.md: 21 anchors at that
    // noise put a floor near them); this guards what the solver does.
    let noisier = &judged[6];
    assert!(noisier.ate <= 0.2 && noisier.ate_aligned <= 0.12, "{noisier:?}");
    // Anchors rescue a coarse receiver.
    assert!(judged[5].ate < 0.5 * judged[4].ate, "{:?} vs {:?}", judged[5], judged[4]);
}

fn finished_anchors_used(log: &LogContents, anchors: &str) -> usize {
    run(log, Some(anchors)).report.anchors.used
}

fn log_clone(log: &LogContents) -> LogContents {
    LogContents { records: log.records.clone(), damage: log.damage.clone(), signing: log.signing.clone(), ..*log }
}

/// The median and the largest of `values`.
fn median_and_worst(values: &mut [f64]) -> (f64, f64) {
    values.sort_by(f64::total_cmp);
    (values[values.len() / 2], values[values.len() - 1])
}

/// The minute recorded with VO made by `model` (noise from `seed`), finished with GNSS and
/// wheel speed, and with anchors every 50 m (σ 0.3 m per axis): online ATE, finished ATE,
/// after Sim(3), |scale error|, ATE with anchors, after Sim(3). `label` names the row
/// printed. The VO sessions the recording had are checked to be `sessions`.
fn typical_minute(dir: &std::path::Path, model: &VoModel, seed: u64, label: &str, sessions: u32) -> [f64; 6] {
    let work = scratch(&format!("comma-typical-{label}"));
    let recorded = record_minute(dir, &work, model, seed).expect("record");
    let (log, truth) = (&recorded.log, &recorded.truth);
    let last_session = std::fs::read_to_string(work.join("vo.csv"))
        .expect("vo.csv")
        .lines()
        .skip(1)
        .filter_map(|l| l.rsplit(',').next()?.parse::<u32>().ok())
        .max();
    assert_eq!(last_session, Some(sessions - 1), "{label}: {sessions} VO session(s) in the minute");
    let on = compare(&log.records, &recorded.device, truth).expect("online comparison");
    let gnss = run(log, None).records.to_vec();
    let fin = compare(&gnss, &device_times(&gnss).expect("UTC"), truth).expect("finished");
    let with = run(log, Some(&anchors_from_truth(log, truth, 50.0, 0.3, seed))).records.to_vec();
    let anc = compare(&with, &device_times(&with).expect("UTC"), truth).expect("anchored");
    assert!(fin.matched > 1000 && anc.matched > 1000, "{label}: {} / {} poses", fin.matched, anc.matched);
    let row = [on.ape_rmse, fin.ape_rmse, fin.ape_aligned, fin.scale_error.abs(), anc.ape_rmse, anc.ape_aligned];
    println!(
        "| {label} | {:.2} | {:.2} | {:.2} | {:.2} % | {:.2} | {:.2} |",
        row[0],
        row[1],
        row[2],
        100.0 * row[3],
        row[4],
        row[5]
    );
    row
}

/// Issues #30 and #31: the minute with the typical profile's VO — noise on every increment
/// of translation and rotation, random-walk scale and heading, a bounded tilt — with one
/// tracking loss and re-initialisation (a new origin, heading and scale) and without, over
/// five noise seeds. Each VO session is anchored on its own, so the re-initialised minute
/// finishes as well as the steady one (it had been hundreds of metres off). The figures are
/// in docs/fidelity.md (`cargo test --release -p dash2sim-tests --test finish_comma2k19 --
/// --nocapture`).
#[test]
fn the_comma2k19_minute_with_a_typical_vo_over_five_noise_seeds() {
    use dash2sim_sim::scenario::profile::{Profile, Receiver};
    use dash2sim_sim::scenario::vo::Reinit;
    use dash2sim_sim::scenario::ScenarioConfig;
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    println!("| noise seed | online ATE (m) | finished ATE, GNSS + wheel speed (m) | after Sim(3) | abs. scale error | with anchors every 50 m, σ 0.3 m per axis (m) | after Sim(3) |");
    println!("|---|---|---|---|---|---|---|");
    let (mut reinit_rows, mut steady_rows) = (Vec::new(), Vec::new());
    for seed in 1..=5u64 {
        // The typical profile's VO for this seed, re-initialised once in the minute (the
        // profile's every 2–5 min would put one in a minute only now and then).
        let typical = ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good).vo;
        let reinit = Reinit { every_s: (60.0, 60.0), ..typical.reinit.expect("the typical profile re-initialises") };
        let model = VoModel { reinit: Some(reinit), ..typical };
        reinit_rows.push(typical_minute(&dir, &model, seed, &format!("{seed}, one re-init"), 2));
        // The same noise without the re-initialisation: what the rest of the model costs.
        let steady = VoModel { reinit: None, ..model };
        steady_rows.push(typical_minute(&dir, &steady, seed, &format!("{seed}, no re-init"), 1));
    }
    let names = ["online ATE", "finished ATE", "after Sim(3)", "|scale error|", "ATE with anchors", "after Sim(3)"];
    for (variant, rows) in [("one re-init", &reinit_rows), ("no re-init", &steady_rows)] {
        for (k, name) in names.iter().enumerate() {
            let (median, worst) = median_and_worst(&mut rows.iter().map(|r| r[k]).collect::<Vec<_>>());
            assert!(median.is_finite() && worst.is_finite(), "{variant} {name}");
            println!("{variant}: {name} median {median:.4}, worst {worst:.4}");
        }
    }
    // Issue #31's targets for GNSS + wheel speed: ATE ≤ 1.35 m, scale error ≤ 0.3 % (median).
    let median_of =
        |rows: &[[f64; 6]], k: usize| median_and_worst(&mut rows.iter().map(|r| r[k]).collect::<Vec<_>>()).0;
    assert!(median_of(&reinit_rows, 1) <= 1.35, "re-initialised minute: finished ATE {}", median_of(&reinit_rows, 1));
    assert!(median_of(&reinit_rows, 3) <= 0.003 && median_of(&steady_rows, 3) <= 0.003);
    // Anchors still help across the re-initialisation (the target, 0.15 m, is not met: the
    // typical VO's rotation jitter and random walks; docs/fidelity.md).
    assert!(median_of(&reinit_rows, 4) < 0.5 * median_of(&reinit_rows, 1));
}
