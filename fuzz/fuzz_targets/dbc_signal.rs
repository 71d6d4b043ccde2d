//! Arbitrary signal definitions against arbitrary frames: construction validates,
//! extraction never panics and stays within the signal's width.
#![no_main]

use dash2sim_core::can::signal::{decode_message, ByteOrder, Multiplex, Signal};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((frame_len, rest)) = data.split_first() else { return };
    let frame_len = usize::from(*frame_len % 9).min(rest.len());
    let (frame, mut defs) = rest.split_at(frame_len);
    let mut signals = Vec::new();
    while let [start, length, flags, mux, tail @ ..] = defs {
        defs = tail;
        let order = if flags & 1 == 0 { ByteOrder::Intel } else { ByteOrder::Motorola };
        let multiplex = match flags >> 1 & 3 {
            0 => Multiplex::Plain,
            1 => Multiplex::Multiplexor,
            _ => Multiplex::Multiplexed(u64::from(*mux)),
        };
        let factor = if flags & 8 == 0 { 1.0 } else { f64::from(*mux) * 0.01 - 1.0 };
        let Ok(signal) =
            Signal::new(u16::from(*start), u16::from(*length), order, flags & 16 != 0, factor, -40.0, multiplex)
        else {
            continue;
        };
        if let Some(raw) = signal.raw(frame) {
            let bits = u32::from(signal.length);
            let (min, max) = if signal.signed {
                (-(1i128 << (bits - 1)), (1i128 << (bits - 1)) - 1)
            } else {
                (0, (1i128 << bits) - 1)
            };
            assert!((min..=max).contains(&raw), "{signal:?} → {raw}");
        }
        signals.push(signal);
    }
    let mut count = 0;
    let missing = decode_message(&signals, frame, |i, _| {
        assert!(i < signals.len());
        count += 1;
    });
    assert!(count + missing <= signals.len());
});
