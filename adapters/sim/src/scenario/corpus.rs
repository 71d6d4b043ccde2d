//! `dash2sim scenario corpus`: a folder of device logs as a fleet uploads them — many
//! generated drives (seeds, lengths, regions, careful and careless drivers), each recorded
//! through the on-device pipeline, with its map tile beside it, and some damaged on purpose
//! in the ways real uploads are. The corpus job (`docs/fleet.md`) and its benchmark run on
//! it; `corpus.json` says what each log is, so a test can hold the job to it.

use std::path::{Path, PathBuf};

use dash2sim_core::geo::Geodetic;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::profile::{Profile, Receiver};
use super::write::{road_tile, write_scenario};
use super::{generate, Driver, ScenarioConfig};
use crate::{Error, Result};
use dash2sim_linux::record::{self, Setup, Sources};

/// A corpus to generate (`dash2sim scenario corpus`).
#[derive(Debug, Clone)]
pub struct CorpusRequest {
    /// Output folder: `drive-NNNN.d2slog` with `drive-NNNN.map` beside each, and `corpus.json`.
    pub output: PathBuf,
    /// How many logs.
    pub logs: usize,
    /// Every this many logs, one is damaged (0: none), cycling through the kinds of damage.
    pub damaged_every: usize,
    /// Seed of the first drive; the others follow.
    pub first_seed: u64,
    /// How far the sensors are from ideal.
    pub profile: Profile,
}

/// What [`make_corpus`] wrote.
#[derive(Debug, Clone)]
pub struct Corpus {
    /// Logs written.
    pub logs: usize,
    /// Of them, damaged on purpose.
    pub damaged: usize,
    /// `corpus.json`, which says what each log is.
    pub listing: PathBuf,
}

/// Where the drives are: the synthetic road is placed at each origin in turn.
const REGIONS: [(&str, [f64; 3]); 3] = [
    ("helsinki", [60.2711, 24.8572, 20.0]),
    ("tampere", [61.4978, 23.7610, 110.0]),
    ("oulu", [65.0121, 25.4651, 15.0]),
];

/// Lengths of the drives, s, in turn.
const DURATIONS: [f64; 4] = [20.0, 30.0, 40.0, 50.0];

/// How a log is damaged, in turn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Damage {
    /// Not a log at all (an upload of the wrong file).
    Garbage,
    /// The file ends inside the header (an upload cut short).
    HeaderCut,
    /// The file ends mid-record at 60 % (power lost while writing): the intact part finishes.
    TailCut,
    /// One byte in 300 flipped (bad storage): damaged stretches are skipped.
    BitFlips,
    /// Recorded without the GNSS receiver: nothing to anchor the VO to.
    NoGnss,
    /// The map tile is missing.
    NoMap,
}

const DAMAGES: [Damage; 6] =
    [Damage::Garbage, Damage::HeaderCut, Damage::TailCut, Damage::BitFlips, Damage::NoGnss, Damage::NoMap];

impl Damage {
    fn name(self) -> &'static str {
        match self {
            Damage::Garbage => "garbage",
            Damage::HeaderCut => "header-cut",
            Damage::TailCut => "tail-cut",
            Damage::BitFlips => "bit-flips",
            Damage::NoGnss => "no-gnss",
            Damage::NoMap => "no-map",
        }
    }
}

/// One log of the corpus, as chosen from its index.
#[derive(Clone, Copy, Debug)]
struct Plan {
    name_index: usize,
    seed: u64,
    duration_s: f64,
    driver: Driver,
    region: usize,
    damage: Option<Damage>,
    profile: Profile,
}

fn plan(args: &CorpusRequest, i: usize) -> Plan {
    let damaged = args.damaged_every > 0 && (i + 1).is_multiple_of(args.damaged_every);
    Plan {
        name_index: i + 1,
        seed: args.first_seed + i as u64,
        duration_s: DURATIONS[i % DURATIONS.len()],
        // One drive in five is careless: a log the verifier rejects.
        driver: if i % 5 == 3 { Driver::Careless } else { Driver::Careful },
        region: i % REGIONS.len(),
        damage: damaged.then(|| DAMAGES[(i / args.damaged_every) % DAMAGES.len()]),
        profile: args.profile,
    }
}

/// One log's entry in `corpus.json`: what the log is and what was done to it.
#[derive(Debug, Serialize)]
struct Entry {
    log: String,
    seed: u64,
    duration_s: f64,
    driver: &'static str,
    region: &'static str,
    origin: [f64; 3],
    damage: Option<&'static str>,
    profile: &'static str,
}

/// `corpus.json`.
#[derive(Debug, Serialize)]
struct Listing {
    logs: Vec<Entry>,
}

