use super::*;

const HEADER: Header = Header { device_id: *b"dashcam-0001\0\0\0\0", origin: [602_711_000, 248_572_000, 12_000] };

/// A 20 Hz drive: ego poses, speeds at 50 Hz, a fix every 10 poses, an event.
fn records(n: i64) -> heapless::Vec<Record, 224> {
    let mut out = heapless::Vec::new();
    for k in 0..n {
        let t = 1_700_000_000_000_000 + k * 50_000;
        let _ = out.push(Record::EgoPose(EgoPose {
            t_us: t,
            x_mm: 1000 * k + k * k,
            y_mm: -500 * k,
            z_mm: 12,
            yaw_e4: 100 + k,
            sigma_mm: 0,
        }));
        let _ = out.push(Record::VehicleSpeed(VehicleSpeed { t_us: t + 3, speed_mm_s: 20_000 + k, source: 0 }));
        if k % 10 == 0 {
            let _ = out.push(Record::GnssFix(GnssFix {
                t_us: t + 80_000,
                lat_e7: 602_711_000 + 9 * k,
                lon_e7: 248_572_000 + 18 * k,
                alt_mm: 15_000,
                speed_mm_s: 20_000,
                track_e4: 7854,
                hdop_e2: 90,
                satellites: 12,
                mode: 3,
            }));
        }
        if k % 4 == 0 {
            // Ten tracks at once (more than one record holds): eight standing cones, a
            // car at constant velocity, a truck that brakes.
            let mut batch = Tracks3d { t_us: t, tracks: heapless::Vec::new() };
            for id in 0..10 {
                let track = match id {
                    0..=7 => Track3d {
                        id,
                        class: 6,
                        x_mm: 50_000 + 5000 * id,
                        y_mm: -3500,
                        l_mm: 400,
                        w_mm: 400,
                        h_mm: 700,
                        is_static: 1,
                        ..Track3d::default()
                    },
                    8 => Track3d {
                        id: 40,
                        class: 0,
                        x_mm: 1500 * k,
                        y_mm: 1750,
                        l_mm: 4600,
                        w_mm: 1900,
                        h_mm: 1500,
                        vx_mm_s: 15_000,
                        ..Track3d::default()
                    },
                    _ => Track3d {
                        id: 41,
                        class: 1,
                        x_mm: 1000 * k - 10 * k * k,
                        y_mm: 1750,
                        l_mm: 9000,
                        w_mm: 2500,
                        h_mm: 3500,
                        yaw_e4: k,
                        vx_mm_s: 10_000 - 200 * k,
                        ..Track3d::default()
                    },
                };
                if batch.tracks.is_full() {
                    let _ = out.push(Record::Tracks3d(core::mem::replace(
                        &mut batch,
                        Tracks3d { t_us: t, tracks: heapless::Vec::new() },
                    )));
                }
                let _ = batch.tracks.push(track);
            }
            let _ = out.push(Record::Tracks3d(batch));
        }
        if k == 7 {
            let mut text = heapless::Vec::new();
            let _ = text.extend_from_slice(b"work zone ahead");
            let _ = out.push(Record::Event(EventRecord { t_us: t, level: 2, text }));
        }
    }
    out
}

/// One-second segments, so that the short test drives span several.
fn short_segments() -> WriterConfig {
    WriterConfig { segment_us: 1_000_000, ..WriterConfig::default() }
}

fn write(records: &[Record], config: WriterConfig, out: &mut [u8]) -> usize {
    let total = out.len();
    let mut rest: &mut [u8] = out;
    let mut w: Writer<&mut &mut [u8], 4096> = Writer::new(&mut rest, &HEADER, config).expect("header");
    for r in records {
        w.write(r).expect("fits");
    }
    w.finish().expect("finish");
    total - rest.len()
}

