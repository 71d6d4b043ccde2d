//! Issue #31, the device's verification windows: judged on the ego with the anchorer's
//! corrections eased in and smoothed a second late, against agents that include those the
//! tracker lost within the lag. On typical-profile drives (seeds the sweep never runs, both
//! drivers) the raw anchored ego failed comfort in nearly every window; here it passes
//! comfort in most, the verdicts agree with the truth's in four windows of five (the map's
//! metrics allowing for the ego's σ), and no window in which the true drive collides is
//! verified. The same drives hold the device's stated σ to its error: every ego pose states
//! one, and most lie within 2σ of the truth.

use dash2sim_core::binlog::Record;
use dash2sim_sim::fidelity::drive::{assess, Anchors, Recorded};
use dash2sim_sim::scenario::profile::{Profile, Receiver};
use dash2sim_sim::scenario::{Driver, ScenarioConfig};
use dash2sim_tests::recorded::record_config;

#[test]
fn device_windows_verify_where_the_truth_does_and_never_over_a_collision() {
    let (mut agree, mut total, mut truth_verified, mut both_verified) = (0, 0, 0, 0);
    let (mut comfortable, mut windows) = (0, 0);
    let (mut sigma_poses, mut within_2sigma) = (0, 0);
    let mut collisions = 0;
    for seed in 2011..2017 {
        for driver in [Driver::Careful, Driver::Careless] {
            let config = ScenarioConfig { driver, ..ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good) };
            let r = record_config(&config, &format!("device-windows-{seed}-{}", driver.name()));
            let log = &r.log;
            let judged: Vec<(i64, i64)> = log
                .records
                .iter()
                .filter_map(|record| {
                    if let Record::Verification(v) = record {
                        Some((v.comfort_e4, v.speed_limit_e4))
                    } else {
                        None
                    }
                })
                .collect();
            println!("seed {seed} {}: comfort, speed limit ×1e4 {judged:?}", driver.name());
            // The windows counted as collisions (what keeps a file under loop recording) are
            // those whose collision multiplier is below 1.
            let collided = log
                .records
                .iter()
                .filter(|record| matches!(record, Record::Verification(v) if v.collisions_e4 < 10_000))
                .count() as u64;
            assert_eq!(r.recording.stats.collision_windows, collided, "seed {seed}");
            collisions += collided;
            windows += judged.len();
            comfortable += judged.iter().filter(|(comfort, _)| *comfort == 10_000).count();
            let log_name = format!("windows-{seed}.d2slog");
            let recorded = Recorded {
                scenario: &r.scenario,
                drive_dir: &r.work.join("drive"),
                log,
                log_name: &log_name,
                tile: &r.tile,
                setup: &r.setup,
            };
            let a = assess(&recorded, Anchors::None, &r.work.join("anchors.csv"), None, Default::default())
                .expect("assess");
            for record in &log.records {
                if let Record::EgoPose(p) = record {
                    assert!(p.sigma_mm > 0, "seed {seed}: an ego pose without its σ: {p:?}");
                }
            }
            sigma_poses += a.online.judgement.sigma.poses;
            within_2sigma += a.online.judgement.sigma.within_2sigma;
            for w in &a.windows {
                println!(
                    "seed {seed} {:8} {:5.1}–{:5.1} s: device {:6.2} truth {:6.2}{}",
                    driver.name(),
                    w.start_s,
                    w.end_s,
                    w.device_score,
                    w.truth_score,
                    if w.truth_collision { " (collision)" } else { "" }
                );
                assert!(!(w.truth_collision && w.device_verified), "seed {seed}: verified over a collision: {w:?}");
                total += 1;
                agree += usize::from(w.device_verified == w.truth_verified);
                truth_verified += usize::from(w.truth_verified);
                both_verified += usize::from(w.truth_verified && w.device_verified);
            }
        }
    }
    println!(
        "{agree} of {total} windows agree; {both_verified} of the truth's {truth_verified} verified windows verified"
    );
    // The raw anchored ego's accelerations (a median of 1.5–3 m/s², peaks of 10–40) failed
    // comfort in nearly every window; smoothed, the comfort of a drive the generator made
    // comfortable is seen in most.
    println!("{comfortable} of {windows} device windows comfortable");
    println!("{collisions} device windows with a collision");
    assert!(collisions > 0, "the careless drives collide: the count above is not vacuous");
    assert!(total >= 24, "{total} windows");
    assert!(comfortable * 4 >= windows * 3, "three in four windows comfortable: {comfortable} of {windows}");
    // The windows' map metrics allow for the ego's stated σ (`Scorer::step_in_doubt`):
    // without it, its 2 m error against the work zone's lanes failed drivable area or the
    // driving direction where the truth kept inside (18 of these 30 windows agreed, 10 of
    // the truth's 22 verified ones verified; 27 and 19 with it). Issue #31's target is 80 %
    // over the sweep (85.5 % of 461 typical windows, docs/fidelity.md).
    assert!(both_verified > 0);
    assert!(agree * 5 >= total * 4, "{agree} of {total} windows agree with the truth's");
    // Issue #31's target is 90 % over the sweep (94.7 % on 200 typical drives,
    // docs/fidelity.md); on these twelve the bound leaves room for their spread.
    println!("{within_2sigma} of {sigma_poses} device poses within 2σ of the truth");
    assert!(sigma_poses > 1000, "{sigma_poses} poses with a σ");
    assert!(within_2sigma * 100 >= sigma_poses * 85, "{within_2sigma} of {sigma_poses} within 2σ");
}

/// A window ends at a gap in the ego (a VO re-initialisation, before the carry or the new
/// session's anchor takes over): the device saw nothing in the gap, so no verdict may cover
/// it. A window holds the ego poses after the previous window's record up to its own.
#[test]
fn no_window_spans_a_gap_in_the_ego() {
    let mut gaps = 0;
    // Typical drives (seeds the sweep never runs) whose VO re-initialises with no pose for
    // 1.2–2 s.
    for seed in [2005, 2018] {
        let config = ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good);
        let r = record_config(&config, &format!("window-gaps-{seed}"));
        let mut previous: Option<i64> = None;
        let mut in_window: Vec<i64> = Vec::new();
        let mut ego: Vec<i64> = Vec::new();
        for record in &r.log.records {
            match record {
                Record::EgoPose(p) => ego.push(p.t_us),
                Record::Verification(v) => {
                    in_window.clear();
                    in_window.extend(ego.iter().copied().filter(|&t| previous.is_none_or(|p| t > p) && t <= v.t_us));
                    for pair in in_window.windows(2) {
                        assert!(
                            pair[1] - pair[0] <= 1_000_000,
                            "seed {seed}: the window ending at {} µs spans a gap of {} µs in the ego",
                            v.t_us,
                            pair[1] - pair[0]
                        );
                    }
                    previous = Some(v.t_us);
                }
                _ => {}
            }
        }
        gaps += ego.windows(2).filter(|pair| pair[1] - pair[0] > 1_000_000).count();
    }
    assert!(gaps > 0, "the drives have gaps in the ego: the check above is not vacuous");
}
