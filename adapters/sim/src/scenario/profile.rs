//! Sensor profiles: how far a generated drive's sensors are from ideal.
//!
//! A profile is a distribution, not a setting: each drive draws its own mount error,
//! receiver misjudgement, latencies, tyre scale and detector calibration from its seed
//! (a stream of its own), as a fleet of dashcams would differ from one car to the next.
//! What was drawn is written to `scenario.json` as the drive's truth; nothing on the
//! product's path reads it. `docs/scenario.md` gives every number and where it comes from.
//!
//! - `ideal`: the simulator as it was before profiles — VO orientation exact, scale and
//!   heading drifting linearly, the mount exactly as the device is told, every error model
//!   reporting its own σ. Kept to reproduce old figures; not a claim about any dashcam.
//! - `typical`: a consumer dashcam on a good day (the default).
//! - `hard`: a cheap one on a bad day.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::sensors::{GnssModel, MountError, WheelModel};
use super::vo::{Reinit, VoModel};
use super::ScenarioConfig;
use dash2sim_core::sim3::rotation_z;

/// How far the sensors are from ideal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// The kind simulator of old: exact VO orientation, linear drifts, exact mount, every
    /// reported σ the true one. For reproducing old figures only.
    Ideal,
    /// A consumer dashcam on a good day.
    #[default]
    Typical,
    /// A cheap dashcam on a bad day: frequent VO re-initialisation, GNSS outages, more
    /// multipath and misses.
    Hard,
}

impl Profile {
    /// Every profile, mildest first.
    pub const ALL: [Profile; 3] = [Profile::Ideal, Profile::Typical, Profile::Hard];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Ideal => "ideal",
            Profile::Typical => "typical",
            Profile::Hard => "hard",
        }
    }
}

/// Which GNSS receiver the generated drive has.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Receiver {
    /// A phone-grade receiver: σ 3–10 m wandering, multipath jumps ([`GnssModel::default`]).
    #[default]
    Phone,
    /// A good receiver: σ 1–2 m ([`GnssModel::good`]).
    Good,
}

impl Receiver {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Receiver::Phone => "phone",
            Receiver::Good => "good",
        }
    }

    /// The receiver's own error model, as the ideal profile uses it.
    pub fn model(self) -> GnssModel {
        match self {
            Receiver::Phone => GnssModel::default(),
            Receiver::Good => GnssModel::good(),
        }
    }
}

/// Street-imagery anchors as a place-recognition matcher gives them: the matched image's
/// geotag, off by `sigma_per_axis` east and north, and now and then a wrong match.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct StreetAnchorModel {
    /// Error σ per horizontal axis, m (the σ the anchors' file reports, too).
    pub sigma_per_axis: f64,
    /// Fraction of anchors that are wrong matches.
    pub outlier_rate: f64,
    /// How far a wrong match lies, m (uniform, in a uniform direction).
    pub outlier_m: (f64, f64),
}

impl Default for StreetAnchorModel {
    /// σ 0.3 m per axis (0.42 m horizontal RMS), no wrong matches.
    fn default() -> Self {
        StreetAnchorModel { sigma_per_axis: 0.3, outlier_rate: 0.0, outlier_m: (2.0, 10.0) }
    }
}

/// The stream of the per-drive draws (the generator's sensor streams are 1–5).
const PROFILE_STREAM: u64 = 6;

