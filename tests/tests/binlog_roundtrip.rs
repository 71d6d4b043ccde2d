//! The 4D log round trip on property-generated records: every kind, any values (the
//! codec wraps differences, so even i64::MIN survives), any order, any segment bounds and
//! any chunking of the bytes — decode(encode(x)) == x. And at the physical level: metres,
//! degrees and seconds come back within half a quantisation step.

use dash2sim_core::binlog::{
    AnchorEstimate, Decoder, Detection2d, EgoPose, Event, EventRecord, FlushPolicy, FrameMeta, GnssFix, Header,
    MountEstimate, Record, Track2d, Track3d, TrackCovariance, Tracks3d, VehicleSpeed, Verification, VoPose, Writer,
    WriterConfig, MAX_TRACKS,
};
use dash2sim_linux::log::quantise;
use proptest::prelude::*;

fn value() -> impl Strategy<Value = i64> + Clone {
    prop_oneof![
        6 => -2000i64..2000,
        2 => -2_000_000_000i64..2_000_000_000,
        1 => any::<i64>(),
        1 => Just(i64::MIN),
        1 => Just(i64::MAX),
    ]
}

fn track() -> impl Strategy<Value = Track3d> {
    prop::array::uniform12(value()).prop_map(|v| Track3d {
        id: v[0] % 50,
        class: v[1],
        x_mm: v[2],
        y_mm: v[3],
        z_mm: v[4],
        l_mm: v[5],
        w_mm: v[6],
        h_mm: v[7],
        yaw_e4: v[8],
        vx_mm_s: v[9],
        vy_mm_s: v[10],
        is_static: v[11] % 3,
    })
}

fn record() -> impl Strategy<Value = Record> {
    let t = value();
    prop_oneof![
        (t.clone(), prop::array::uniform8(value())).prop_map(|(t_us, v)| Record::GnssFix(GnssFix {
            t_us,
            lat_e7: v[0],
            lon_e7: v[1],
            alt_mm: v[2],
            speed_mm_s: v[3],
            track_e4: v[4],
            hdop_e2: v[5],
            satellites: v[6],
            mode: v[7]
        })),
        (t.clone(), value(), value()).prop_map(|(t_us, s, k)| Record::VehicleSpeed(VehicleSpeed {
            t_us,
            speed_mm_s: s,
            source: k
        })),
        (t.clone(), prop::array::uniform7(value())).prop_map(|(t_us, v)| Record::VoPose(VoPose {
            t_us,
            x: v[0],
            y: v[1],
            z: v[2],
            yaw_e4: v[3],
            pitch_e4: v[4],
            roll_e4: v[5],
            session: v[6]
        })),
        (t.clone(), prop::array::uniform7(value())).prop_map(|(t_us, v)| Record::MountEstimate(MountEstimate {
            t_us,
            yaw_e6: v[0],
            pitch_e6: v[1],
            roll_e6: v[2],
            sigma_yaw_e6: v[3],
            sigma_pitch_e6: v[4],
            samples: v[5],
            calibrated: v[6]
        })),
        (t.clone(), prop::array::uniform4(value())).prop_map(|(t_us, v)| Record::TrackCovariance(TrackCovariance {
            t_us,
            id: v[0],
            cov_xx_mm2: v[1],
            cov_xy_mm2: v[2],
            cov_yy_mm2: v[3]
        })),
        (t.clone(), prop::array::uniform5(value())).prop_map(|(t_us, v)| Record::EgoPose(EgoPose {
            t_us,
            x_mm: v[0],
            y_mm: v[1],
            z_mm: v[2],
            yaw_e4: v[3],
            sigma_mm: v[4]
        })),
        (t.clone(), prop::array::uniform11(value())).prop_map(|(t_us, v)| Record::AnchorEstimate(AnchorEstimate {
            t_us,
            scale_e6: v[0],
            yaw_e6: v[1],
            pitch_e6: v[2],
            roll_e6: v[3],
            tx_mm: v[4],
            ty_mm: v[5],
            tz_mm: v[6],
            observability: v[7],
            anchors: v[8],
            rms_mm: v[9],
            latency_us: v[10]
        })),
        (t.clone(), value(), value()).prop_map(|(t_us, frame, flags)| Record::FrameMeta(FrameMeta {
            t_us,
            frame,
            flags
        })),
        (t.clone(), prop::array::uniform7(value())).prop_map(|(t_us, v)| Record::Detection2d(Detection2d {
            t_us,
            frame: v[0],
            class: v[1],
            score_e3: v[2],
            x_e1: v[3],
            y_e1: v[4],
            w_e1: v[5],
            h_e1: v[6]
        })),
        (t.clone(), prop::array::uniform7(value())).prop_map(|(t_us, v)| Record::Track2d(Track2d {
            t_us,
            id: v[0],
            class: v[1],
            score_e3: v[2],
            x_e1: v[3],
            y_e1: v[4],
            w_e1: v[5],
            h_e1: v[6]
        })),
        (t.clone(), prop::collection::vec(track(), 1..=MAX_TRACKS)).prop_map(|(t_us, tracks)| {
            let mut b = Tracks3d { t_us, ..Tracks3d::default() };
            for x in tracks {
                let _ = b.tracks.push(x);
            }
            Record::Tracks3d(b)
        }),
        (t.clone(), prop::array::uniform13(value())).prop_map(|(t_us, v)| Record::Verification(Verification {
            t_us,
            collisions_e4: v[0],
            drivable_e4: v[1],
            direction_e4: v[2],
            making_progress_e4: v[3],
            progress_e4: v[4],
            ttc_e4: v[5],
            speed_limit_e4: v[6],
            comfort_e4: v[7],
            score_e2: v[8],
            worst_corner_mm: v[9],
            decision: v[10],
            score_low_e2: v[11],
            score_high_e2: v[12]
        })),
        (t, 0u8..6, prop::collection::vec(any::<u8>(), 0..255)).prop_map(|(t_us, level, text)| {
            let mut e = EventRecord { t_us, level, ..EventRecord::default() };
            for b in text {
                let _ = e.text.push(b);
            }
            Record::Event(e)
        }),
    ]
}

