//! A serial byte stream is untrusted: any bytes, cut into any chunks, go through the
//! framer, the sentence check, the message parsers and the epoch assembler without a
//! panic, and every fix they produce is plausible.
#![no_main]

use dash2sim_core::nmea::{Event, Stream, StreamEvent};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&chunk, bytes)) = data.split_first() else { return };
    let chunk = usize::from(chunk % 16) + 1;
    let mut stream: Stream<96> = Stream::new();
    let check = |fix: &dash2sim_core::nmea::GnssFix| {
        if let Some(lat) = fix.lat {
            assert!((-90.0..=90.0).contains(&lat), "{fix:?}");
        }
        if let Some(lon) = fix.lon {
            assert!((-180.0..=180.0).contains(&lon), "{fix:?}");
        }
        assert!(fix.speed_mps.is_none_or(f64::is_finite));
    };
    for piece in bytes.chunks(chunk) {
        stream.feed(piece, |event| {
            if let StreamEvent::Sentence(Event::Message { fix: Some(fix), .. }) = event {
                check(fix);
            }
        });
    }
    if let Some(fix) = stream.decoder.finish() {
        check(&fix);
    }
    assert!(stream.framer.stats().sentences >= stream.decoder.stats().decoded);
});
