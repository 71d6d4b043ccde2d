//! One line of arbitrary bytes through the sentence check and every message parser.
#![no_main]

use dash2sim_core::nmea::{messages, EpochAssembler, Sentence};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    for require_checksum in [false, true] {
        if let Ok(sentence) = Sentence::parse(data, require_checksum) {
            if let Ok(message) = messages::parse(&sentence) {
                let mut assembler = EpochAssembler::new();
                let _ = assembler.push(&message);
                let _ = assembler.push(&message);
                let _ = assembler.finish();
            }
        }
    }
});
