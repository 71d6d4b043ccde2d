//! A serial byte stream is untrusted: any bytes, cut into any chunks, go through the
//! framer, the sentence check, the message parsers and the epoch assembler without a
//! panic, and every fix they produce is plausible.
#![no_main]

use dash2sim_core::nmea::{Decoder, Event, Feed, Framer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, bytes)) = data.split_first() else { return };
    let chunk = usize::from(chunk % 16) + 1;
    let mut framer: Framer<96> = Framer::new();
    let mut decoder = Decoder::new();
    let check = |fix: dash2sim_core::nmea::GnssFix| {
        if let Some(lat) = fix.lat {
            assert!((-90.0..=90.0).contains(&lat), "{fix:?}");
        }
        if let Some(lon) = fix.lon {
            assert!((-180.0..=180.0).contains(&lon), "{fix:?}");
        }
        assert!(fix.speed_mps.is_none_or(f64::is_finite));
    };
    for piece in bytes.chunks(chunk) {
        let mut input = piece;
        loop {
            match framer.feed(input) {
                Feed::Consumed => break,
                Feed::Sentence { line, remaining } => {
                    assert!(line.len() <= 96);
                    if let Event::Message { fix: Some(fix), .. } = decoder.line(line) {
                        check(fix);
                    }
                    input = remaining;
                }
                Feed::Dropped { remaining, .. } => input = remaining,
            }
        }
    }
    if let Some(fix) = decoder.finish() {
        check(fix);
    }
});
