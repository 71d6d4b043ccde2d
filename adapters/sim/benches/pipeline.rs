//! The on-device pipeline on the host: a generated 40 s work-zone drive (seed 1, good
//! receiver) as the device sees it — VO 10 Hz, NMEA 5 Hz, CCVS1 50 Hz, 3D and 2D detections
//! 10 Hz — replayed through `Pipeline<64, 32>` with the road's map tile (verification on).
//! Criterion times the whole recording; before it, every input is timed on its own over
//! 20 replays (each input's fastest run, so that other processes' noise drops out) and
//! the median and worst case per input kind are printed. Figures in docs/benchmarks.md.

use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use dash2sim_core::pipeline::profile::{work_zone_meta, work_zone_pipeline, work_zone_trackers};
use dash2sim_core::pipeline::replay::{feed, Input, Reader};
use dash2sim_core::pipeline::{Pipeline, PipelineConfig, Trackers};
use dash2sim_linux::record::{self, Setup, Sources};
use dash2sim_sim::scenario::sensors::GnssModel;
use dash2sim_sim::scenario::write::write_scenario;
use dash2sim_sim::scenario::{generate, ScenarioConfig};

const KINDS: [&str; 6] = ["serial chunk", "CAN frame", "VO pose", "3D detections", "2D detections", "IMU sample"];

fn kind(input: &Input<'_>) -> usize {
    match input {
        Input::Serial(_) => 0,
        Input::Can(_) => 1,
        Input::Vo(..) => 2,
        Input::Detections3d(..) => 3,
        Input::Detections2d(..) => 4,
        Input::Imu(_) => 5,
    }
}

/// Every input's time (ns) in one replay.
fn timed_replay(stream: &[u8], config: PipelineConfig<'_>) -> Vec<(usize, f64)> {
    let mut trackers: Box<Trackers<'_, 64, 32>> = Box::new(work_zone_trackers());
    let mut pipeline: Box<Pipeline<'_, Vec<u8>>> = Box::new(Pipeline::new(Vec::new(), config, &mut trackers));
    let mut reader = Reader::new(stream).expect("stream");
    let mut times = Vec::new();
    while let Some(Ok((t, input))) = reader.next_input() {
        let start = Instant::now();
        feed(&mut pipeline, t, &input).expect("vec");
        times.push((kind(&input), start.elapsed().as_nanos() as f64));
    }
    times
}

fn pipeline(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("d2s-bench-pipeline-{}", std::process::id()));
    let scenario = generate(&ScenarioConfig { duration_s: 40.0, gnss: GnssModel::good(), ..ScenarioConfig::default() });
    write_scenario(&scenario, &dir).expect("scenario");
    let (stream, _) = record::read_sources(&Sources::scenario(&dir)).expect("sources");
    let [lat, lon, h] = scenario.config.origin;
    let origin = Geodetic::new(lat, lon, h).expect("origin");
    let osm = dash2sim_linux::ingest::osm::read(&dir.join("road.osm")).expect("osm");
    let tile = dash2sim_linux::ingest::map_tile::encode(
        &dash2sim_linux::ingest::map_tile::from_osm(&osm, Some(origin), &mut Vec::new()),
        50.0,
    );
    let meta = work_zone_meta();
    let map = MapView::parse(&tile).expect("tile");
    let config = PipelineConfig { map: Some(map), ..work_zone_pipeline(origin, &meta) };

    // Per input: the fastest of 20 replays; then median and worst case per kind.
    let mut best: Vec<(usize, f64)> = timed_replay(&stream, config);
    for _ in 1..20 {
        for (b, (_, t)) in best.iter_mut().zip(timed_replay(&stream, config)) {
            b.1 = b.1.min(t);
        }
    }
    eprintln!("| input | count | median | worst |");
    for (k, name) in KINDS.iter().enumerate() {
        let mut t: Vec<f64> = best.iter().filter(|(kind, _)| *kind == k).map(|(_, t)| *t).collect();
        t.sort_by(f64::total_cmp);
        if let (Some(median), Some(worst)) = (t.get(t.len() / 2), t.last()) {
            eprintln!("| {name} | {} | {:.1} µs | {:.1} µs |", t.len(), median / 1e3, worst / 1e3);
        }
    }
    eprintln!(
        "size_of Pipeline<64, 32, 4096> = {} bytes + Trackers<64, 32> = {} bytes",
        size_of::<Pipeline<'_, Vec<u8>, 64, 32, 4096>>(),
        size_of::<Trackers<'_, 64, 32>>()
    );

    let inputs = best.len() as u64;
    let mut group = c.benchmark_group("pipeline");
    group.throughput(Throughput::Elements(inputs));
    group.bench_function("record 40 s work zone (inputs)", |b| {
        b.iter(|| {
            record::run_stream(&stream, &Setup::work_zone(origin, Some(tile.clone()), [0; 16]))
                .expect("record")
                .log
                .len()
        })
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, pipeline);
criterion_main!(benches);
