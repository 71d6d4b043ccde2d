//! What `dash2sim scenario generate`, `eval`, `publish` and `sweep` check of a drive's length.

use super::profile::{Profile, Receiver};
use super::ScenarioConfig;
use crate::{Error, Field, Result};

/// Longest drive, seconds: ten minutes, on a road of 12 sections (13.8 km, a work zone in
/// each).
pub const MAX_DURATION_S: f64 = 600.0;

/// The drive `seed` of `duration_s` seconds under `profile` with `receiver`, or why not.
pub fn config(seed: u64, duration_s: f64, profile: Profile, receiver: Receiver) -> Result<ScenarioConfig> {
    if !(duration_s.is_finite() && (1.0..=MAX_DURATION_S).contains(&duration_s)) {
        return Err(Error::request(
            Field::Duration,
            format!("{duration_s} s must be between 1 and {MAX_DURATION_S} seconds"),
        ));
    }
    Ok(ScenarioConfig { duration_s, ..ScenarioConfig::drive(seed, profile, receiver) })
}