const HEADER: Header = Header { device_id: [7; 16], origin: [123_456_789, -987_654_321, -5000] };

fn encode(records: &[Record], config: WriterConfig) -> Vec<u8> {
    let mut w: Box<Writer<Vec<u8>, 8192>> = Box::new(Writer::new(Vec::new(), &HEADER, config).expect("header"));
    for r in records {
        w.write(r).expect("every record fits");
    }
    w.finish().expect("finish")
}

fn decode(bytes: &[u8], chunk: usize) -> (Vec<Record>, u64) {
    let mut d: Box<Decoder> = Box::default();
    let mut out = Vec::new();
    let mut on = |e: Event| {
        if let Event::Record(r) = e {
            out.push(r);
        }
    };
    for c in bytes.chunks(chunk) {
        d.push(c, &mut on);
    }
    d.finish(&mut on);
    let damaged = d.stats().damaged;
    (out, damaged)
}

/// A log's records with the 3D tracks of one time as one list. A writer puts the tracks of
/// one time into one frame until it is full and then starts another, and a reader hands a
/// frame back in records of at most `MAX_TRACKS` tracks: how a time's tracks are cut into
/// records depends on their coded size, what they are does not.
#[derive(Debug, PartialEq)]
enum Joined {
    Tracks(i64, Vec<Track3d>),
    Other(Box<Record>),
}

fn joined(records: &[Record]) -> Vec<Joined> {
    let mut out: Vec<Joined> = Vec::new();
    for r in records {
        match (r, out.last_mut()) {
            (Record::Tracks3d(b), Some(Joined::Tracks(t, tracks))) if *t == b.t_us => {
                tracks.extend(b.tracks.iter().copied());
            }
            (Record::Tracks3d(b), _) => out.push(Joined::Tracks(b.t_us, b.tracks.to_vec())),
            (other, _) => out.push(Joined::Other(Box::new(other.clone()))),
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, ..ProptestConfig::default() })]

    #[test]
    fn decode_of_encode_is_the_identity(
        records in prop::collection::vec(record(), 0..120),
        segment_us in prop_oneof![Just(1i64), 1i64..10_000_000, Just(i64::MAX)],
        segment_records in 1u32..300,
        chunk in 1usize..5000,
        every_record in any::<bool>(),
    ) {
        let flush = if every_record { FlushPolicy::EveryRecord } else { FlushPolicy::WhenFull };
        let bytes = encode(&records, WriterConfig { segment_us, segment_records, flush });
        let (back, damaged) = decode(&bytes, chunk);
        prop_assert_eq!(damaged, 0);
        prop_assert_eq!(joined(&back), joined(&records));
    }
}

#[test]
fn physical_values_come_back_within_half_a_step() {
    let (x, lat, t) = (1_234.567_891_2_f64, 37.721_000_009_f64, 46_408.547_498_3_f64);
    let record = Record::GnssFix(GnssFix {
        t_us: quantise(t, 1e-6),
        lat_e7: quantise(lat, 1e-7),
        alt_mm: quantise(x, 1e-3),
        ..GnssFix::default()
    });
    let (back, _) = decode(&encode(std::slice::from_ref(&record), WriterConfig::default()), 64);
    let Some(Record::GnssFix(f)) = back.first() else { panic!("a fix") };
    assert!((f.t_us as f64 * 1e-6 - t).abs() <= 0.5e-6);
    assert!((f.lat_e7 as f64 * 1e-7 - lat).abs() <= 0.5e-7);
    assert!((f.alt_mm as f64 * 1e-3 - x).abs() <= 0.5e-3);
}
