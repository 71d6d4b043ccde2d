//! Trajectory evaluation throughput, end to end (read files, associate, align, metric,
//! statistics) on KITTI 00 — the same work as `evo_ape kitti ... -as` / `evo_rpe`.
//! Compare with `scripts/bench_evo.py` on the same machine; figures in docs/benchmarks.md.
//!
//! Needs the shared data (`DASH2SIM_DATA`, default `../shared/data`); without it the
//! file benchmarks are skipped with a message.

/// What the benches share, the host library's (where the recorded data lives).
#[path = "../../linux/benches/common/mod.rs"]
mod common;

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use dash2sim_core::traj::{Delta, RpePairs};
use dash2sim_linux::trajectory::Format;
use dash2sim_verify::evaluate::{self, Align, Relation};

fn evo_dir() -> Option<PathBuf> {
    common::data("evo")
}

fn kitti(c: &mut Criterion) {
    let Some(dir) = evo_dir() else { return };
    let (gt, orb) = (dir.join("KITTI_00_gt.txt"), dir.join("KITTI_00_ORB.txt"));
    let mut group = c.benchmark_group("kitti00_4541_poses");
    group.bench_function("ape_sim3_end_to_end", |b| {
        b.iter(|| {
            let (r, e) =
                evaluate::load_pair(&gt, &orb, Format::Kitti, evaluate::Association::within(0.01)).expect("load");
            evaluate::ape(&r, &e, Align::Sim3, Relation::Trans).expect("ape")
        })
    });
    let rpe_10m = RpePairs { delta: Delta::Metres(10.0), all_pairs: false, from_reference: false };
    group.bench_function("rpe_10m_end_to_end", |b| {
        b.iter(|| {
            let (r, e) =
                evaluate::load_pair(&gt, &orb, Format::Kitti, evaluate::Association::within(0.01)).expect("load");
            evaluate::rpe(&r, &e, Align::None, Relation::Trans, rpe_10m).expect("rpe")
        })
    });
    let (r, e) = evaluate::load_pair(&gt, &orb, Format::Kitti, evaluate::Association::within(0.01)).expect("load");
    group.bench_function("ape_sim3_compute_only", |b| {
        b.iter(|| evaluate::ape(&r, &e, Align::Sim3, Relation::Trans).expect("ape"))
    });
    let rpe_1f = RpePairs { delta: Delta::Frames(1), ..rpe_10m };
    group.bench_function("rpe_1frame_angle_compute_only", |b| {
        b.iter(|| evaluate::rpe(&r, &e, Align::None, Relation::AngleDeg, rpe_1f).expect("rpe"))
    });
    group.finish();
}

criterion_group!(benches, kitti);
criterion_main!(benches);
