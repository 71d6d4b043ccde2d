//! The 3D track manager's per-frame cost in steady state: 64 tracks × 64 detections
//! (predict + 3D GIoU association + Joseph-form update), AB3DMOT's car settings. The same
//! input (a formula, below and in `scripts/bench_ab3dmot.py`) is run by an AB3DMOT-style
//! loop on filterpy + scipy. Also prints the tracker's state size. Figures in
//! docs/benchmarks.md.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use dash2sim_core::box3d::Box3d;
use dash2sim_core::track3d::{
    Association, ClassConfig, Config3d, Detection3d, Tracker3d, AB3DMOT_MEASUREMENT_NOISE, AB3DMOT_PROCESS_NOISE,
};

const OBJECTS: usize = 64;
const WARM_UP: usize = 10;
const TIMED: usize = 50;

const CAR: [ClassConfig; 1] = [ClassConfig {
    association: Association::Giou(-0.2),
    min_size: [1.0, 0.5, 0.5],
    max_size: [10.0, 4.0, 4.0],
    max_ground_offset: 1.0,
    process_noise: AB3DMOT_PROCESS_NOISE,
    measurement_noise: AB3DMOT_MEASUREMENT_NOISE,
    initial_velocity_variance: 1e4,
}];

/// Frame `k`'s detections: 64 cars on an 8 × 8 grid 10 m apart, each at its own constant
/// velocity, with deterministic noise, in a shuffled order (index i·37 + k mod 64).
fn detections(k: usize) -> Vec<Detection3d> {
    (0..OBJECTS)
        .map(|j| {
            let i = (j * 37 + k) % OBJECTS;
            let (fi, fk) = (i as f64, k as f64);
            let x = 10.0 * (i % 8) as f64 + (0.3 + 0.01 * fi) * fk + 0.1 * (1.7 * fi + 0.9 * fk).sin();
            let y = 10.0 * (i / 8) as f64 + (0.2 - 0.005 * fi) * fk + 0.1 * (2.3 * fi + 1.1 * fk).cos();
            let yaw = 0.1 * fi + 0.02 * (fi + fk).sin();
            Detection3d::new(0, Box3d { x, y, z: 0.8, yaw, l: 4.5, w: 1.9, h: 1.6 }, 0.9)
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let config = Config3d { classes: &CAR, min_hits: 3, max_age: 2, ground_z: 0.0, static_speed: 0.05 };
    let frames: Vec<Vec<Detection3d>> = (0..WARM_UP + TIMED).map(detections).collect();
    let mut warm = Tracker3d::<OBJECTS>::new(config);
    for (k, f) in frames.iter().enumerate().take(WARM_UP) {
        warm.update(k as u64, f, |_| {}).expect("in order");
    }
    let mut check = warm.clone();
    let mut reported = 0;
    for (k, f) in frames.iter().enumerate().skip(WARM_UP) {
        check.update(k as u64, f, |_| reported += 1).expect("in order");
    }
    assert_eq!(reported, OBJECTS * TIMED, "every object tracked in every timed frame");
    eprintln!(
        "Tracker3d<64>: {} bytes of state (size_of), {} ids issued",
        size_of::<Tracker3d<'_, OBJECTS>>(),
        OBJECTS
    );
    c.bench_function("track3d 64x64, 50 frames", |b| {
        b.iter_batched(
            || warm.clone(),
            |mut tracker| {
                for (k, f) in frames.iter().enumerate().skip(WARM_UP) {
                    let _ = tracker.update(k as u64, f, |o| {
                        std::hint::black_box(o);
                    });
                }
                tracker
            },
            BatchSize::SmallInput,
        )
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
