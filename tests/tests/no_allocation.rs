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

#[test]
fn the_counter_sees_allocations() {
    // Guard against a counter that never counts.
    let info = allocation_counter::measure(|| {
        let v: Vec<u8> = std::hint::black_box(Vec::with_capacity(64));
        drop(v);
    });
    assert!(info.count_total >= 1);
}
