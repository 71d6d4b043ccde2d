//! Signed segments: written by the writer, judged from the decoder's events; the signatures
//! and digests cross-checked with independent implementations (`ed25519-dalek`, `sha2`).

extern crate std;
use std::vec::Vec;

use super::*;
use crate::binlog::{Decoder, EgoPose, Event, Header, Record, Writer, WriterConfig, SYNC};

const HEADER: Header = Header { device_id: *b"dashcam-0001\0\0\0\0", origin: [602_711_000, 248_572_000, 12_000] };
const SEED: [u8; 32] = [7; 32];

/// 6 s of 20 Hz ego poses in 1 s segments: six segments.
fn poses() -> impl Iterator<Item = Record> {
    (0..120i64).map(|k| {
        Record::EgoPose(EgoPose {
            t_us: 1_700_000_000_000_000 + k * 50_000,
            x_mm: 1000 * k,
            y_mm: -500 * k,
            z_mm: 12,
            yaw_e4: 100 + k,
            sigma_mm: 0,
        })
    })
}

fn config() -> WriterConfig {
    WriterConfig { segment_us: 1_000_000, ..WriterConfig::default() }
}

/// A log of `records`, signed by `sealer` if given; the sealer back (its chain goes on).
fn log(records: impl Iterator<Item = Record>, sealer: Option<Sealer>) -> (Vec<u8>, Option<Sealer>) {
    let mut out = [0u8; 16_384];
    let mut rest: &mut [u8] = &mut out;
    let mut w: Writer<&mut &mut [u8], 4096> = Writer::new(&mut rest, &HEADER, config()).expect("header");
    if let Some(s) = sealer {
        w.seal_with(s);
    }
    for r in records {
        w.write(&r).expect("write");
    }
    w.close().expect("close");
    let sealer = w.take_sealer();
    w.finish().expect("finish");
    let n = 16_384 - rest.len();
    (out[..n].to_vec(), sealer)
}

/// The decoder's events of `bytes`.
fn events(bytes: &[u8]) -> Vec<Event> {
    let mut d: Decoder = Decoder::new();
    let mut out = Vec::new();
    let mut on = |e: Event| out.push(e);
    for c in bytes.chunks(97) {
        d.push(c, &mut on);
    }
    d.finish(&mut on);
    out
}

/// Each segment's verdict, files checked in order with one check.
fn seals(public: &[u8; 32], files: &[&[u8]]) -> Vec<Seal> {
    let mut check = SealCheck::new(public).expect("key");
    let mut out = Vec::new();
    for f in files {
        out.extend(events(f).iter().filter_map(|e| check.on_event(e)).map(|(_, s)| s));
        out.extend(check.end_of_file().map(|(_, s)| s));
    }
    out
}

/// Where each segment starts (its sync marker) and where the file ends.
fn segment_starts(bytes: &[u8]) -> Vec<usize> {
    let mut at: Vec<usize> = bytes.windows(4).enumerate().filter(|(_, w)| *w == SYNC).map(|(k, _)| k).collect();
    at.push(bytes.len());
    at
}

fn public() -> [u8; 32] {
    Sealer::new(&SEED).public_key()
}

#[test]
fn every_segment_of_a_signed_log_verifies_and_the_chain_holds() {
    let (bytes, _) = log(poses(), Some(Sealer::new(&SEED)));
    let got = seals(&public(), &[&bytes]);
    assert_eq!(got.len(), 6);
    assert_eq!(got[0], Seal::ChainStart);
    assert!(got[1..].iter().all(|s| *s == Seal::Valid), "{got:?}");
    // The records are the unsigned log's: a trailer is only added.
    let records = |b: &[u8]| events(b).into_iter().filter(|e| matches!(e, Event::Record(_))).collect::<Vec<_>>();
    let (unsigned, _) = log(poses(), None);
    assert_eq!(records(&bytes), records(&unsigned));
    assert_eq!(bytes.len() - unsigned.len(), 6 * (2 + TRAILER_LEN + 4));
}

#[test]
fn the_signatures_and_digests_are_plain_ed25519_and_sha512() {
    use ed25519_dalek::Verifier as _;
    use sha2::Digest as _;
    let (bytes, _) = log(poses(), Some(Sealer::new(&SEED)));
    let dalek = ed25519_dalek::SigningKey::from_bytes(&SEED);
    assert_eq!(dalek.verifying_key().to_bytes(), public());
    let starts = segment_starts(&bytes);
    let mut checked = 0;
    for e in events(&bytes) {
        let Event::Signature { trailer, digest: Some(digest) } = e else { continue };
        // The digest is SHA-512 of the segment up to its index (the header with the first).
        let from = if checked == 0 { 0 } else { starts[checked] };
        let trailer_frame = 2 + TRAILER_LEN + 4;
        let to = starts[checked + 1] - trailer_frame;
        assert_eq!(digest.as_slice(), sha2::Sha512::digest(&bytes[from..to]).as_slice());
        let mut message = Vec::from(&b"dash2sim segment v1"[..]);
        message.extend_from_slice(&trailer.key_id);
        message.extend_from_slice(&trailer.link);
        message.extend_from_slice(&digest);
        let signature = ed25519_dalek::Signature::from_bytes(&trailer.signature);
        dalek.verifying_key().verify(&message, &signature).expect("ed25519-dalek verifies it");
        checked += 1;
    }
    assert_eq!(checked, 6);
}

