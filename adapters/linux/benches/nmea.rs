//! NMEA 0183 throughput on the concatenated gpsd corpus (80 real captures), against the
//! `nmea` crate on the same bytes. pynmea2 is timed by `scripts/bench_pynmea2.py`.
//! Figures in docs/benchmarks.md. Needs the shared data (skipped with a message without).

mod common;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use dash2sim_core::nmea::{Event, Stream, StreamEvent};

fn corpus() -> Option<Vec<u8>> {
    let dir = common::data("gpsd/daemon")?;
    let Ok(entries) = std::fs::read_dir(&dir) else {
        eprintln!("SKIPPED: {} not found", dir.display());
        return None;
    };
    let mut paths: Vec<_> = entries.filter_map(Result::ok).map(|e| e.path()).collect();
    paths.sort();
    let mut bytes = Vec::new();
    for p in paths.iter().filter(|p| p.extension().is_some_and(|e| e == "log")) {
        bytes.extend(std::fs::read(p).ok()?);
    }
    Some(bytes)
}

/// Ours: framer → checked sentence → message → epoch assembly. Returns fixes.
fn dash2sim_decode(bytes: &[u8]) -> usize {
    let mut stream: Stream = Stream::new();
    let mut fixes = 0;
    stream.feed(bytes, |event| {
        if let StreamEvent::Sentence(Event::Message { fix: Some(_), .. }) = event {
            fixes += 1;
        }
    });
    fixes
}

fn nmea_benches(c: &mut Criterion) {
    let Some(bytes) = corpus() else { return };
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let lines: Vec<&str> = text.lines().map(str::trim_end).filter(|l| l.starts_with('$')).collect();
    eprintln!("corpus: {} bytes, {} sentence lines", bytes.len(), lines.len());
    let mut group = c.benchmark_group("nmea_gpsd_corpus");
    group.throughput(Throughput::Bytes(bytes.len() as u64));
    group.bench_function("dash2sim_framer_decoder_epochs", |b| b.iter(|| dash2sim_decode(&bytes)));
    group.bench_function("nmea_crate_parse_str_per_line", |b| {
        b.iter(|| lines.iter().filter(|l| nmea::parse_str(l).is_ok()).count())
    });
    group.bench_function("nmea_crate_stateful_Nmea_parse", |b| {
        b.iter(|| {
            let mut state = nmea::Nmea::default();
            lines.iter().filter(|l| state.parse(l).is_ok()).count()
        })
    });
    group.finish();
}

criterion_group!(benches, nmea_benches);
criterion_main!(benches);
