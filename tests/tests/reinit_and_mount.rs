//! Issue #31 on one held-out drive of the typical profile with the hard profile's tracking
//! losses (the VO re-initialises every 60 s with a new origin, heading and scale) and the
//! camera turned on its mount: the device anchors each VO session afresh and says when it
//! is observable again, calibrates the mount, and the finished ego does not jump across a
//! re-initialisation. Measured against the generator's truth.

use std::collections::BTreeMap;

use dash2sim_core::binlog::Record;
use dash2sim_linux::log::LogContents;
use dash2sim_sim::fidelity::drive::{assess, Anchors, Recorded};
use dash2sim_sim::scenario::judge::{judge_log, truth_at};
use dash2sim_sim::scenario::profile::{Profile, Receiver};
use dash2sim_sim::scenario::vo::Reinit;
use dash2sim_sim::scenario::ScenarioConfig;
use dash2sim_tests::recorded::record_config;

/// Drive time (s from frame 1) of every log time of a frame.
fn frame_times(log: &LogContents) -> BTreeMap<i64, f64> {
    let frames: Vec<(i64, i64)> = log
        .records
        .iter()
        .filter_map(|r| if let Record::FrameMeta(f) = r { Some((f.t_us, f.frame)) } else { None })
        .collect();
    let Some(&(t1, _)) = frames.iter().find(|(_, f)| *f == 1) else { return BTreeMap::new() };
    frames.iter().map(|&(t, _)| (t, (t - t1) as f64 * 1e-6)).collect()
}

/// Drive times of the events starting with `prefix`.
fn events(log: &LogContents, prefix: &str, first_frame_us: i64) -> Vec<f64> {
    log.records
        .iter()
        .filter_map(|r| match r {
            Record::Event(e) if e.text.starts_with(prefix.as_bytes()) => Some((e.t_us - first_frame_us) as f64 * 1e-6),
            _ => None,
        })
        .collect()
}

#[test]
fn each_vo_session_is_anchored_again_the_mount_calibrated_and_the_finished_ego_does_not_jump() {
    let mut config =
        ScenarioConfig { duration_s: 200.0, ..ScenarioConfig::drive(2001, Profile::Typical, Receiver::Good) };
    config.vo.reinit = Some(Reinit { every_s: (60.0, 60.0), gap_s: (1.0, 1.0), scale_factor: (0.5, 2.0) });
    let r = record_config(&config, "reinit-mount");
    let (scenario, log, work) = (&r.scenario, &r.log, &r.work);
    let reinits = scenario.vo.reinits();
    assert!(reinits >= 3, "{reinits} re-initialisations in 200 s");
    let first_frame_us = log
        .records
        .iter()
        .find_map(|r| if let Record::FrameMeta(f) = r { (f.frame == 1).then_some(f.t_us) } else { None })
        .expect("frame 1");

    // The device: an event per new session; its ego carried by the last anchored pose and
    // the wheels from the session's first second until the anchorer is observable again,
    // which the carried attitude (the anchorer's rotation prior) makes a matter of seconds.
    let began = events(log, "VO session", first_frame_us);
    let observable = events(log, "anchor: Observable", first_frame_us);
    let errors = judge_log(scenario, log).ego_errors;
    println!("VO sessions began at {began:.1?} s; observable at {observable:.1?} s");
    assert_eq!(began.len() as u32, reinits);
    for t in &began {
        let again = observable.iter().find(|o| *o >= t).map(|o| o - t);
        let frames = (*t * 10.0).round() as usize..((*t + 10.0) * 10.0).round() as usize;
        let within: Vec<f64> = frames.clone().filter_map(|k| errors.get(&k).copied()).collect();
        let worst = within.iter().fold(0.0f64, |m, e| m.max(*e));
        println!(
            "session at {t:.1} s: observable again after {again:.1?} s; {} of the next 100 frames have an ego pose, worst error {worst:.2} m",
            within.len()
        );
        assert!(again.is_some_and(|a| a <= 10.0), "observable again within 10 s of a re-initialisation: {again:?}");
        assert!(within.len() >= 85, "an ego pose for most of the ten seconds after a re-initialisation");
        assert!(worst < 6.0, "within 6 m of the truth: {worst}");
    }

    // The mount: the device's last estimate within 0.5° of the camera's true yaw and pitch.
    let truth = scenario.config.camera.true_mount().roll_pitch_yaw;
    let m = log
        .records
        .iter()
        .rev()
        .find_map(|r| if let Record::MountEstimate(m) = r { Some(*m) } else { None })
        .expect("a mount estimate");
    let (yaw, pitch) =
        ((m.yaw_e6 as f64 * 1e-6 - truth[2]).to_degrees(), (m.pitch_e6 as f64 * 1e-6 - truth[1]).to_degrees());
    println!(
        "mount error: yaw {yaw:+.3}°, pitch {pitch:+.3}° (true yaw {:+.2}°, pitch {:+.2}°)",
        truth[2].to_degrees(),
        truth[1].to_degrees()
    );
    assert!(truth[1].abs().max(truth[2].abs()).to_degrees() > 0.5, "the drive's camera is turned on its mount");
    assert!(m.calibrated == 1 && yaw.abs() < 0.5 && pitch.abs() < 0.5);

    // Finishing: one solution per session, and across each gap the finished ego moves as
    // the car did (its error changes by less than 1 m from the last pose before the gap to
    // the first after).
    let log_name = "reinit.d2slog".to_owned();
    let recorded =
        Recorded { scenario, drive_dir: &work.join("drive"), log, log_name: &log_name, tile: &r.tile, setup: &r.setup };
    let a = assess(&recorded, Anchors::Street, &work.join("anchors.csv"), None, Default::default()).expect("assess");
    assert_eq!(a.finish_report.sessions.len(), reinits as usize + 1, "{:?}", a.finish_report);
    // Every finished pose states its σ; most lie within 2σ of the truth (79 % on this drive
    // of three joins; the target, 90 %, is not met yet: docs/fidelity.md).
    let poses = a.finished_log.records.iter().filter(|r| matches!(r, Record::EgoPose(_))).count();
    let sigma = a.finished.judgement.sigma;
    println!(
        "finished σ: {} of {poses} poses state one, {:.1} % within 2σ, mean NEES {:.2} (2 when right)",
        sigma.poses,
        100.0 * sigma.fraction(),
        sigma.nees()
    );
    assert_eq!(sigma.poses, a.finished.judgement.ego_errors.len(), "every judged finished pose has a σ");
    assert!(sigma.fraction() >= 0.75, "{sigma:?}");
    let times = frame_times(&a.finished_log);
    let error = |t_us: i64, x: f64, y: f64| {
        let t = *times.get(&t_us)?;
        let truth = truth_at(scenario, t)?;
        Some((t, x - truth.x, y - truth.y))
    };
    let errors: Vec<(f64, f64, f64)> = a
        .finished_log
        .records
        .iter()
        .filter_map(|r| {
            if let Record::EgoPose(p) = r {
                error(p.t_us, p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3)
            } else {
                None
            }
        })
        .collect();
    let mut jumps = Vec::new();
    for w in errors.windows(2) {
        let ((t0, x0, y0), (t1, x1, y1)) = (w[0], w[1]);
        if t1 - t0 > 0.5 {
            jumps.push(((x1 - x0).hypot(y1 - y0), t0));
        }
    }
    println!("finished ego across the gaps: {jumps:.2?} (error change m, at s)");
    assert_eq!(jumps.len() as u32, reinits);
    assert!(jumps.iter().all(|(j, _)| *j < 1.0), "{jumps:?}");
    let _ = std::fs::remove_dir_all(work);
}