#[test]
fn a_flipped_byte_fails_its_segment_only() {
    let (bytes, _) = log(poses(), Some(Sealer::new(&SEED)));
    let starts = segment_starts(&bytes);
    // Every byte of the third segment's signed part, and of the header (the first's).
    for at in (0..48).chain(starts[2]..starts[3] - (2 + TRAILER_LEN + 4)) {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0x10;
        let got = seals(&public(), &[&damaged]);
        let bad = if at < 48 { 0 } else { 2 };
        for (k, s) in got.iter().enumerate() {
            if k == bad {
                assert_eq!(*s, Seal::BadSignature, "byte {at}");
            } else {
                assert!(s.is_trusted(), "byte {at}: segment {k} {s:?}");
            }
        }
    }
}

#[test]
fn a_removed_or_moved_segment_breaks_the_chain_after_it() {
    let (bytes, _) = log(poses(), Some(Sealer::new(&SEED)));
    let s = segment_starts(&bytes);
    let mut removed = bytes[..s[2]].to_vec();
    removed.extend_from_slice(&bytes[s[3]..]);
    let got = seals(&public(), &[&removed]);
    assert_eq!(got, [Seal::ChainStart, Seal::Valid, Seal::ChainBroken, Seal::Valid, Seal::Valid]);

    let mut swapped = bytes[..s[2]].to_vec();
    swapped.extend_from_slice(&bytes[s[3]..s[4]]);
    swapped.extend_from_slice(&bytes[s[2]..s[3]]);
    swapped.extend_from_slice(&bytes[s[4]..]);
    let got = seals(&public(), &[&swapped]);
    assert_eq!(got[..2], [Seal::ChainStart, Seal::Valid]);
    assert_eq!(got[2..4], [Seal::ChainBroken, Seal::ChainBroken]);
    assert_eq!(got[4], Seal::ChainBroken, "the segment after the swap follows neither");
}

#[test]
fn another_key_is_named_and_an_unsigned_log_is_unsigned() {
    let (bytes, _) = log(poses(), Some(Sealer::new(&[9; 32])));
    let got = seals(&public(), &[&bytes]);
    let other = key_id(&Sealer::new(&[9; 32]).public_key());
    assert!(got.iter().all(|s| *s == Seal::OtherKey(other)), "{got:?}");
    let (unsigned, _) = log(poses(), None);
    assert_eq!(seals(&public(), &[&unsigned]), [Seal::Unsigned; 6]);
    let not_a_point = (0..=255u8).map(|b| [b; 32]).filter(|k| SealCheck::new(k).is_err()).count();
    assert!(not_a_point > 0, "some 32-byte strings are not curve points and are refused");
}

#[test]
fn the_chain_runs_across_files_and_a_missing_middle_file_shows() {
    let (a, sealer) = log(poses(), Some(Sealer::new(&SEED)));
    let (b, sealer) = log(poses(), sealer);
    let (c, _) = log(poses(), sealer);
    let got = seals(&public(), &[&a, &b, &c]);
    assert_eq!(got.len(), 18);
    assert_eq!(got[0], Seal::ChainStart);
    assert!(got[1..].iter().all(|s| *s == Seal::Valid), "{got:?}");
    // A folder whose oldest files loop recording deleted starts where it can.
    assert_eq!(seals(&public(), &[&b, &c])[0], Seal::Continues);
    // The middle file removed: the third's first segment does not follow the first's last.
    let got = seals(&public(), &[&a, &c]);
    assert_eq!(got[6], Seal::ChainBroken);
    assert!(got[7..].iter().all(|s| *s == Seal::Valid));
}

#[test]
fn a_log_cut_anywhere_keeps_every_complete_segment_trusted() {
    let (bytes, _) = log(poses(), Some(Sealer::new(&SEED)));
    let ends: Vec<usize> = segment_starts(&bytes)[1..].to_vec();
    for cut in 0..=bytes.len() {
        let got = seals(&public(), &[&bytes[..cut]]);
        let complete = ends.iter().filter(|e| **e <= cut).count();
        assert!(got[..complete].iter().all(|s| s.is_trusted()), "cut {cut}: {got:?}");
        // What follows is the torn segment, reported unsigned (never as tampered).
        assert!(got[complete..].iter().all(|s| *s == Seal::Unsigned), "cut {cut}: {got:?}");
        assert!(got.len() <= complete + 1);
    }
}

#[test]
fn a_trailer_round_trips_and_foreign_bytes_are_not_one() {
    let t = Trailer { key_id: [1; 8], link: [2; 16], signature: [3; 64] };
    assert_eq!(Trailer::decode(&t.encode()), Some(t));
    let mut other_format = t.encode();
    other_format[0] = 2;
    assert_eq!(Trailer::decode(&other_format), None);
    assert_eq!(Trailer::decode(&t.encode()[..TRAILER_LEN - 1]), None);
    assert_eq!(Trailer::decode(&[]), None);
}