fn read(bytes: &[u8], chunk: usize) -> (heapless::Vec<Record, 224>, Stats, bool) {
    let mut d: Decoder = Decoder::new();
    let mut got = heapless::Vec::new();
    let mut header = false;
    let mut on = |e: Event| match e {
        Event::Record(r) => {
            let _ = got.push(r);
        }
        Event::Header(h) => header = h == HEADER,
        _ => {}
    };
    for c in bytes.chunks(chunk.max(1)) {
        d.push(c, &mut on);
    }
    d.finish(&mut on);
    (got, *d.stats(), header)
}

#[test]
fn records_round_trip_in_any_chunking() {
    let input = records(80);
    let mut buf = [0u8; 16_384];
    let n = write(&input, short_segments(), &mut buf);
    for chunk in [1, 7, 100, 4096, n] {
        let (got, stats, header) = read(&buf[..n], chunk);
        assert!(header);
        assert_eq!(got, input, "chunk {chunk}");
        assert_eq!((stats.damaged, stats.lost, stats.segments), (0, 0, 4), "80 poses at 20 Hz, 1 s segments");
    }
    // A steady pose stream costs a few bytes per record.
    let (_, stats, _) = read(&buf[..n], 4096);
    let i = Kind::ALL.iter().position(|k| *k == Kind::EgoPose).expect("kind");
    let per_pose = stats.bytes[i] as f64 / stats.records[i] as f64;
    assert!(per_pose <= 12.0, "{per_pose} bytes per ego pose");
}

#[test]
fn a_log_cut_anywhere_gives_back_every_record_before_the_cut() {
    let input = records(40);
    let mut buf = [0u8; 8192];
    let n = write(&input, WriterConfig { flush: FlushPolicy::EveryRecord, ..short_segments() }, &mut buf);
    // Where each record's frame ends, from a clean read with offsets.
    let (full, _, _) = read(&buf[..n], n);
    assert_eq!(full, input);
    let mut previous = 0;
    for cut in 0..=n {
        let (got, stats, _) = read(&buf[..cut], 64);
        assert!(got.len() >= previous, "cut {cut}: fewer records than a shorter cut");
        assert_eq!(&input[..got.len()], &got[..], "cut {cut}: a prefix, exactly");
        assert!(stats.damaged <= 1);
        previous = got.len();
    }
    assert_eq!(previous, input.len());
}

fn is_subsequence(got: &[Record], of: &[Record]) -> bool {
    let mut it = of.iter();
    got.iter().all(|g| it.any(|r| r == g))
}

#[test]
fn flipped_bits_lose_only_the_damaged_stretch_and_reading_resumes() {
    let input = records(80);
    let mut buf = [0u8; 16_384];
    let n = write(&input, short_segments(), &mut buf);
    let last_sync = (0..n - SYNC.len()).rev().find(|&i| buf[i..i + SYNC.len()] == SYNC).expect("segments");
    let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
    let mut damaged_total = 0;
    for _ in 0..400 {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let at = 6 + (seed as usize) % (n - 6);
        let mut flipped = buf;
        flipped[at] ^= 1 << ((seed >> 32) % 8);
        let (before, _, _) = read(&buf[..at], 4096);
        let (got, stats, _) = read(&flipped[..n], 4096);
        assert!(got.len() >= before.len() && got[..before.len()] == before[..], "flip at {at}: the records before it");
        assert!(is_subsequence(&got, &input), "flip at {at}: no invented records");
        if at < last_sync {
            assert_eq!(got.last(), input.last(), "flip at {at}: reading resumes by the last segment");
        }
        assert!(stats.damaged >= 1 || got == input, "flip at {at}: damage is counted");
        damaged_total += stats.damaged;
    }
    assert!(damaged_total >= 400);
}

