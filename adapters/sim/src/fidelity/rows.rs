//! What a sweep is asked and what it gives back for each drive: the request, each drive's
//! row with its verdicts, and what the row takes from the drive besides its assessment.
//! The runner ([`super::sweep`]), the statistics ([`super::summary`]) and the picture
//! ([`super::plot`]) all read these; none of them is read here.

use std::ops::RangeInclusive;
use std::path::PathBuf;

use dash2sim_core::pipeline::RelativeMotion;
use serde::Serialize;

use super::drive::{Anchors, Assessment, WindowPair};
use crate::scenario::profile::{Profile, Receiver};
use crate::scenario::{Driver, Drivers};
use crate::{Error, Result};
use dash2sim_verify::decide::{decision_or_point, Decision, DoubtSettings};
use dash2sim_verify::VerifyReport;

/// A sweep (`dash2sim scenario sweep`).
#[derive(Debug, Clone)]
pub struct SweepRequest {
    /// Seeds, both ends included ([`parse_seeds`] reads `A-B` or `A`).
    pub seeds: RangeInclusive<u64>,
    /// Drive each seed careful, careless or both.
    pub driver: Drivers,
    /// How far the sensors are from ideal.
    pub profile: Profile,
    /// The GNSS receiver.
    pub receiver: Receiver,
    /// Finishing's anchors: street (simulated from the true path every 50 m) or none.
    pub anchors: Anchors,
    /// Hand finishing the receiver's true latency instead of letting it estimate one: an
    /// oracle that bounds what a better latency estimate could gain. Its figures are a
    /// bound, never the product's (the summary says so).
    pub oracle_latency: bool,
    /// Where the device's relative motion comes from: the camera's VO, or (a camera that
    /// publishes no VO at all) gyro + wheels dead reckoning; the drives' VO is then not
    /// recorded.
    pub relative_motion: RelativeMotion,
    /// How much doubt the logs' decisions allow (`--decide-at`, `--object-sigma`).
    pub doubt: DoubtSettings,
    /// Length of each drive, s.
    pub duration: f64,
    /// Drives run at once (default: one per core).
    pub jobs: Option<usize>,
    /// Output folder: runs.csv, runs.jsonl, summary.json, sweep.png.
    pub output: PathBuf,
    /// Keep each drive's files (generated streams, logs, anchors) under `OUTPUT/drives/`.
    pub keep: bool,
}

/// `A-B` or `A` as an inclusive range of seeds.
pub fn parse_seeds(text: &str) -> Result<RangeInclusive<u64>> {
    let number = |s: &str| -> Result<u64> {
        s.trim().parse().map_err(|_| Error::invalid(format!("`{s}` is not a seed (a whole number ≥ 0); give A-B or A")))
    };
    let (a, b) = match text.split_once('-') {
        Some((a, b)) => (number(a)?, number(b)?),
        None => {
            let a = number(text)?;
            (a, a)
        }
    };
    if a > b {
        return Err(Error::invalid(format!("{text}: the first seed is after the last (give A-B with A ≤ B)")));
    }
    Ok(a..=b)
}

/// One drive's verdict in one channel mode.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// nuPlan-style score, 0–100.
    pub score: f64,
    /// Score > 90.
    pub verified: bool,
    /// nuPlan's names of the metrics below 1.
    pub failed: Vec<String>,
    /// With the log's doubt (`verify --decide-at 2`): verified, rejected or undecided (the
    /// truth's, which has none, is its point verdict).
    pub decision: Decision,
    /// The score's interval within the doubt.
    pub score_interval: [f64; 2],
    /// Each metric that could flip within the doubt, in words.
    pub in_doubt: Vec<String>,
}

impl Verdict {
    fn of(report: &VerifyReport) -> Self {
        let failed =
            report.metrics.named().into_iter().filter(|(_, x)| *x < 1.0).map(|(name, _)| name.to_owned()).collect();
        let (decision, score_interval) = decision_or_point(report.decided.as_ref(), report.score);
        let in_doubt = report.decided.as_ref().map_or_else(Vec::new, |d| d.in_doubt.clone());
        Verdict { score: report.score, verified: report.verified, failed, decision, score_interval, in_doubt }
    }
}

/// A verdict in both channel modes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdicts {
    /// Every lane drivable (as the device verifies).
    pub insensitive: Verdict,
    /// Only the lanes along the route.
    pub sensitive: Verdict,
}

impl Verdicts {
    fn of(b: &super::drive::BothModes) -> Self {
        Verdicts { insensitive: Verdict::of(&b.insensitive), sensitive: Verdict::of(&b.sensitive) }
    }
}

