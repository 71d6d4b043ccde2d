//! Cost of `dash2sim finish` as the drive grows (issues #14, #58): synthetic drives of 1,
//! 10, 60 and 180 minutes with 20 Hz VO (a drifting similarity of the truth), 5 Hz GNSS
//! (σ 1.5 m) and 50 Hz wheel speed, finished without a map (re-anchoring, ego smoothing, the
//! finished records). Each log is also written to `target/finish-<N>min.d2slog` so that the
//! CLI's time and peak memory, and GTSAM's on the same problem, can be measured on it
//! (`docs/benchmarks.md`).

use criterion::{criterion_group, criterion_main, Criterion};
use dash2sim_core::binlog::{quantise, GnssFix, Header, Record, VehicleSpeed, VoPose};
use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::{Rotation3, Vector3};
use dash2sim_core::pipeline::CameraMount;
use dash2sim_finish::finish;
use dash2sim_finish::solve::Settings;
use dash2sim_linux::log::{self, LogContents, RecordStore};

const ORIGIN: [f64; 3] = [60.17, 24.94, 20.0];

/// The car's heading and speed at `t`: a meandering road at 12–18 m/s (the position is
/// their integral).
fn heading_speed(t: f64) -> (f64, f64) {
    (0.8 * (t / 40.0).sin() + 0.3 * (t / 7.0).sin(), 15.0 + 3.0 * (t / 25.0).sin())
}

/// The VO frame's yaw drift at `t`, rad.
fn vo_yaw(t: f64) -> f64 {
    0.035 * (t / 500.0).sin()
}

/// Records of a `minutes`-long drive.
fn drive(minutes: f64) -> (Header, Vec<Record>) {
    let frame = LocalFrame::new(Geodetic::new(ORIGIN[0], ORIGIN[1], ORIGIN[2]).expect("origin"));
    let mut records = Vec::new();
    let (mut position, dt) = (Vector3::<f64>::zeros(), 0.01);
    // VO integrates the car's increments through a drifting similarity (scale 3.7 ± 2 %,
    // yaw ± 2°), from its own origin: how monocular VO drifts.
    let mut vo = Vector3::<f64>::zeros();
    let steps = (minutes * 60.0 / dt) as usize;
    let mut noise_state = 12345u64;
    let mut noise = || {
        // xorshift, mapped to a sum of uniforms ≈ N(0, 1).
        let mut s = 0.0;
        for _ in 0..4 {
            noise_state ^= noise_state << 13;
            noise_state ^= noise_state >> 7;
            noise_state ^= noise_state << 17;
            s += (noise_state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        }
        s * 3f64.sqrt()
    };
    let t0 = 1_700_000_000.0;
    for k in 0..=steps {
        let t = k as f64 * dt;
        let (heading, speed) = heading_speed(t);
        let us = quantise(t0 + t, 1e-6);
        if k % 5 == 0 {
            let yaw = vo_yaw(t);
            records.push(Record::VoPose(VoPose {
                t_us: us,
                x: quantise(vo.x, 1e-3),
                y: quantise(vo.y, 1e-3),
                z: quantise(vo.z, 1e-3),
                yaw_e4: quantise(heading + yaw, 1e-4),
                pitch_e4: 0,
                roll_e4: 0,
                session: 0,
            }));
        }
        if k % 2 == 0 {
            records.push(Record::VehicleSpeed(VehicleSpeed { t_us: us, speed_mm_s: quantise(speed, 1e-3), source: 0 }));
        }
        if k % 20 == 0 {
            let noisy = position + Vector3::new(1.5 * noise(), 1.5 * noise(), 2.0 * noise());
            let g = frame.enu_to_geodetic(&noisy).expect("geodetic");
            records.push(Record::GnssFix(GnssFix {
                t_us: us,
                lat_e7: quantise(g.lat_deg, 1e-7),
                lon_e7: quantise(g.lon_deg, 1e-7),
                alt_mm: quantise(g.height_m, 1e-3),
                hdop_e2: 60,
                satellites: 12,
                mode: 3,
                ..GnssFix::default()
            }));
        }
        let step = Vector3::new(heading.cos(), heading.sin(), 0.0) * speed * dt;
        let scale = 1.0 / (3.7 * (1.0 + 0.02 * (t / 300.0).sin()));
        vo += Rotation3::from_euler_angles(0.0, 0.0, vo_yaw(t)) * step * scale;
        position += step;
    }
    let header = Header {
        device_id: *b"dash2sim-bench\0\0",
        origin: [quantise(ORIGIN[0], 1e-7) as i32, quantise(ORIGIN[1], 1e-7) as i32, quantise(ORIGIN[2], 1e-3) as i32],
    };
    (header, records)
}

fn contents(minutes: f64) -> LogContents<RecordStore> {
    let (header, mut records) = drive(minutes);
    let bytes = log::import::encode(&header, &mut records).expect("encode");
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../target/finish-{minutes:.0}min.d2slog"));
    std::fs::write(&path, &bytes).expect("write the log");
    log::decode_compact(&bytes, "bench").expect("decode")
}

fn finishing(c: &mut Criterion) {
    let mut group = c.benchmark_group("finish");
    group.sample_size(10);
    for minutes in [1.0, 10.0, 60.0, 180.0] {
        let log = contents(minutes);
        let settings = Settings { gravity_aligned: true, ..Settings::default() };
        group.bench_function(format!("{minutes:.0}_min"), |b| {
            b.iter(|| finish(&log, "bench", None, None, CameraMount::default(), settings, 2.5).expect("finish"))
        });
    }
    group.finish();
}

criterion_group!(benches, finishing);
criterion_main!(benches);
