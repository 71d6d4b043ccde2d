//! The core decodes without touching the heap: a counting global allocator sees no
//! allocation while a stream of NMEA (good, damaged and unknown sentences) is framed,
//! parsed and assembled. (The crate is `no_std` without `alloc`, so it should not be able
//! to; this proves it for the whole decode path, dependencies included.) The counting
//! allocator comes from `allocation-counter`, which replaces the global allocator of this
//! test crate only.

use dash2sim_core::nmea::{Event, Stream, StreamEvent};

const STREAM: &[u8] = b"junk\r\n$GPGGA,165007.000,4143.6058,N,08338.0778,W,1,06,1.5,204.3,M,-33.7,M,,0000*67\r\n\
$GPGSA,A,3,31,16,29,23,20,32,,,,,,,2.8,1.5,2.4*36\r\n\
$GPGSV,3,1,10,16,74,173,27,23,42,310,21,31,40,066,23,32,39,218,22*7F\r\n\
$GPRMC,165007.000,A,4143.6058,N,08338.0778,W,0.55,36.58,180710,,,A*4F\r\n\
$GPRMC,165007.000,A,4143.6058,N,08338.0778,W,0.55,36.58,180710,,,A*00\r\n\
$GPGGA,165008.000,9543.6059,N,08338.0786,W,1,06,1.5,204.1,M,-33.7,M,,0000\r\n\
$GPTXT,01,01,02,ANTSTATUS=OK*3B\r\n$PGRME,15.0,M,45.0,M,25.0,M*1C\r\n\
$GPGGA,165008.000,4143.6059,N,08338.0786,W,1,06,1.5,204.1,M,-33.7,M,,0000*6A\r\n\x01\x02\xff$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A\r\n";

#[test]
fn decoding_allocates_nothing() {
    let mut stream: Stream = Stream::new();
    let mut fixes = 0;
    let info = allocation_counter::measure(|| {
        for _ in 0..200 {
            for chunk in STREAM.chunks(5) {
                stream.feed(chunk, |event| {
                    if let StreamEvent::Sentence(Event::Message { fix: Some(_), .. }) = event {
                        fixes += 1;
                    }
                });
            }
        }
    });
    assert!(fixes > 300, "{fixes} fixes");
    assert!(
        stream.decoder.stats().bad_checksum > 0
            && stream.decoder.stats().bad_fields > 0
            && stream.decoder.stats().unknown > 0
    );
    assert_eq!(info.count_total, 0, "decoding allocated {} times", info.count_total);
}

/// CAN: id split, fast-packet reassembly (complete, clashing, expired), every decoder
/// and DBC signal extraction, over frames built before measuring.
#[test]
fn can_decoding_allocates_nothing() {
    use dash2sim_core::can::frame::id_from_raw;
    use dash2sim_core::can::signal::{decode_message, ByteOrder, Multiplex, Signal};
    use dash2sim_core::can::{CanFrame, Decoder, Event};
    use dash2sim_core::time::Timestamp;

    let ext = |raw| id_from_raw(raw, true).expect("29-bit");
    let std_id = |raw| id_from_raw(raw, false).expect("11-bit");
    let frames = [
        CanFrame::data_frame(ext(0x09F8_0102), &[0x36, 0x72, 0x9A, 0x16, 0x02, 0x1A, 0xB8, 0x0D]),
        CanFrame::data_frame(ext(0x09F8_0202), &[0xD0, 0xFC, 0, 0, 3, 0, 0xFF, 0xFF]),
        // PGN 129029 in 7 frames, one of them repeated (a clash), and a short one.
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x20, 0x2F, 0xEB, 0xC7, 0x3F, 0x70, 0x4B, 0x43]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x21, 0x24, 0xC0, 0x75, 0x1E, 0x3C, 0xEB, 0x42]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x22, 0x43, 0x05, 0x80, 0xF4, 0x95, 0x73, 0xC0]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x23, 0xB9, 0x31, 0x03, 0x8C, 0x57, 0x93, 0x02]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x24, 0, 0, 0, 0, 0x13, 0xFC, 0x0C]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x25, 0x49, 0, 0x80, 0, 0xAC, 0x0D, 0]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x26, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x40, 0x2F, 1, 2, 3, 4, 5, 6]),
        CanFrame::data_frame(ext(0x0DF8_0502), &[0x40, 0x2F, 1, 2, 3, 4, 5, 6]),
        CanFrame::data_frame(ext(0x09F8_0102), &[1, 2, 3]),
        CanFrame::data_frame(ext(0x0CFE_F100), &[0xFF, 0x00, 0x32, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]),
        CanFrame::data_frame(ext(0x18FE_F31C), &[0x00, 0xEF, 0x9B, 0x9E, 0x80, 0x4A, 0x40, 0x83]),
        CanFrame::data_frame(std_id(0x7E8), &[0x03, 0x41, 0x0D, 0x39, 0, 0, 0, 0]),
        CanFrame::data_frame(std_id(0x123), &[1]),
    ]
    .map(|f| f.expect("classic frame"));
    let signals = [
        Signal::new(0, 8, ByteOrder::Intel, false, 1.0, 0.0, Multiplex::Multiplexor).expect("valid"),
        Signal::new(6, 15, ByteOrder::Motorola, false, 0.01, -67.67, Multiplex::Plain).expect("valid"),
        Signal::new(24, 12, ByteOrder::Intel, true, 0.5, 0.0, Multiplex::Multiplexed(0x20)).expect("valid"),
    ];
    let mut decoder = Decoder::<4>::default();
    let (mut decoded, mut problems, mut sum) = (0, 0, 0.0);
    let info = allocation_counter::measure(|| {
        for round in 0..100i64 {
            for (i, frame) in frames.iter().enumerate() {
                let now = Timestamp::from_micros(round * 2_000_000 + i as i64 * 1000);
                decoder.decode(now, frame, |event| match event {
                    Event::Decoded(_) => decoded += 1,
                    Event::Error(_) | Event::Dropped(_) => problems += 1,
                });
                decode_message(&signals, embedded_can::Frame::data(frame), |_, v| sum += v);
            }
        }
    });
    // Per round: 129025, 129026, 129029, CCVS1, VP1, OBD = 6; a clash and a truncated
    // frame, and the clashed message times out in the next round (not after the last).
    assert_eq!((decoded, problems), (600, 299));
    assert!(sum != 0.0);
    assert_eq!(info.count_total, 0, "CAN decoding allocated {} times", info.count_total);
}

#[test]
fn the_counter_sees_allocations() {
    // Guard against a counter that never counts.
    let info = allocation_counter::measure(|| {
        let v: Vec<u8> = std::hint::black_box(Vec::with_capacity(64));
        drop(v);
    });
    assert!(info.count_total >= 1);
}