/// What a drive came to: one row of the sweep.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Row {
    /// The drive's seed.
    pub seed: u64,
    /// `careful` or `careless`.
    pub driver: &'static str,
    /// Sensor profile.
    pub profile: &'static str,
    /// GNSS receiver.
    pub receiver: &'static str,
    /// Finishing's anchors.
    pub anchors: &'static str,
    /// Finishing was told the receiver's true latency (`--oracle-latency`): this row is a
    /// bound, not the product's.
    pub oracle_latency: bool,
    /// Why the drive did not come through the product (then nothing else is filled).
    pub error: Option<String>,
    /// The true drive's verification.
    pub truth: Option<Verdicts>,
    /// The device's log's (none when it never anchored: nothing verified).
    pub online: Option<Verdicts>,
    /// The finished log's.
    pub finished: Option<Verdicts>,
    /// The online ego verified against the true objects (its tracks set aside).
    pub online_ego_true_agents: Option<Verdicts>,
    /// The finished ego verified against the true objects.
    pub finished_ego_true_agents: Option<Verdicts>,
    /// Online horizontal ego APE (RMSE over anchored frames), m; none when never anchored.
    pub online_ape_m: Option<f64>,
    /// Finished ego APE (RMSE), m.
    pub finished_ape_m: Option<f64>,
    /// The same two as a user measures them: each pose at its UTC stamp against the truth
    /// at that instant, m.
    pub online_ape_utc_m: Option<f64>,
    /// See `online_ape_utc_m`.
    pub finished_ape_utc_m: Option<f64>,
    /// The device's log's UTC against the drive's (median over its frames), s.
    pub online_clock_error_s: Option<f64>,
    /// The finished log's, s.
    pub finished_clock_error_s: Option<f64>,
    /// Online scale error at the last observable estimate (relative); none without VO.
    pub online_scale_error: Option<f64>,
    /// Finished scale against the VO's mean true scale (relative); none without VO.
    pub finished_scale_error: Option<f64>,
    /// MOTA of the online 3D tracks against the truth.
    pub online_mota: Option<f64>,
    /// IDF1 of the online 3D tracks.
    pub online_idf1: Option<f64>,
    /// MOTA of the finished tracks.
    pub finished_mota: Option<f64>,
    /// IDF1 of the finished tracks.
    pub finished_idf1: Option<f64>,
    /// Seconds from the first frame to the device's first anchored pose.
    pub first_anchor_s: Option<f64>,
    /// VO sessions in the drive (1: no re-initialisation).
    pub vo_sessions: u32,
    /// The device's camera mount at the end of the drive against the true one: the larger
    /// of the yaw and pitch errors, degrees (none when it wrote no estimate).
    pub mount_error_deg: Option<f64>,
    /// The device called its mount calibrated by the end of the drive.
    pub mount_calibrated: bool,
    /// The finished mount's yaw against the true one, degrees: what its objects were placed
    /// with.
    pub finished_mount_yaw_error_deg: Option<f64>,
    /// The device's poses stating a σ, and those of them within 2σ of the truth.
    pub online_sigma_poses: usize,
    /// See `online_sigma_poses`.
    pub online_within_2sigma: usize,
    /// Mean horizontal NEES of the device's poses (2 when their σ is right).
    pub online_nees: Option<f64>,
    /// Finished poses stating a σ, and those of them within 2σ of the truth.
    pub finished_sigma_poses: usize,
    /// See `finished_sigma_poses`.
    pub finished_within_2sigma: usize,
    /// Mean horizontal NEES of the finished poses (2 when their σ is right).
    pub finished_nees: Option<f64>,
    /// `finish`'s GNSS latency against the receiver's true one, s.
    pub latency_error_s: Option<f64>,
    /// The device's (its last observable anchor estimate's) against the true one, s.
    pub online_latency_error_s: Option<f64>,
    /// The horizontal length of the fixes' mean error over the drive (weighted by their
    /// stated σ, multipath left out), m: about what an estimate resting on these fixes
    /// alone for its position can expect, since errors correlated for up to 30 s do not
    /// average out within a drive (judged; never shown to the estimators).
    pub gnss_mean_error_m: Option<f64>,
    /// `finish`'s wheel factor (true distance / odometer distance) against the true one
    /// (the inverse of the wheels' scale error), relative.
    pub wheel_factor_error: Option<f64>,
    /// The device's 15 s windows beside the truth's.
    pub windows: Vec<WindowPair>,
}

