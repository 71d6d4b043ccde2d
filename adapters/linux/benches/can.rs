//! CAN throughput on the gpsd NMEA 2000 capture (10 495 real frames, candump `-l`):
//! text → frames → id split → fast-packet reassembly → 129025/129026/129029, with and
//! without building the JSON objects `dash2sim can decode` prints; and DBC decoding of
//! comma2k19's 135 468 Toyota frames. canboat's JavaScript analyzer (canboatjs) is timed
//! on the same file by `scripts/bench_canboatjs.js`. Figures in docs/benchmarks.md.

mod common;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dash2sim_can::candump::CandumpReader;
use dash2sim_can::{FrameSource, SignalTable};
use dash2sim_core::can::{Decoder, Event};
use dash2sim_linux::ingest::can::{decode_source, CanDecoder};

fn data(path: &str) -> Option<Vec<u8>> {
    let path = common::data(path)?;
    std::fs::read(&path).map_err(|e| eprintln!("SKIPPED: {}: {e}", path.display())).ok()
}

/// Frames parsed and messages decoded into core structs.
fn decode_core(bytes: &[u8]) -> (u32, u32) {
    let mut reader = CandumpReader::new(bytes);
    let mut decoder = Decoder::<16>::default();
    let mut messages = 0;
    while let Some(Ok(record)) = reader.next_frame() {
        decoder.decode(record.time.unwrap_or_default(), &record.frame, |e| {
            if let Event::Decoded(_) = e {
                messages += 1;
            }
        });
    }
    (decoder.stats().frames, messages)
}

/// The CLI's path: messages as JSON values (not printed).
fn decode_json(bytes: &[u8], table: &SignalTable) -> usize {
    let mut reader = CandumpReader::new(bytes);
    let mut decoder = CanDecoder::new(table.clone());
    let mut messages = 0;
    decode_source(
        &mut reader,
        &mut decoder,
        |v| {
            std::hint::black_box(v);
            messages += 1;
            Ok(())
        },
        |_, _| {},
    )
    .ok();
    messages
}

/// DBC signals as numbers (what an on-line consumer needs): lookup + bit extraction.
fn decode_signals(bytes: &[u8], table: &SignalTable) -> f64 {
    let mut reader = CandumpReader::new(bytes);
    let mut sum = 0.0;
    while let Some(Ok(record)) = reader.next_frame() {
        if let Some(message) = table.message(embedded_can::Frame::id(&record.frame)) {
            message.decode(embedded_can::Frame::data(&record.frame), |_, v| sum += v);
        }
    }
    sum
}

fn can_benches(c: &mut Criterion) {
    if let Some(n2k) = data("gpsd/nmea2000/logfile_20140914_365495765_can.log") {
        let (frames, messages) = decode_core(&n2k);
        assert_eq!((frames, messages), (10_495, 3_056));
        let mut group = c.benchmark_group("can/n2k_gpsd_log");
        group.throughput(Throughput::Elements(u64::from(frames)));
        group.bench_function("candump_parse", |b| {
            b.iter(|| {
                let mut reader = CandumpReader::new(&n2k[..]);
                let mut n = 0;
                while let Some(Ok(_)) = reader.next_frame() {
                    n += 1;
                }
                n
            })
        });
        group.bench_function("decode", |b| b.iter(|| decode_core(&n2k)));
        let empty = SignalTable::default();
        group.bench_function("decode_json", |b| b.iter(|| decode_json(&n2k, &empty)));
        group.finish();
    }
    if let (Some(log), Some(dbc)) =
        (data("comma2k19/raw_can.candump.log"), data("comma2k19/opendbc-toyota/_toyota_2017.dbc"))
    {
        let (table, _) = SignalTable::parse(&String::from_utf8_lossy(&dbc)).expect("Toyota DBC");
        let mut group = c.benchmark_group("can/toyota_dbc");
        group.throughput(Throughput::Elements(135_468));
        group.sample_size(20);
        group.bench_function("decode_signals", |b| b.iter(|| decode_signals(&log, &table)));
        group.bench_function("decode_json", |b| b.iter(|| decode_json(&log, &table)));
        group.finish();
    }
}

criterion_group!(benches, can_benches);
criterion_main!(benches);
