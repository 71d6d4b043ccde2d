//! 4D log throughput: encoding (framing, prediction, CRC-32C) and push decoding of a
//! generated 40 s work-zone drive (ego poses 10 Hz, GNSS 5 Hz, 3D tracks ~40 per frame)
//! imported through `dash2sim import`. Criterion reports records/s; bytes/s follow from
//! the log size printed. Figures in docs/benchmarks.md.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dash2sim_core::binlog::{Decoder, Event};
use dash2sim_linux::log;
use dash2sim_sim::scenario::write::{import_request, write_scenario};
use dash2sim_sim::scenario::{generate, ScenarioConfig};

fn throughput(c: &mut Criterion) {
    let dir = std::env::temp_dir().join(format!("d2s-bench-binlog-{}", std::process::id()));
    let scenario = generate(&ScenarioConfig { duration_s: 40.0, ..ScenarioConfig::default() });
    write_scenario(&scenario, &dir.join("drive")).expect("scenario");
    let output = dir.join("drive.d2slog");
    log::import::import(&import_request(&scenario, &dir.join("drive"), output.clone()).expect("request"), &mut |_| {})
        .expect("import");
    let bytes = std::fs::read(&output).expect("log");
    let log = log::decode(&bytes, "bench").expect("log");
    let header = log.header.expect("header");
    let records = log.records.len() as u64;
    eprintln!("{records} records, {} bytes", bytes.len());

    let mut group = c.benchmark_group("binlog");
    group.throughput(Throughput::Elements(records));
    group.bench_function("encode (records)", |b| {
        b.iter(|| {
            let mut copy = log.records.clone();
            log::import::encode(&header, &mut copy).expect("encodes").len()
        })
    });
    group.bench_function("decode (records)", |b| {
        b.iter(|| {
            let mut decoder: Box<Decoder> = Box::default();
            let mut n = 0u64;
            let mut on = |e: Event| n += u64::from(matches!(e, Event::Record(_)));
            for chunk in bytes.chunks(4096) {
                decoder.push(chunk, &mut on);
            }
            decoder.finish(&mut on);
            n
        })
    });
    group.finish();
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, throughput);
criterion_main!(benches);