fn log_uniform(rng: &mut impl Rng, (lo, hi): (f64, f64)) -> f64 {
    (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp()
}

fn symmetric(rng: &mut impl Rng, half_width: f64) -> f64 {
    rng.random_range(-half_width..=half_width)
}

impl ScenarioConfig {
    /// Drive `seed` with `receiver` under `profile`: the profile's per-drive values drawn
    /// from the seed, every other setting the default's.
    pub fn drive(seed: u64, profile: Profile, receiver: Receiver) -> Self {
        let base = ScenarioConfig { seed, profile, receiver, gnss: receiver.model(), ..ScenarioConfig::default() };
        if profile == Profile::Ideal {
            return base;
        }
        let hard = profile == Profile::Hard;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(PROFILE_STREAM);
        let rng = &mut rng;
        let vo = VoModel {
            scale: log_uniform(rng, (1.0, 10.0)),
            rotation: rotation_z(rng.random_range(-std::f64::consts::PI..std::f64::consts::PI)),
            scale_drift_per_min: 0.0,
            yaw_drift_deg_per_min: 0.0,
            scale_walk_per_sqrt_min: if hard { 0.03 } else { 0.01 },
            yaw_walk_deg_per_sqrt_min: if hard { 3.0 } else { 1.0 },
            tilt_deg: if hard { 1.0 } else { 0.3 },
            translation_noise: if hard { 0.02 } else { 0.01 },
            rotation_noise_deg: if hard { 0.3 } else { 0.1 },
            reinit: Some(Reinit {
                every_s: if hard { (30.0, 60.0) } else { (120.0, 300.0) },
                gap_s: (0.5, 2.0),
                scale_factor: (0.5, 2.0),
            }),
        };
        let mount_deg = if hard { 6.0 } else { 3.0 };
        let mount_error = MountError {
            yaw: symmetric(rng, mount_deg).to_radians(),
            pitch: symmetric(rng, mount_deg).to_radians(),
            offset: [symmetric(rng, 0.1), symmetric(rng, 0.1), symmetric(rng, 0.1)],
        };
        let gnss = GnssModel {
            correlation_s: log_uniform(rng, (1.0, 30.0)),
            latency_s: rng.random_range(0.0..0.25),
            multipath_rate: if hard { 0.05 } else { 0.01 },
            reported_sigma_factor: log_uniform(rng, (0.5, 2.0)),
            reported_jitter: if hard { 0.4 } else { 0.2 },
            outages_per_min: if hard { 0.5 } else { 0.0 },
            ..receiver.model()
        };
        let wheel =
            WheelModel { scale: rng.random_range(0.97..1.03), latency_s: rng.random_range(0.0..0.1), sigma: 0.03 };
        let detector = super::sensors::DetectorModel {
            covariance_factor: log_uniform(rng, (0.5, 2.0)),
            confusion: if hard { 0.08 } else { 0.03 },
            occlusion: true,
            false_positives: if hard { 1.0 } else { 0.4 },
            ..base.detector
        };
        let anchors =
            StreetAnchorModel { outlier_rate: if hard { 0.10 } else { 0.05 }, ..StreetAnchorModel::default() };
        // Drawn last, so that the draws above stay what they were before the IMU.
        let imu = super::imu::ImuModel::draw(rng, hard);
        ScenarioConfig {
            vo,
            imu,
            camera: super::sensors::Camera { mount_error, ..base.camera },
            gnss,
            wheel,
            detector,
            anchors,
            ..base
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ideal_profile_is_the_default_configuration() {
        let ideal = ScenarioConfig::drive(4, Profile::Ideal, Receiver::Phone);
        assert_eq!(ideal, ScenarioConfig { seed: 4, ..ScenarioConfig::default() });
        let good = ScenarioConfig::drive(4, Profile::Ideal, Receiver::Good);
        assert_eq!(good.gnss, GnssModel::good());
    }

    #[test]
    fn per_drive_values_are_drawn_within_their_ranges_and_differ_between_drives() {
        let drives: Vec<ScenarioConfig> =
            (1..=200).map(|seed| ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good)).collect();
        for c in &drives {
            let e = c.camera.mount_error;
            assert!(e.yaw.to_degrees().abs() <= 3.0 && e.pitch.to_degrees().abs() <= 3.0, "{e:?}");
            assert!(e.offset.iter().all(|o| o.abs() <= 0.1));
            assert!((0.5..=2.0).contains(&c.gnss.reported_sigma_factor));
            assert!((1.0..=30.0).contains(&c.gnss.correlation_s));
            assert!((0.0..0.25).contains(&c.gnss.latency_s));
            assert!((0.97..1.03).contains(&c.wheel.scale) && (0.0..0.1).contains(&c.wheel.latency_s));
            assert!((0.5..=2.0).contains(&c.detector.covariance_factor));
            assert_eq!(c.gnss.sigma_range, GnssModel::good().sigma_range, "the receiver keeps its σ");
        }
        // Spread over the range, not stuck at one value: a quarter of the drives in each
        // outer third of the mount's yaw range.
        let far_left = drives.iter().filter(|c| c.camera.mount_error.yaw.to_degrees() < -1.0).count();
        let far_right = drives.iter().filter(|c| c.camera.mount_error.yaw.to_degrees() > 1.0).count();
        assert!(far_left > 50 && far_right > 50, "{far_left} / {far_right}");
        let factors: Vec<f64> = drives.iter().map(|c| c.gnss.reported_sigma_factor).collect();
        assert!(factors.iter().any(|f| *f < 0.7) && factors.iter().any(|f| *f > 1.4));
        let hard = ScenarioConfig::drive(1, Profile::Hard, Receiver::Phone);
        assert!(hard.gnss.outages_per_min > 0.0 && hard.gnss.multipath_rate == 0.05);
    }
}