/// Generate, record and (maybe) damage one log; its entry in `corpus.json`.
fn make(plan: &Plan, out: &Path) -> Result<Entry> {
    let name = format!("drive-{:04}", plan.name_index);
    let (region, origin) = REGIONS[plan.region];
    let config = ScenarioConfig {
        duration_s: plan.duration_s,
        driver: plan.driver,
        origin,
        ..ScenarioConfig::drive(plan.seed, plan.profile, Receiver::Good)
    };
    let geodetic = Geodetic::new(origin[0], origin[1], origin[2]).map_err(Error::other)?;
    let scenario = generate(&config);
    let work = out.join(".work").join(&name);
    write_scenario(&scenario, &work).map_err(|e| Error::file(&work, e))?;
    let tile = road_tile(&work, geodetic)?;
    let mut sources = Sources::scenario(&work);
    if plan.damage == Some(Damage::NoGnss) {
        sources.nmea = None;
    }
    let (stream, _) = record::read_sources(&sources)?;
    let mut device_id = [0u8; 16];
    device_id[..name.len().min(16)].copy_from_slice(&name.as_bytes()[..name.len().min(16)]);
    let recording = record::run_stream(&stream, &Setup::work_zone(geodetic, Some(tile.clone()), device_id))?;
    std::fs::remove_dir_all(&work).map_err(|e| Error::file(&work, e))?;
    let log = damaged(recording.log, plan);
    let write = |path: PathBuf, bytes: &[u8]| std::fs::write(&path, bytes).map_err(|e| Error::file(&path, e));
    write(out.join(format!("{name}.d2slog")), &log)?;
    if plan.damage != Some(Damage::NoMap) {
        write(out.join(format!("{name}.map")), &tile)?;
    }
    Ok(Entry {
        log: format!("{name}.d2slog"),
        seed: plan.seed,
        duration_s: plan.duration_s,
        driver: plan.driver.name(),
        region,
        origin,
        damage: plan.damage.map(Damage::name),
        profile: plan.profile.name(),
    })
}

/// The log's bytes damaged as the plan says.
fn damaged(mut log: Vec<u8>, plan: &Plan) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(plan.seed);
    match plan.damage {
        Some(Damage::Garbage) => (0..log.len()).map(|_| rng.random()).collect(),
        Some(Damage::HeaderCut) => {
            log.truncate(20);
            log
        }
        Some(Damage::TailCut) => {
            // Not on a record boundary: the last record is cut in the middle.
            log.truncate(log.len() * 3 / 5 + 7);
            log
        }
        Some(Damage::BitFlips) => {
            // Past the header: the log stays a log, with damaged stretches.
            for _ in 0..log.len() / 300 {
                let at = rng.random_range(64..log.len().max(65));
                if let Some(byte) = log.get_mut(at) {
                    *byte ^= 1 << rng.random_range(0..8);
                }
            }
            log
        }
        Some(Damage::NoGnss | Damage::NoMap) | None => log,
    }
}

/// Generate the corpus `args` asks for; `progress` is told how many logs are written so far
/// (from the worker threads, in any order).
pub fn make_corpus(args: &CorpusRequest, progress: &(dyn Fn(usize) + Sync)) -> Result<Corpus> {
    std::fs::create_dir_all(&args.output).map_err(|e| Error::file(&args.output, e))?;
    let plans: Vec<Plan> = (0..args.logs).map(|i| plan(args, i)).collect();
    let workers = std::thread::available_parallelism().map_or(1, usize::from);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let results: Vec<Result<Entry>> = std::thread::scope(|scope| {
        let chunks: Vec<_> = plans
            .chunks(plans.len().div_ceil(workers).max(1))
            .map(|chunk| {
                let (out, done) = (&args.output, &done);
                scope.spawn(move || {
                    chunk
                        .iter()
                        .map(|p| {
                            let entry = make(p, out);
                            let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                            progress(n);
                            entry
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        chunks
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_else(|_| vec![Err(Error::invalid("a worker panicked"))]))
            .collect()
    });
    let _ = std::fs::remove_dir(args.output.join(".work"));
    let logs = results.into_iter().collect::<Result<Vec<Entry>>>()?;
    let damaged = logs.iter().filter(|e| e.damage.is_some()).count();
    let path = args.output.join("corpus.json");
    // Through a `Value`: its keys sorted, as the corpus job's tests and readers have them.
    let listing = serde_json::to_value(Listing { logs }).map_err(Error::other)?;
    let text = serde_json::to_string_pretty(&listing).map_err(Error::other)?;
    std::fs::write(&path, text).map_err(|e| Error::file(&path, e))?;
    Ok(Corpus { logs: args.logs, damaged, listing: path })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_cycles_through_lengths_regions_drivers_and_damage() {
        let args = CorpusRequest {
            output: PathBuf::new(),
            logs: 60,
            damaged_every: 10,
            first_seed: 5,
            profile: Profile::Typical,
        };
        let plans: Vec<Plan> = (0..60).map(|i| plan(&args, i)).collect();
        assert_eq!(plans[0].seed, 5);
        let damages: Vec<Damage> = plans.iter().filter_map(|p| p.damage).collect();
        assert_eq!(damages, DAMAGES.to_vec(), "one of each kind in 60 logs");
        assert_eq!(plans.iter().filter(|p| p.driver == Driver::Careless).count(), 12);
        for region in 0..REGIONS.len() {
            assert_eq!(plans.iter().filter(|p| p.region == region).count(), 20);
        }
        assert!(DURATIONS.iter().all(|d| plans.iter().any(|p| p.duration_s == *d)));
    }

    #[test]
    fn damage_keeps_or_breaks_the_log_as_its_kind_says() {
        let log: Vec<u8> = (0..3000u32).map(|i| (i % 251) as u8).collect();
        let with = |damage| damaged(log.clone(), &Plan { damage: Some(damage), ..plan_zero() });
        assert_eq!(with(Damage::HeaderCut).len(), 20);
        assert_eq!(with(Damage::TailCut).len(), 1807);
        let flipped = with(Damage::BitFlips);
        assert_eq!(flipped[..64], log[..64], "the header is left alone");
        assert!(flipped != log);
        assert_ne!(with(Damage::Garbage)[..8], log[..8]);
        assert_eq!(with(Damage::NoMap), log);
    }

    fn plan_zero() -> Plan {
        Plan {
            name_index: 1,
            seed: 1,
            duration_s: 20.0,
            driver: Driver::Careful,
            region: 0,
            damage: None,
            profile: Profile::Ideal,
        }
    }
}
