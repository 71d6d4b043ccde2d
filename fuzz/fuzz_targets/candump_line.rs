//! Arbitrary text through the candump line parser and the reader; whatever parses must
//! survive a round trip through the `-l` writer.
#![no_main]

use dash2sim_can::candump::{parse_line, write_log_line, CandumpReader, Line};
use dash2sim_can::FrameSource;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    for line in text.lines() {
        if let Ok(Line::Frame { time, interface, frame }) = parse_line(line) {
            let Some(time) = time else { continue };
            let interface = interface.unwrap_or("can0");
            if interface.contains(['(', ')', '#']) {
                continue;
            }
            let mut out = Vec::new();
            write_log_line(&mut out, time, interface, &frame).expect("vec");
            let again = String::from_utf8(out).expect("ascii");
            match parse_line(&again) {
                Ok(Line::Frame { time: t2, frame: f2, .. }) => assert_eq!((Some(time), frame), (t2, f2), "{line:?}"),
                other => panic!("{line:?} → {again:?} → {other:?}"),
            }
        }
    }
    let mut reader = CandumpReader::new(data);
    while reader.next_frame().is_some() {}
});