pub(super) fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl Row {
    pub(super) fn empty(seed: u64, driver: Driver, args: &SweepRequest) -> Self {
        Row {
            seed,
            driver: driver.name(),
            profile: args.profile.name(),
            receiver: args.receiver.name(),
            anchors: args.anchors.name(),
            oracle_latency: args.oracle_latency,
            error: None,
            truth: None,
            online: None,
            finished: None,
            online_ego_true_agents: None,
            finished_ego_true_agents: None,
            online_ape_m: None,
            finished_ape_m: None,
            online_ape_utc_m: None,
            finished_ape_utc_m: None,
            online_clock_error_s: None,
            finished_clock_error_s: None,
            online_scale_error: None,
            finished_scale_error: None,
            online_mota: None,
            online_idf1: None,
            finished_mota: None,
            finished_idf1: None,
            first_anchor_s: None,
            vo_sessions: 0,
            mount_error_deg: None,
            finished_mount_yaw_error_deg: None,
            mount_calibrated: false,
            online_sigma_poses: 0,
            online_within_2sigma: 0,
            online_nees: None,
            finished_sigma_poses: 0,
            finished_within_2sigma: 0,
            finished_nees: None,
            latency_error_s: None,
            online_latency_error_s: None,
            gnss_mean_error_m: None,
            wheel_factor_error: None,
            windows: Vec::new(),
        }
    }

    pub(super) fn with_assessment(mut self, a: &Assessment, facts: &DriveFacts) -> Self {
        let ape = |j: &crate::scenario::judge::LogJudgement| (!j.ego_errors.is_empty()).then_some(j.ego_rmse);
        self.truth = Some(Verdicts::of(&a.truth));
        self.online = a.online.verification.as_ref().map(Verdicts::of);
        self.finished = a.finished.verification.as_ref().map(Verdicts::of);
        self.online_ego_true_agents = a.online.ego_with_true_agents.as_ref().map(Verdicts::of);
        self.finished_ego_true_agents = a.finished.ego_with_true_agents.as_ref().map(Verdicts::of);
        self.online_ape_m = ape(&a.online.judgement);
        self.finished_ape_m = ape(&a.finished.judgement);
        self.online_ape_utc_m = finite(a.online.judgement.ego_rmse_utc);
        self.finished_ape_utc_m = finite(a.finished.judgement.ego_rmse_utc);
        self.online_clock_error_s = a.online.judgement.clock_error_s;
        self.finished_clock_error_s = a.finished.judgement.clock_error_s;
        // A scale is the VO's; a dead-reckoned path's is the wheels' (the wheel factor's row).
        if facts.vo_recorded {
            self.online_scale_error = a.online_scale.map(|(_, e)| e);
            self.finished_scale_error = finite(a.finished_scale.2);
        }
        self.online_mota = finite(a.online.judgement.tracks.0);
        self.online_idf1 = finite(a.online.judgement.tracks.1);
        self.finished_mota = finite(a.finished.judgement.tracks.0);
        self.finished_idf1 = finite(a.finished.judgement.tracks.1);
        self.first_anchor_s = a.online.judgement.first_anchored_s;
        self.vo_sessions = facts.vo_sessions;
        self.mount_error_deg = facts.mount_error_deg;
        self.mount_calibrated = facts.mount_calibrated;
        self.finished_mount_yaw_error_deg = facts.finished_mount_yaw_error_deg;
        let sigma = a.online.judgement.sigma;
        self.online_sigma_poses = sigma.poses;
        self.online_within_2sigma = sigma.within_2sigma;
        self.online_nees = finite(sigma.nees());
        let sigma = a.finished.judgement.sigma;
        self.finished_sigma_poses = sigma.poses;
        self.finished_within_2sigma = sigma.within_2sigma;
        self.finished_nees = finite(sigma.nees());
        let anchoring = &a.finish_report.anchoring;
        self.latency_error_s = finite(anchoring.gnss_latency_s).map(|l| l - facts.true_latency_s);
        self.online_latency_error_s = a.online_latency_s.map(|l| l - facts.true_latency_s);
        self.gnss_mean_error_m = facts.gnss_mean_error_m;
        self.wheel_factor_error = finite(anchoring.wheel_factor).map(|w| w * facts.true_wheel_scale - 1.0);
        self.windows = a.windows.clone();
        self
    }
}

/// What a drive's row takes from the scenario and the device's log besides the assessment.
pub(super) struct DriveFacts {
    pub(super) vo_sessions: u32,
    /// The camera's VO was recorded (not `--relative-motion imu-wheels`).
    pub(super) vo_recorded: bool,
    pub(super) mount_error_deg: Option<f64>,
    pub(super) mount_calibrated: bool,
    pub(super) finished_mount_yaw_error_deg: Option<f64>,
    /// The receiver's latency and the wheels' scale as the generator drew them (what the
    /// estimates are judged against; never shown to them).
    pub(super) true_latency_s: f64,
    pub(super) true_wheel_scale: f64,
    pub(super) gnss_mean_error_m: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_are_a_range_or_one_and_a_backward_range_is_refused() {
        assert_eq!(parse_seeds("3-7").ok(), Some(3..=7));
        assert_eq!(parse_seeds("12").ok(), Some(12..=12));
        let e = parse_seeds("5-2").expect_err("backwards").to_string();
        assert!(e.contains("first seed is after the last"), "{e}");
        assert!(parse_seeds("a-3").expect_err("not a number").to_string().contains("not a seed"));
        assert!(parse_seeds("-3").is_err());
    }
}
