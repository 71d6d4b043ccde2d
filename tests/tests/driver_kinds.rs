//! Every kind of driver the generator has, held to what its drive's truth must score
//! (`Driver::expectation`, written to `scenario.json`): the careful and knife-edge drives
//! verify with every metric whole, and each bad driver fails the nuPlan metric it is made
//! to fail and is rejected — so a sweep's "0 verified" per kind tests that kind. And the
//! verdict with its doubt (`verify --decide-at`) on those truths, their σ stated.

use dash2sim_core::map::MapView;
use dash2sim_core::obb::PACIFICA;
use dash2sim_sim::fidelity::drive::verify_truth;
use dash2sim_sim::scenario::profile::{Profile, Receiver};
use dash2sim_sim::scenario::write::{road_tile, write_scenario};
use dash2sim_sim::scenario::{generate, Driver, Expectation, ScenarioConfig};
use dash2sim_verify::decide::{Decided, Decision, DoubtSettings};
use dash2sim_verify::{read_objects, replay_in_doubt, StatedUncertainty};

/// Seeds per kind: drives are 40 s long, as the sweep's.
const SEEDS: std::ops::RangeInclusive<u64> = 1..=6;

#[test]
fn each_drivers_truth_scores_as_its_kind_says() {
    let dir = std::env::temp_dir().join(format!("dash2sim-driver-kinds-{}", std::process::id()));
    let mut report = Vec::new();
    for driver in Driver::ALL {
        for seed in SEEDS {
            let config = ScenarioConfig { driver, ..ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good) };
            let scenario = generate(&config);
            let drive = dir.join(format!("{seed}-{}", driver.name()));
            write_scenario(&scenario, &drive).expect("write");
            let verdict = verify_truth(&scenario, &drive).expect("verify");
            for (mode, v) in [("insensitive", &verdict.insensitive), ("sensitive", &verdict.sensitive)] {
                let failed = v.metrics.failed();
                let holds = match driver.expectation() {
                    Expectation::Verifies => v.verified && failed.is_empty(),
                    Expectation::Fails(metric) => !v.verified && failed.contains(&metric),
                };
                if !holds {
                    report.push(format!("{} seed {seed} ({mode}): {:.2}, failed {failed:?}", driver.name(), v.score));
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(report.is_empty(), "{}", report.join("\n"));
}

/// The verdict with its doubt on the truth of a drive, its poses stated `sigma` m (DRMS), each
/// object's place stated `track_sigma` m along each axis (a covariance, as `finish`'s
/// `TrackCovariance`; 0: none stated), and `object_sigma` m (`--object-sigma`) for those
/// that state none.
fn decided_with(driver: Driver, seed: u64, sigma: f64, track_sigma: f64, object_sigma: f64) -> (f64, Decided) {
    decided_with_hole(driver, seed, sigma, track_sigma, object_sigma, None)
}

/// [`decided_with`], the ego's poses from `hole.0` to `hole.1` s into the drive left out (a
/// VO session `finish` could not anchor).
fn decided_with_hole(
    driver: Driver,
    seed: u64,
    sigma: f64,
    track_sigma: f64,
    object_sigma: f64,
    hole: Option<(f64, f64)>,
) -> (f64, Decided) {
    use dash2sim_core::geo::Geodetic;
    use dash2sim_sim::fidelity::drive::truth_ego;
    let config = ScenarioConfig { driver, ..ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good) };
    let scenario = generate(&config);
    // A folder of its own per call: the tests run in parallel and may generate the same drive.
    static CALLS: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let call = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir =
        std::env::temp_dir().join(format!("dash2sim-doubt-{}-{call}-{seed}-{}", std::process::id(), driver.name()));
    write_scenario(&scenario, &dir).expect("write");
    let [lat, lon, h] = config.origin;
    let tile = road_tile(&dir, Geodetic::new(lat, lon, h).expect("origin")).expect("tile");
    let map = MapView::parse(&tile).expect("map");
    let agents = read_objects(&dir.join("objects.csv")).expect("objects");
    let mut ego = truth_ego(&scenario);
    if let (Some((from, to)), Some(&(t0, _))) = (hole, ego.first()) {
        ego.retain(|(t, _)| !(t0 + from..t0 + to).contains(t));
    }
    let variance = track_sigma * track_sigma;
    let tracks = if track_sigma > 0.0 {
        agents.values().flatten().map(|a| (a.id, [variance, 0.0, variance])).collect()
    } else {
        Default::default()
    };
    let sigmas = StatedUncertainty { ego: vec![sigma; ego.len()], tracks };
    let doubt = DoubtSettings { decide_at: 2.0, object_sigma_m: object_sigma };
    let checker = dash2sim_core::drivable::Checker::new(map, PACIFICA);
    let v = replay_in_doubt(checker, &ego, &sigmas, &agents, false, Some(doubt)).expect("replay");
    let _ = std::fs::remove_dir_all(&dir);
    (v.scores.score, v.decided.expect("asked for a decision"))
}

#[test]
fn a_stated_sigma_makes_a_verdict_undecided_where_the_evidence_cannot_tell() {
    for driver in [Driver::Careful, Driver::Shoulder, Driver::Careless] {
        // No doubt: the decision is nuPlan's verdict, the interval the point.
        let (score, sure) = decided_with(driver, 3, 0.0, 0.0, 0.0);
        let expected = if driver == Driver::Careful { Decision::Verified } else { Decision::Rejected };
        assert_eq!((sure.decision, sure.score_interval), (expected, [score; 2]), "{}", driver.name());
        assert!(sure.in_doubt.is_empty(), "{}: {:?}", driver.name(), sure.in_doubt);
    }
    // A σ of 2 m (a drive without anchors): the careful drive could be over the road's edge
    // and the shoulder drive back on it; neither is decided, and each says why.
    for driver in [Driver::Careful, Driver::Shoulder] {
        let (score, doubtful) = decided_with(driver, 3, 2.0, 0.0, 0.0);
        assert_eq!(doubtful.decision, Decision::Undecided, "{}: {doubtful:?}", driver.name());
        let [low, high] = doubtful.score_interval;
        assert!(low <= score && score <= high, "{}: {score} outside {low}–{high}", driver.name());
        assert!(low <= 90.0 && high > 90.0);
        assert!(doubtful.in_doubt.iter().any(|w| w.starts_with("drivable area")), "{:?}", doubtful.in_doubt);
    }
    // The ego's σ does not move the drums it clipped (they were placed through it); a stated
    // σ for the objects puts the collisions in doubt — but not the verdict: even with every
    // drum shrunk to nothing the careless ego drives at them (time to collision fails).
    let (_, ego_only) = decided_with(Driver::Careless, 3, 2.0, 0.0, 0.0);
    assert_ne!(ego_only.decision, Decision::Verified);
    assert!(!ego_only.in_doubt.iter().any(|w| w.starts_with("collisions")), "{:?}", ego_only.in_doubt);
    let (score, objects) = decided_with(Driver::Careless, 3, 0.0, 0.0, 1.0);
    assert_eq!(objects.decision, Decision::Rejected, "{objects:?}");
    assert!(objects.score_interval[0] <= score && score <= objects.score_interval[1]);
    assert!(objects.score_interval[1] > score, "shrunk drums are not hit: {objects:?}");
    assert!(objects.in_doubt.iter().any(|w| w.starts_with("collisions")), "{:?}", objects.in_doubt);
}

/// A knife-edge drive passes a drum 0.1–0.3 m clear: with no σ stated for the objects its
/// truth is verified; each track stating its place to 0.2 m along each axis
/// (`TrackCovariance`, as `finish` writes it) makes it undecided — a drum 0.4 m (2σ) further
/// in could be in the ego's path — and what the log states for its tracks is what counts,
/// not `--object-sigma` (for the objects that state none).
#[test]
fn a_tracks_stated_sigma_puts_a_near_pass_in_doubt() {
    let (score, sure) = decided_with(Driver::KnifeEdge, 2, 0.0, 0.0, 0.0);
    assert_eq!((sure.decision, sure.tracks_with_sigma), (Decision::Verified, 0), "{sure:?}");
    let (_, stated) = decided_with(Driver::KnifeEdge, 2, 0.0, 0.2, 0.0);
    assert_eq!(stated.decision, Decision::Undecided, "{stated:?}");
    let drms = 0.2 * std::f64::consts::SQRT_2;
    assert!(stated.tracks_with_sigma > 10 && (stated.track_sigma_median_m - drms).abs() < 1e-9, "{stated:?}");
    let [low, high] = stated.score_interval;
    assert!(low < 90.0 && low <= score && high >= score, "{stated:?}");
    assert!(
        stated.in_doubt.iter().any(|w| w.contains("across the ego's path (the tracks' σ median 0.28 m)")),
        "{:?}",
        stated.in_doubt
    );
    // The words name the pass that came nearest: a drum clear as placed, not with its doubt
    // (2 × 0.2 m across the path).
    let nearest = stated.in_doubt.iter().find_map(|w| w.split_once("the nearest pass: track ")).map(|(_, p)| p);
    let clear = |label: &str| -> Option<f64> { nearest?.split(label).next()?.rsplit(' ').next()?.parse().ok() };
    let (placed, in_doubt) = (clear(" m clear of the ego"), clear(" m with its place"));
    assert!(nearest.is_some_and(|p| p.contains("(an object)") && p.contains("± 0.40 m (2σ)")), "{:?}", stated.in_doubt);
    assert!(placed.is_some_and(|m| m > 0.0) && in_doubt == Some(0.0), "{nearest:?}");
    // `--object-sigma` is for objects that state none: a tight stated σ wins over it.
    let (_, tight) = decided_with(Driver::KnifeEdge, 2, 0.0, 0.002, 1.0);
    assert_eq!(tight.decision, Decision::Verified, "{tight:?}");
}

/// A log with a hole (poses missing for 2.5 s: a session `finish` could not anchor) is never
/// verified — whatever happened there is not in it — and says where the hole is; a drive
/// rejected for what the log does show stays rejected.
#[test]
fn a_hole_in_the_log_is_never_verified() {
    let (_, whole) = decided_with_hole(Driver::Careful, 3, 0.0, 0.0, 0.0, None);
    assert_eq!((whole.decision, whole.holes.len()), (Decision::Verified, 0), "{whole:?}");
    let (score, holed) = decided_with_hole(Driver::Careful, 3, 0.0, 0.0, 0.0, Some((15.0, 17.5)));
    assert!(score > 90.0, "nuPlan's score sees only what is there: {score}");
    assert_eq!(holed.decision, Decision::Undecided, "{holed:?}");
    assert_eq!(holed.score_interval[0], 0.0);
    let [[from, to]] = holed.holes[..] else { panic!("one hole: {:?}", holed.holes) };
    assert!((to - from - 2.5).abs() <= 0.11, "{from}–{to}");
    assert!(
        holed.in_doubt.iter().any(|w| w.starts_with("a hole in the log: no ego pose from")),
        "{:?}",
        holed.in_doubt
    );
    let (_, careless) = decided_with_hole(Driver::Careless, 3, 0.0, 0.0, 0.0, Some((15.0, 17.5)));
    assert_eq!(careless.decision, Decision::Rejected, "{careless:?}");
}
