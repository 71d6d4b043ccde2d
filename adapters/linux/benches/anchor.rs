//! Cost of one incremental anchor update (the on-device hot path): a GNSS fix paired
//! with VO under 9 latency hypotheses, robust weighting, Umeyama per hypothesis, wheel
//! fusion and observability. Fed in the steady state of a long synthetic drive.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use dash2sim_core::anchor::{AnchorConfig, Anchorer};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::time::Timestamp;

fn position(t: f64) -> Vector3<f64> {
    Vector3::new(300.0 * (t / 30.0).sin(), 200.0 * (t / 45.0).cos(), 2.0 * (t / 10.0).sin())
}

fn ts(t: f64) -> Timestamp {
    Timestamp::from_micros((t * 1e6) as i64)
}

/// An anchorer after `seconds` of drive (VO 20 Hz, GNSS 10 Hz, speed 50 Hz).
fn warmed_up(seconds: f64) -> Anchorer {
    let mut a: Anchorer = Anchorer::new(AnchorConfig::default());
    for k in 0..(seconds * 100.0) as usize {
        let t = k as f64 * 0.01;
        if k % 2 == 0 {
            let _ = a.push_speed(ts(t), (position(t + 0.01) - position(t)).norm() * 100.0);
        }
        if k % 10 == 0 && k > 0 {
            let _ = a.push_gnss(ts(t), position(t - 0.05), 2.0);
        }
        if k % 5 == 0 {
            let _ = a.push_vo(ts(t), position(t) * 0.5);
        }
    }
    a
}

fn anchor_update(c: &mut Criterion) {
    let base = warmed_up(60.0);
    let t = 60.0;
    c.bench_function("anchor_update_gnss_fix", |b| {
        b.iter_batched_ref(
            || base.clone(),
            |a| {
                // The fix waits for the VO frame after it, which triggers the update.
                let _ = a.push_gnss(ts(t), position(t - 0.05), 2.0);
                let _ = a.push_vo(ts(t + 0.001), position(t + 0.001) * 0.5);
            },
            BatchSize::SmallInput,
        )
    });
    c.bench_function("anchor_vo_frame_only", |b| {
        b.iter_batched_ref(
            || base.clone(),
            |a| a.push_vo(ts(t + 0.001), position(t + 0.001) * 0.5),
            BatchSize::SmallInput,
        )
    });
}

criterion_group!(benches, anchor_update);
criterion_main!(benches);
