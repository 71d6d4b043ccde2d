//! Signature trailers from arbitrary bytes: a segment of fuzzed frames closed by a fuzzed
//! trailer, read by the decoder and judged by a `SealCheck`. Never a panic, every segment
//! judged at most once, and never a trusted verdict — the fuzzer cannot sign for the key
//! (a forged trailer that verified would be a broken signature scheme). Also the trailer's
//! own decoding round-trips.
#![no_main]

use dash2sim_core::binlog::signature::{SealCheck, Sealer, Trailer, SIGNATURE, TRAILER_LEN};
use dash2sim_core::binlog::{Decoder, Event, Header, CRC32C, INDEX, SEGMENT, SYNC};
use libfuzzer_sys::fuzz_target;

fn frame(out: &mut Vec<u8>, code: u8, payload: &[u8]) {
    let start = out.len();
    let len = payload.len().min(127);
    out.push(len as u8);
    out.push(code);
    out.extend_from_slice(&payload[..len]);
    let crc = CRC32C.checksum(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

fn trailer_frame(out: &mut Vec<u8>, payload: &[u8]) {
    let start = out.len();
    out.push(payload.len() as u8);
    out.push(SIGNATURE);
    out.extend_from_slice(payload);
    let crc = CRC32C.checksum(&out[start..]);
    out.extend_from_slice(&crc.to_le_bytes());
}

fuzz_target!(|data: &[u8]| {
    if let Some(t) = Trailer::decode(data) {
        assert_eq!(Trailer::decode(&t.encode()), Some(t));
    }
    let public = Sealer::new(&[7; 32]).public_key();
    let Ok(mut check) = SealCheck::new(&public) else { return };
    // header · (SYNC · segment · frame · index · trailer) per 89-byte trailer in the input.
    let mut log = Header { device_id: [0; 16], origin: [0; 3] }.encode().to_vec();
    for (seq, chunk) in data.chunks(TRAILER_LEN + 8).enumerate() {
        let (head, trailer) = chunk.split_at(chunk.len().min(8));
        log.extend_from_slice(&SYNC);
        frame(&mut log, SEGMENT, &[seq as u8 & 0x7f, 0]);
        // A record kind (never a structural frame, which would start a segment of its own).
        frame(&mut log, head.first().copied().filter(|c| *c >= 0x10).unwrap_or(0x13), head);
        frame(&mut log, INDEX, &[seq as u8 & 0x7f, 1, 0, 8]);
        // The key id of the check's key, so that the signature itself is what is judged.
        let mut payload = trailer.to_vec();
        if payload.len() >= 9 {
            payload[1..9].copy_from_slice(&dash2sim_core::binlog::signature::key_id(&public));
        }
        trailer_frame(&mut log, &payload);
    }
    let mut decoder: Box<Decoder> = Box::default();
    let mut judged = Vec::new();
    let mut on = |e: Event| judged.extend(check.on_event(&e));
    for c in log.chunks(usize::from(data.first().copied().unwrap_or(1)).max(1)) {
        decoder.push(c, &mut on);
    }
    decoder.finish(&mut on);
    judged.extend(check.end_of_file());
    let mut seqs: Vec<u64> = judged.iter().map(|(s, _)| *s).collect();
    seqs.dedup();
    assert_eq!(seqs.len(), judged.len(), "a segment judged twice: {judged:?}");
    assert!(judged.iter().all(|(_, seal)| !seal.is_trusted()), "a forged trailer verified: {judged:?}");
});
