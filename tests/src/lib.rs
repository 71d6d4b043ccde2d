//! Shared helpers of the conformance tests: where the real data lives, and how a test
//! says it was skipped.
//!
//! The recordings in `../shared/data` are not part of the repository (their licenses
//! forbid it). Tests find them through `DASH2SIM_DATA`, defaulting to `../shared/data`
//! beside the workspace. When the folder is absent a test prints that it was skipped and
//! why — unless `DASH2SIM_REQUIRE_DATA=1` (CI), where a missing folder fails the test.
#![forbid(unsafe_code)]

use std::path::{Path, PathBuf};

pub mod can;
pub mod drive;
pub mod recorded;
pub mod road;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

/// `$DASH2SIM_DATA/<sub>` if it exists; otherwise `None` after printing why the calling
/// test is skipped. Panics instead when `DASH2SIM_REQUIRE_DATA=1`.
pub fn data_dir(sub: &str) -> Option<PathBuf> {
    let base =
        std::env::var_os("DASH2SIM_DATA").map(PathBuf::from).unwrap_or_else(|| workspace_root().join("../shared/data"));
    let dir = base.join(sub);
    if dir.is_dir() {
        return Some(dir);
    }
    let required = std::env::var("DASH2SIM_REQUIRE_DATA").is_ok_and(|v| v == "1");
    assert!(!required, "DASH2SIM_REQUIRE_DATA=1 but {} does not exist", dir.display());
    eprintln!("SKIPPED: {} not found (set DASH2SIM_DATA to the shared data folder)", dir.display());
    None
}

/// Read a JSON file.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `n` footprint poses (rear axle) on `map` for comparing two drivable checks: every other
/// one near a lane — on a random segment or up to 20 % of a segment past its ends, heading its way ±0.5
/// rad, up to `across` metres to either side — and the rest anywhere in the lanes' box,
/// heading anywhere. Reproducible from `seed`.
pub fn footprints(
    map: &dash2sim_core::map::MapView<'_>,
    n: usize,
    across: f64,
    seed: u64,
) -> Vec<dash2sim_core::obb::Pose2> {
    use dash2sim_core::obb::Pose2;
    use rand::{Rng, SeedableRng};
    let lanes: Vec<Vec<(f64, f64)>> =
        (0..map.header().lanes).filter_map(|i| map.lane(i)).map(|lane| lane.points().collect()).collect();
    let (lo, hi) = lanes.iter().flatten().fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
        ((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))
    });
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            if k % 2 == 0 {
                let centreline = &lanes[rng.random_range(0..lanes.len())];
                let s = rng.random_range(0..centreline.len().max(2) - 1);
                let (a, b) = (centreline[s], centreline[(s + 1).min(centreline.len() - 1)]);
                let t = rng.random_range(-0.2..1.2);
                let heading = (b.1 - a.1).atan2(b.0 - a.0) + rng.random_range(-0.5..0.5);
                let side = rng.random_range(-across..across);
                Pose2::new(
                    a.0 + t * (b.0 - a.0) - side * heading.sin(),
                    a.1 + t * (b.1 - a.1) + side * heading.cos(),
                    heading,
                )
            } else {
                Pose2::new(rng.random_range(lo.0..hi.0), rng.random_range(lo.1..hi.1), rng.random_range(-3.2..3.2))
            }
        })
        .collect()
}

/// How a drivable check's corners lie, added to `tally`: inside the drivable area (≤ 0),
/// outside it, and with nothing drivable within the search radius.
#[derive(Clone, Copy, Debug, Default)]
pub struct CornerTally {
    /// Corners inside.
    pub inside: usize,
    /// Corners outside, something drivable near.
    pub outside: usize,
    /// Corners with nothing drivable near.
    pub far: usize,
}

impl CornerTally {
    /// Count `corners` (distances to the drivable area, `None` for nothing near).
    pub fn add(&mut self, corners: &[Option<f64>; 4]) {
        for d in corners {
            match d {
                Some(d) if *d <= 0.0 => self.inside += 1,
                Some(_) => self.outside += 1,
                None => self.far += 1,
            }
        }
    }

    /// Whether each kind was seen more than `n` times (a comparison that covered every case).
    pub fn each_over(&self, n: usize) -> bool {
        self.inside > n && self.outside > n && self.far > n
    }
}

/// Relative difference |a − b| / max(|b|, tiny).
pub fn rel_diff(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}
