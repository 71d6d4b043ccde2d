//! The anchorer takes numbers from sensors: any sequence of pushes (NaN, inf, huge,
//! out of order, repeated) must be refused or absorbed without a panic, and whatever
//! estimate it reports must be finite with a positive scale.
#![no_main]

use dash2sim_core::anchor::{AnchorConfig, AnchorMode, Anchorer};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::time::Timestamp;
use libfuzzer_sys::fuzz_target;

fn f64_at(bytes: &[u8]) -> f64 {
    let mut b = [0u8; 8];
    for (d, s) in b.iter_mut().zip(bytes) {
        *d = *s;
    }
    f64::from_le_bytes(b)
}

fuzz_target!(|data: &[u8]| {
    let Some((&mode, mut rest)) = data.split_first() else { return };
    let config = AnchorConfig {
        mode: if mode & 1 == 0 { AnchorMode::Full } else { AnchorMode::GravityAligned },
        ..AnchorConfig::default()
    };
    let mut anchorer: Anchorer = Anchorer::new(config);
    // Each record: kind (1), time µs delta (2), three f64 values (24).
    while rest.len() >= 27 {
        let (record, tail) = rest.split_at(27);
        rest = tail;
        let dt = i64::from(u16::from_le_bytes([record[1], record[2]]));
        let t = Timestamp::from_micros(dt * 1000);
        let v = Vector3::new(f64_at(&record[3..]), f64_at(&record[11..]), f64_at(&record[19..]));
        let _ = match record[0] % 3 {
            0 => anchorer.push_vo(t, v),
            1 => anchorer.push_gnss(t, v, v.x.abs() % 10.0 + 0.1),
            _ => anchorer.push_speed(t, v.y),
        };
        if let Some(est) = anchorer.estimate() {
            assert!(est.is_valid(), "{est:?}");
        }
    }
});
