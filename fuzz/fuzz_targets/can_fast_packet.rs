//! Arbitrary frames (id, timestamp step, up to 8 bytes each) through the CAN decoder:
//! fast-packet reassembly with few slots, every PGN/OBD decoder, timeouts.
#![no_main]

use dash2sim_core::can::frame::id_from_raw;
use dash2sim_core::can::{CanFrame, Decoder, Event};
use dash2sim_core::time::Timestamp;
use embedded_can::Frame;
use libfuzzer_sys::fuzz_target;

/// Ids that reach every decoder: 129025/6/9 from two sources, CCVS1, VP1, OBD.
const IDS: [(u32, bool); 8] = [
    (0x09F8_0102, true),
    (0x09F8_0202, true),
    (0x0DF8_0502, true),
    (0x0DF8_0503, true),
    (0x0CFE_F100, true),
    (0x18FE_F31C, true),
    (0x7E8, false),
    (0x18DA_F110, true),
];

fuzz_target!(|data: &[u8]| {
    let mut decoder = Decoder::<2>::default();
    let mut now = 0i64;
    // Each record: selector, time step, length, then that many bytes (capped at 8).
    let mut rest = data;
    while let [selector, step, len, tail @ ..] = rest {
        let len = usize::from(*len % 9).min(tail.len());
        let (payload, next) = tail.split_at(len);
        rest = next;
        now += i64::from(*step) * 10_000;
        let (raw, extended) = IDS[usize::from(*selector) % IDS.len()];
        let raw = if selector & 0x80 != 0 { raw ^ u32::from(*step) } else { raw };
        let Some(id) = id_from_raw(raw & if extended { 0x1FFF_FFFF } else { 0x7FF }, extended) else { continue };
        let Some(frame) = CanFrame::data_frame(id, payload) else { continue };
        decoder.decode(Timestamp::from_micros(now), &frame, |event| {
            if let Event::Decoded(d) = event {
                assert_eq!(d.header.is_some(), frame.is_extended());
            }
        });
    }
    assert!(decoder.stats().frames >= decoder.stats().decoded);
});