#[test]
fn an_appended_field_costs_nothing_while_it_is_zero_and_round_trips_when_it_is_not() {
    let pose = |k: i64, sigma_mm: i64| {
        Record::EgoPose(EgoPose { t_us: k * 100_000, x_mm: 1000 * k, y_mm: 0, z_mm: 5, yaw_e4: 0, sigma_mm })
    };
    let length = |sigma_mm: i64| {
        let mut out = [0u8; 64];
        Streams::default().encode(&pose(1, sigma_mm), &mut out).expect("fits")
    };
    // The σ (appended in v1.3) is left out while it is 0; the yaw, as 0 but of the first
    // version, is not (a reader of that version needs it).
    assert_eq!(length(0) + 1, length(7));
    assert_eq!(length(0), 8, "t 3 bytes, x 2, y, z and yaw 1 each");
    // σ going 0 → 250 → 0 → 0 → 300 round-trips: the decoder's state follows the values.
    let input = [pose(1, 0), pose(2, 250), pose(3, 0), pose(4, 0), pose(5, 300)];
    let mut buf = [0u8; 2048];
    let n = write(&input, WriterConfig::default(), &mut buf);
    let (got, stats, _) = read(&buf[..n], 7);
    assert_eq!(got.as_slice(), &input);
    assert_eq!(stats.damaged, 0);
}

#[test]
fn an_anchor_estimate_without_a_latency_is_as_long_as_in_v1_3() {
    let anchor = |latency_us: i64| {
        Record::AnchorEstimate(AnchorEstimate {
            t_us: 1_000_000,
            scale_e6: 1_000_000,
            yaw_e6: 5,
            pitch_e6: 0,
            roll_e6: 0,
            tx_mm: 10,
            ty_mm: 20,
            tz_mm: 0,
            observability: 2,
            anchors: 12,
            rms_mm: 900,
            latency_us,
        })
    };
    let length = |latency_us: i64| {
        let mut out = [0u8; 96];
        Streams::default().encode(&anchor(latency_us), &mut out).expect("fits")
    };
    // The latency (appended in v1.4) is left out while it is 0; 62.5 ms takes three bytes.
    assert_eq!(length(0) + 3, length(62_500));
    let input = [anchor(0), anchor(62_500), anchor(0)];
    let mut buf = [0u8; 2048];
    let n = write(&input, WriterConfig::default(), &mut buf);
    let (got, stats, _) = read(&buf[..n], 3);
    assert_eq!(got.as_slice(), &input);
    assert_eq!(stats.damaged, 0);
}

/// A sink that refuses its next `refuse` writes (a failing card), then takes all.
struct Flaky<'a> {
    out: [u8; 32_768],
    len: usize,
    refuse: &'a core::cell::Cell<u32>,
}

impl embedded_io::ErrorType for Flaky<'_> {
    type Error = embedded_io::ErrorKind;
}

impl embedded_io::Write for Flaky<'_> {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
        if self.refuse.get() > 0 {
            self.refuse.set(self.refuse.get() - 1);
            return Err(embedded_io::ErrorKind::OutOfMemory);
        }
        let n = buf.len().min(self.out.len() - self.len);
        self.out[self.len..self.len + n].copy_from_slice(&buf[..n]);
        self.len += n;
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Self::Error> {
        Ok(())
    }
}

#[test]
fn a_sink_that_refuses_writes_loses_records_but_never_garbles_the_ones_after() {
    let input = records(200);
    // A buffer of the MCU's size flushed only when full: each refusal lands on the flush
    // that makes room for a record, mid-segment, and the next flush succeeds.
    let refuse = core::cell::Cell::new(0);
    let sink = Flaky { out: [0; 32_768], len: 0, refuse: &refuse };
    let config = WriterConfig { flush: FlushPolicy::WhenFull, ..short_segments() };
    let mut w: Writer<Flaky<'_>, 2304> = Writer::new(sink, &HEADER, config).expect("header");
    let mut refused = 0;
    for (k, r) in input.iter().enumerate() {
        if k % 100 == 50 {
            refuse.set(1);
        }
        if w.write(r).is_err() {
            refused += 1;
        }
    }
    refuse.set(0);
    let sink = w.finish().expect("finish");
    assert!(refused > 0, "the refusals hit a flush");
    let (got, stats, _) = read(&sink.out[..sink.len], 4096);
    assert!(got.len() < input.len(), "records were lost");
    assert!(got.len() >= input.len() - 2 * refused, "{} of {}", got.len(), input.len());
    assert!(is_subsequence(&got, &input), "every record read back is one written, exactly");
    assert_eq!(stats.damaged, 0);
}
