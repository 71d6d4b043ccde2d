//! Every kind of driver the generator has, held to what its drive's truth must score
//! (`Driver::expectation`, written to `scenario.json`): the careful and knife-edge drives
//! verify with every metric whole, and each bad driver fails the nuPlan metric it is made
//! to fail and is rejected — so a sweep's "0 verified" per kind tests that kind.

use dash2sim_linux::sim::fidelity::drive::verify_truth;
use dash2sim_linux::sim::scenario::profile::{Profile, Receiver};
use dash2sim_linux::sim::scenario::write::write_scenario;
use dash2sim_linux::sim::scenario::{generate, Driver, Expectation, ScenarioConfig};

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
