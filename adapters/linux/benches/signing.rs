//! Cost of signed segments on the host: one 5 s segment of the MCU example's drive (the
//! device's own log, ~6.5 KB a segment) written with and without the device key, and checked
//! against the public key (decode, digest, Ed25519 verification). The Cortex-M7's cost is
//! measured in instructions by `examples/mcu` (docs/benchmarks.md).

use criterion::{criterion_group, criterion_main, Criterion};
use dash2sim_core::binlog::signature::{SealCheck, Sealer};
use dash2sim_core::binlog::{Decoder, Event, Header, Record, Writer, WriterConfig};
use dash2sim_linux::log;

const SEED: [u8; 32] = *b"dash2sim MCU example: demo key!!";

/// The first segment's records of the MCU drive's log, written by the host pipeline.
fn segment_records() -> (Header, Vec<Record>) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/mcu");
    let setup = dash2sim_linux::record::Setup::work_zone(
        dash2sim_core::geo::Geodetic::new(60.2711, 24.8572, 0.0).expect("origin"),
        std::fs::read(dir.join("drive.d2smap")).ok(),
        [0; 16],
    );
    let stream = std::fs::read(dir.join("drive.d2sin")).expect("drive.d2sin");
    let recording = dash2sim_linux::record::run_stream(&stream, &setup).expect("record");
    let contents = log::decode(&recording.log, "drive").expect("log");
    let t0 = contents.records.first().map_or(0, Record::t_us);
    let records = contents.records.into_iter().filter(|r| r.t_us() < t0 + 4_900_000).collect();
    (contents.header.expect("header"), records)
}

fn write(header: &Header, records: &[Record], sealer: Option<Sealer>) -> Vec<u8> {
    let mut w: Writer<Vec<u8>, 4096> = Writer::new(Vec::new(), header, WriterConfig::default()).expect("header");
    if let Some(s) = sealer {
        w.seal_with(s);
    }
    for r in records {
        w.write(r).expect("write");
    }
    w.finish().expect("finish")
}

fn signing(c: &mut Criterion) {
    let (header, records) = segment_records();
    let signed = write(&header, &records, Some(Sealer::new(&SEED)));
    println!("one segment: {} records, {} bytes signed", records.len(), signed.len());
    let public = Sealer::new(&SEED).public_key();
    c.bench_function("write_segment_unsigned", |b| b.iter(|| write(&header, &records, None)));
    c.bench_function("write_segment_signed", |b| b.iter(|| write(&header, &records, Some(Sealer::new(&SEED)))));
    c.bench_function("verify_segment", |b| {
        b.iter(|| {
            let mut check = SealCheck::new(&public).expect("key");
            let mut decoder: Box<Decoder> = Box::default();
            let mut ok = 0;
            let mut on = |e: Event| ok += usize::from(check.on_event(&e).is_some_and(|(_, s)| s.is_trusted()));
            decoder.push(&signed, &mut on);
            decoder.finish(&mut on);
            assert_eq!(ok, 1);
        })
    });
}

/// The same segment's signature checked by `ed25519-dalek` (its default, precomputed
/// tables), the peer: what the Ed25519 arithmetic costs in each, apart from hashing the
/// segment.
fn peer(c: &mut Criterion) {
    use ed25519_dalek::Verifier as _;
    let (header, records) = segment_records();
    let signed = write(&header, &records, Some(Sealer::new(&SEED)));
    let mut decoder: Box<Decoder> = Box::default();
    let mut found = None;
    let mut on = |e: Event| {
        if let Event::Signature { trailer, digest: Some(d) } = e {
            found = Some((trailer, d));
        }
    };
    decoder.push(&signed, &mut on);
    decoder.finish(&mut on);
    let (trailer, digest) = found.expect("a signed segment");
    let message = [&b"dash2sim segment v1"[..], &trailer.key_id, &trailer.link, &digest].concat();
    let key = ed25519_dalek::SigningKey::from_bytes(&SEED);
    let signature = ed25519_dalek::Signature::from_bytes(&trailer.signature);
    key.verifying_key().verify(&message, &signature).expect("dalek verifies salty's signature");
    c.bench_function("dalek_sign_message", |b| b.iter(|| ed25519_dalek::Signer::sign(&key, &message)));
    c.bench_function("dalek_verify_message", |b| b.iter(|| key.verifying_key().verify(&message, &signature)));
}

criterion_group!(benches, signing, peer);
criterion_main!(benches);
