//! Arbitrary bytes into the 4D log decoder, in arbitrary chunks: it never panics, counts
//! what it skips, and reports records only from intact frames. Two views of each input:
//! the raw bytes after a valid header (damage, resynchronisation), and the bytes cut into
//! (kind, payload) frames with valid CRCs and a segment start (so that the fuzzer reaches
//! payload decoding — track references, truncated varints — without guessing CRCs).
#![no_main]

use dash2sim_core::binlog::{Decoder, Event, Header, CRC32C, SEGMENT, SYNC};
use libfuzzer_sys::fuzz_target;

fn run(bytes: &[u8], chunk: usize) {
    let mut decoder: Box<Decoder> = Box::default();
    let mut records = 0u64;
    let mut on = |e: Event| {
        if let Event::Record(_) = e {
            records += 1;
        }
    };
    for c in bytes.chunks(chunk.max(1)) {
        decoder.push(c, &mut on);
    }
    decoder.finish(&mut on);
    assert_eq!(decoder.stats().total(), records);
}

fn frame(out: &mut Vec<u8>, code: u8, payload: &[u8]) {
    let start = out.len();
    out.push(payload.len() as u8 & 0x7f);
    out.push(code);
    out.extend_from_slice(&payload[..usize::from(payload.len() as u8 & 0x7f)]);
    let crc = CRC32C.checksum(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, rest)) = data.split_first() else { return };
    let header = Header { device_id: [0; 16], origin: [0; 3] }.encode();
    run(data, usize::from(chunk));
    let mut raw = header.to_vec();
    raw.extend_from_slice(rest);
    run(&raw, usize::from(chunk));
    let mut framed = header.to_vec();
    framed.extend_from_slice(&SYNC);
    frame(&mut framed, SEGMENT, &[0, 0]);
    let mut input = rest;
    while let [code, len, tail @ ..] = input {
        let n = usize::from(*len).min(tail.len());
        frame(&mut framed, *code, &tail[..n]);
        input = &tail[n..];
    }
    run(&framed, usize::from(chunk));
});
