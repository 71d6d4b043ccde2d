//! The statistics over a sweep's rows: how often each log's verdict equals the truth's
//! (confusion tables), the spread of the anchoring and tracking errors, and every
//! disagreement with its cause.

use std::fmt::Write as _;

use dash2sim_core::pipeline::RelativeMotion;
use serde::Serialize;

use super::rows::{Row, SweepRequest, Verdict, Verdicts};
use dash2sim_verify::decide::Decision;

/// A log's verdicts against the truth's: rows truth, columns the log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct Confusion {
    /// Both verified.
    pub truth_verified_log_verified: usize,
    /// The truth verified, the log rejected (a good drive thrown away).
    pub truth_verified_log_rejected: usize,
    /// The truth rejected, the log verified (a bad drive let through).
    pub truth_rejected_log_verified: usize,
    /// Both rejected.
    pub truth_rejected_log_rejected: usize,
}

impl Confusion {
    fn of(pairs: impl Iterator<Item = (bool, bool)>) -> Self {
        let mut c = Confusion::default();
        for (truth, log) in pairs {
            match (truth, log) {
                (true, true) => c.truth_verified_log_verified += 1,
                (true, false) => c.truth_verified_log_rejected += 1,
                (false, true) => c.truth_rejected_log_verified += 1,
                (false, false) => c.truth_rejected_log_rejected += 1,
            }
        }
        c
    }

    /// Pairs counted.
    pub fn total(&self) -> usize {
        self.truth_verified_log_verified
            + self.truth_verified_log_rejected
            + self.truth_rejected_log_verified
            + self.truth_rejected_log_rejected
    }

    /// Fraction of pairs that agree (none without pairs).
    pub fn agreement(&self) -> Option<f64> {
        self.agreement_with_failed(0)
    }

    /// Fraction of the pairs and `failed` drives that agree: a drive that did not come
    /// through the product agrees with nothing.
    pub fn agreement_with_failed(&self, failed: usize) -> Option<f64> {
        let n = self.total() + failed;
        (n > 0).then(|| (self.truth_verified_log_verified + self.truth_rejected_log_rejected) as f64 / n as f64)
    }
}

/// The log's decisions (with the doubt of its stated σ) for the drives of one truth verdict.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct DecisionRow {
    /// Verified anywhere within the doubt.
    pub verified: usize,
    /// Rejected anywhere within it.
    pub rejected: usize,
    /// Neither.
    pub undecided: usize,
}

/// The log's decisions against the truth's verdicts, 2 × 3, and the drives that did not
/// come through the product.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct DecisionTable {
    /// The drives the truth verifies.
    pub truth_verified: DecisionRow,
    /// The drives the truth rejects.
    pub truth_rejected: DecisionRow,
    /// Drives that did not come through the product (no log, no decision).
    pub failed: usize,
}

impl DecisionTable {
    fn add(&mut self, truth_verified: bool, log: Decision) {
        let row = if truth_verified { &mut self.truth_verified } else { &mut self.truth_rejected };
        match log {
            Decision::Verified => row.verified += 1,
            Decision::Rejected => row.rejected += 1,
            Decision::Undecided => row.undecided += 1,
        }
    }

    /// Every drive, failed ones included.
    pub fn drives(&self) -> usize {
        let row = |r: &DecisionRow| r.verified + r.rejected + r.undecided;
        row(&self.truth_verified) + row(&self.truth_rejected) + self.failed
    }

    /// Decided verdicts that differ from the truth's.
    pub fn wrong_decided(&self) -> usize {
        self.truth_verified.rejected + self.truth_rejected.verified
    }

    /// Decided verdicts.
    pub fn decided(&self) -> usize {
        self.truth_verified.verified
            + self.truth_verified.rejected
            + self.truth_rejected.verified
            + self.truth_rejected.rejected
    }

    /// Undecided drives.
    pub fn undecided(&self) -> usize {
        self.truth_verified.undecided + self.truth_rejected.undecided
    }

    /// Of the decided verdicts, the fraction equal to the truth's (none without any).
    pub fn agreement_among_decided(&self) -> Option<f64> {
        let decided = self.decided();
        (decided > 0).then(|| (decided - self.wrong_decided()) as f64 / decided as f64)
    }

    /// Undecided drives of all the drives (failed ones count in the denominator).
    pub fn undecided_rate(&self) -> Option<f64> {
        let drives = self.drives();
        (drives > 0).then(|| self.undecided() as f64 / drives as f64)
    }
}

/// Percentiles of a figure over the drives that have it (linear between ranks, as numpy's
/// default).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Spread {
    /// Drives with a value.
    pub n: usize,
    /// 5th percentile.
    pub p5: Option<f64>,
    /// Median.
    pub p50: Option<f64>,
    /// 90th percentile.
    pub p90: Option<f64>,
    /// 95th percentile.
    pub p95: Option<f64>,
    /// Largest.
    pub max: Option<f64>,
}

/// The `q`-quantile (0–1) of sorted `values`, linear between ranks.
pub fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    let last = sorted.len().checked_sub(1)?;
    let at = q.clamp(0.0, 1.0) * last as f64;
    let (lo, hi) = (at.floor() as usize, at.ceil() as usize);
    Some(sorted[lo] + (sorted[hi] - sorted[lo]) * (at - lo as f64))
}

impl Spread {
    fn of(values: impl Iterator<Item = Option<f64>>) -> Self {
        let mut v: Vec<f64> = values.flatten().filter(|x| x.is_finite()).collect();
        v.sort_by(f64::total_cmp);
        Spread {
            n: v.len(),
            p5: quantile(&v, 0.05),
            p50: quantile(&v, 0.5),
            p90: quantile(&v, 0.9),
            p95: quantile(&v, 0.95),
            max: v.last().copied(),
        }
    }
}

/// The confusion tables of a sweep.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Confusions {
    /// The finished log against the truth, channel-insensitive.
    pub finished: Confusion,
    /// The same, channel-sensitive.
    pub finished_channel_sensitive: Confusion,
    /// The online log (the whole drive) against the truth, channel-insensitive.
    pub online: Confusion,
    /// The device's 15 s windows against the truth's over the same stretches.
    pub device_windows: Confusion,
}

/// The spreads of a sweep's figures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Spreads {
    /// Online ego APE (RMSE per drive), m.
    pub ape_online_m: Spread,
    /// Finished ego APE, m.
    pub ape_finished_m: Spread,
    /// The finished ego APE with its UTC stamps against the truth's UTC, m.
    pub ape_finished_utc_m: Spread,
    /// |the device's log's UTC − the drive's|, s.
    pub clock_error_online_abs_s: Spread,
    /// |the finished log's UTC − the drive's|, s.
    pub clock_error_finished_abs_s: Spread,
    /// |online scale error| at the last observable estimate.
    pub scale_error_online_abs: Spread,
    /// |finished scale error|.
    pub scale_error_finished_abs: Spread,
    /// MOTA of the online tracks.
    pub mota_online: Spread,
    /// MOTA of the finished tracks.
    pub mota_finished: Spread,
    /// IDF1 of the finished tracks.
    pub idf1_finished: Spread,
    /// Seconds to the device's first anchored pose.
    pub first_anchor_s: Spread,
    /// The device's mount error at the end of the drive (the larger of yaw and pitch), °.
    pub mount_error_deg: Spread,
    /// The finished mount's yaw error, °.
    pub finished_mount_yaw_error_deg: Spread,
    /// Mean NEES of each drive's device poses (2 when their σ is right).
    pub nees_online: Spread,
    /// Mean NEES of each drive's finished poses (2 when their σ is right).
    pub nees_finished: Spread,
    /// |finished GNSS latency − the receiver's true latency|, s.
    pub latency_error_finished_abs_s: Spread,
    /// |the device's GNSS latency − the receiver's true latency|, s.
    pub latency_error_online_abs_s: Spread,
    /// The horizontal length of each drive's mean GNSS error, m (see the row's field).
    pub gnss_mean_error_m: Spread,
    /// |finished wheel factor / the true one − 1|.
    pub wheel_factor_error_finished_abs: Spread,
}

/// Issue #31's target for the calibrated mount: yaw and pitch within this of the truth, °.
pub const MOUNT_TARGET_DEG: f64 = 0.5;

/// A drive whose finished verdict differs from the truth's, and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Disagreement {
    /// Seed.
    pub seed: u64,
    /// Driver.
    pub driver: &'static str,
    /// The truth's score and the finished log's (channel-insensitive).
    pub truth_score: f64,
    /// See `truth_score`.
    pub finished_score: f64,
    /// Metrics below 1 for the finished log and not for the truth, or the reverse.
    pub metrics: Vec<String>,
    /// `agents` (the finished ego against the true objects verifies as the truth does: the
    /// tracks made the difference), `ego` (it does not), `map` (the truth itself leaves
    /// the map's drivable area or direction: the map and the road disagree), or `failed`
    /// (the drive did not come through the product; `metrics` holds why).
    pub cause: &'static str,
}

/// A finished log without an ego: nothing verified, nothing decided.
fn no_ego() -> Verdict {
    Verdict {
        score: 0.0,
        verified: false,
        failed: vec!["no ego poses".to_owned()],
        decision: Decision::Undecided,
        score_interval: [0.0, 100.0],
        in_doubt: vec!["the log has no ego poses".to_owned()],
    }
}

/// Metric names that only the map decides.
const MAP_METRICS: [&str; 2] = ["drivable_area_compliance", "driving_direction_compliance"];

fn disagreement(row: &Row) -> Option<Disagreement> {
    if let Some(why) = &row.error {
        return Some(Disagreement {
            seed: row.seed,
            driver: row.driver,
            truth_score: f64::NAN,
            finished_score: f64::NAN,
            metrics: vec![why.clone()],
            cause: "failed",
        });
    }
    let truth = &row.truth.as_ref()?.insensitive;
    let nothing = no_ego();
    let finished = row.finished.as_ref().map_or(&nothing, |v| &v.insensitive);
    if truth.verified == finished.verified {
        return None;
    }
    let only =
        |a: &Verdict, b: &Verdict| a.failed.iter().filter(|m| !b.failed.contains(m)).cloned().collect::<Vec<_>>();
    let mut metrics = only(finished, truth);
    metrics.extend(only(truth, finished));
    let with_true_agents = row.finished_ego_true_agents.as_ref().map(|v| v.insensitive.verified);
    let cause = if truth.failed.iter().any(|m| MAP_METRICS.contains(&m.as_str())) && !truth.verified {
        "map"
    } else if with_true_agents == Some(truth.verified) {
        "agents"
    } else {
        "ego"
    };
    Some(Disagreement {
        seed: row.seed,
        driver: row.driver,
        truth_score: truth.score,
        finished_score: finished.score,
        metrics,
        cause,
    })
}

/// A sweep's summary (`summary.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Sensor profile.
    pub profile: &'static str,
    /// GNSS receiver.
    pub receiver: &'static str,
    /// Finishing's anchors.
    pub anchors: &'static str,
    /// Finishing was told the receiver's true latency (`--oracle-latency`): the figures
    /// are a bound, not the product's.
    pub oracle_latency: bool,
    /// The device's relative motion: `vo`, or `imu-wheels` (the camera published no VO).
    pub relative_motion: &'static str,
    /// Seeds, `A-B`.
    pub seeds: String,
    /// Drivers.
    pub drivers: Vec<&'static str>,
    /// Length of each drive, s.
    pub duration_s: f64,
    /// Drives run.
    pub drives: usize,
    /// Drives that did not come through the product (their rows say why).
    pub failed_drives: usize,
    /// Fraction of drives whose finished verdict equals the truth's (channel-insensitive);
    /// a failed drive counts as a disagreement, as in every rate over drives.
    pub finished_agreement: Option<f64>,
    /// The same, channel-sensitive.
    pub finished_agreement_channel_sensitive: Option<f64>,
    /// Drives the truth rejects and the finished log verifies (channel-insensitive).
    pub finished_false_verified: usize,
    /// Drives the truth verifies and the finished log rejects.
    pub finished_false_rejected: usize,
    /// Fraction of drives whose online verdict (the whole drive) equals the truth's.
    pub online_agreement: Option<f64>,
    /// Fraction of the device's windows whose verdict equals the truth's over the same stretch.
    pub online_window_agreement: Option<f64>,
    /// The device's windows judged.
    pub windows: usize,
    /// The drive time the device's windows cover, of all the drives' time (a failed
    /// drive's included): a window the device never produced is time no verdict speaks for.
    pub device_window_coverage: Option<f64>,
    /// Device windows verified where the truth has an at-fault collision.
    pub device_verified_collision_windows: usize,
    /// The device's window decisions with the ego's doubt against the truth's verdicts over
    /// the same stretches (windows the device did not decide are left out).
    pub device_window_decisions: DecisionTable,
    /// Of the device's decided windows, the fraction equal to the truth's.
    pub device_window_agreement_among_decided: Option<f64>,
    /// The device's windows undecided, of its decided and undecided ones.
    pub device_window_undecided_rate: Option<f64>,
    /// Device windows decided verified where the truth collides or leaves the drivable
    /// area.
    pub device_decided_verified_off_road_or_collision: usize,
    /// Median finished APE, m.
    pub ape_finished_median_m: Option<f64>,
    /// Drives the device never anchored.
    pub never_anchored: usize,
    /// Drives whose VO re-initialised at least once.
    pub drives_with_vo_reinit: usize,
    /// Fraction of drives whose device ended with its camera mount within
    /// [`MOUNT_TARGET_DEG`] of the truth in yaw and pitch (none: no mount estimates).
    pub mount_within_half_degree: Option<f64>,
    /// Drives whose device called its mount calibrated.
    pub mount_calibrated: usize,
    /// Of all the device's poses stating a σ (over every drive), the fraction within 2σ
    /// of the truth (issue #31's target: ≥ 90 %).
    pub online_within_2sigma: Option<f64>,
    /// The device's poses stating a σ.
    pub online_sigma_poses: usize,
    /// The same for the finished poses.
    pub finished_within_2sigma: Option<f64>,
    /// The finished poses stating a σ.
    pub finished_sigma_poses: usize,
    /// The finished logs' decisions with their doubt (`verify --decide-at 2`,
    /// channel-insensitive) against the truth's verdicts, over every drive.
    pub finished_decisions: DecisionTable,
    /// The same per driver kind, in the order of `drivers`.
    pub finished_decisions_by_driver: Vec<(&'static str, DecisionTable)>,
    /// Finished decided verdicts that differ from the truth's.
    pub wrong_decided: usize,
    /// Finished logs undecided, of all the drives (failed ones included).
    pub undecided_rate: Option<f64>,
    /// Of the finished decided verdicts, the fraction equal to the truth's.
    pub agreement_among_decided: Option<f64>,
    /// The confusion tables.
    pub confusion: Confusions,
    /// The spreads of the figures.
    pub spread: Spreads,
    /// Every finished verdict that differs from the truth's, with its cause.
    pub disagreements: Vec<Disagreement>,
}

/// The truth's verdict and the finished log's (a finished log without an ego verifies nothing).
fn verdict_pair(row: &Row, mode: impl Fn(&Verdicts) -> &Verdict) -> Option<(bool, bool)> {
    Some((mode(row.truth.as_ref()?).verified, row.finished.as_ref().is_some_and(|v| mode(v).verified)))
}

impl Summary {
    /// The summary of `rows`, run as `args` says.
    pub fn of(args: &SweepRequest, rows: &[Row]) -> Self {
        let ok: Vec<&Row> = rows.iter().filter(|r| r.error.is_none()).collect();
        let failed = rows.len() - ok.len();
        let finished = Confusion::of(ok.iter().filter_map(|r| verdict_pair(r, |v| &v.insensitive)));
        let finished_cs = Confusion::of(ok.iter().filter_map(|r| verdict_pair(r, |v| &v.sensitive)));
        // A device that never anchored verified nothing.
        let online = Confusion::of(ok.iter().filter_map(|r| {
            Some((r.truth.as_ref()?.insensitive.verified, r.online.as_ref().is_some_and(|v| v.insensitive.verified)))
        }));
        let device_windows =
            Confusion::of(ok.iter().flat_map(|r| r.windows.iter().map(|w| (w.truth_verified, w.device_verified))));
        let mut device_window_decisions = DecisionTable::default();
        for w in ok.iter().flat_map(|r| &r.windows) {
            if let Some(decision) = w.device_decision {
                device_window_decisions.add(w.truth_verified, decision);
            }
        }
        let abs = |x: Option<f64>| x.map(f64::abs);
        let spread = Spreads {
            ape_online_m: Spread::of(ok.iter().map(|r| r.online_ape_m)),
            ape_finished_m: Spread::of(ok.iter().map(|r| r.finished_ape_m)),
            ape_finished_utc_m: Spread::of(ok.iter().map(|r| r.finished_ape_utc_m)),
            clock_error_online_abs_s: Spread::of(ok.iter().map(|r| abs(r.online_clock_error_s))),
            clock_error_finished_abs_s: Spread::of(ok.iter().map(|r| abs(r.finished_clock_error_s))),
            scale_error_online_abs: Spread::of(ok.iter().map(|r| abs(r.online_scale_error))),
            scale_error_finished_abs: Spread::of(ok.iter().map(|r| abs(r.finished_scale_error))),
            mota_online: Spread::of(ok.iter().map(|r| r.online_mota)),
            mota_finished: Spread::of(ok.iter().map(|r| r.finished_mota)),
            idf1_finished: Spread::of(ok.iter().map(|r| r.finished_idf1)),
            first_anchor_s: Spread::of(ok.iter().map(|r| r.first_anchor_s)),
            mount_error_deg: Spread::of(ok.iter().map(|r| r.mount_error_deg)),
            finished_mount_yaw_error_deg: Spread::of(ok.iter().map(|r| r.finished_mount_yaw_error_deg)),
            nees_online: Spread::of(ok.iter().map(|r| r.online_nees)),
            nees_finished: Spread::of(ok.iter().map(|r| r.finished_nees)),
            latency_error_finished_abs_s: Spread::of(ok.iter().map(|r| abs(r.latency_error_s))),
            latency_error_online_abs_s: Spread::of(ok.iter().map(|r| abs(r.online_latency_error_s))),
            gnss_mean_error_m: Spread::of(ok.iter().map(|r| r.gnss_mean_error_m)),
            wheel_factor_error_finished_abs: Spread::of(ok.iter().map(|r| abs(r.wheel_factor_error))),
        };
        let drivers: Vec<&'static str> = rows.iter().map(|r| r.driver).fold(Vec::new(), |mut v, d| {
            if !v.contains(&d) {
                v.push(d);
            }
            v
        });
        let decisions = |driver: Option<&str>| {
            let mut table = DecisionTable::default();
            for row in rows.iter().filter(|r| driver.is_none_or(|d| d == r.driver)) {
                match (&row.error, &row.truth) {
                    (None, Some(truth)) => {
                        let finished = row.finished.as_ref().map_or_else(no_ego, |v| v.insensitive.clone());
                        table.add(truth.insensitive.verified, finished.decision);
                    }
                    _ => table.failed += 1,
                }
            }
            table
        };
        let finished_decisions = decisions(None);
        let with_mount = ok.iter().filter(|r| r.mount_error_deg.is_some()).count();
        let coverage = |poses: fn(&Row) -> usize, within: fn(&Row) -> usize| {
            let poses: usize = ok.iter().map(|r| poses(r)).sum();
            let within: usize = ok.iter().map(|r| within(r)).sum();
            ((poses > 0).then(|| within as f64 / poses as f64), poses)
        };
        let (online_within_2sigma, online_sigma_poses) = coverage(|r| r.online_sigma_poses, |r| r.online_within_2sigma);
        let (finished_within_2sigma, finished_sigma_poses) =
            coverage(|r| r.finished_sigma_poses, |r| r.finished_within_2sigma);
        let within = ok.iter().filter(|r| r.mount_error_deg.is_some_and(|e| e <= MOUNT_TARGET_DEG)).count();
        Summary {
            profile: args.profile.name(),
            receiver: args.receiver.name(),
            anchors: args.anchors.name(),
            oracle_latency: args.oracle_latency,
            relative_motion: match args.relative_motion {
                RelativeMotion::Vo => "vo",
                RelativeMotion::ImuWheels => "imu-wheels",
            },
            seeds: format!("{}-{}", args.seeds.start(), args.seeds.end()),
            finished_decisions_by_driver: drivers.iter().map(|d| (*d, decisions(Some(d)))).collect(),
            drivers,
            wrong_decided: finished_decisions.wrong_decided(),
            undecided_rate: finished_decisions.undecided_rate(),
            agreement_among_decided: finished_decisions.agreement_among_decided(),
            finished_decisions,
            duration_s: args.duration,
            drives: rows.len(),
            failed_drives: failed,
            finished_agreement: finished.agreement_with_failed(failed),
            finished_agreement_channel_sensitive: finished_cs.agreement_with_failed(failed),
            finished_false_verified: finished.truth_rejected_log_verified,
            finished_false_rejected: finished.truth_verified_log_rejected,
            online_agreement: online.agreement_with_failed(failed),
            online_window_agreement: device_windows.agreement(),
            windows: device_windows.total(),
            device_window_coverage: {
                let covered: f64 = ok.iter().flat_map(|r| &r.windows).map(|w| (w.end_s - w.start_s).max(0.0)).sum();
                let total = rows.len() as f64 * args.duration;
                (total > 0.0).then(|| covered / total)
            },
            device_verified_collision_windows: ok
                .iter()
                .flat_map(|r| &r.windows)
                .filter(|w| w.truth_collision && w.device_verified)
                .count(),
            device_window_agreement_among_decided: device_window_decisions.agreement_among_decided(),
            device_window_undecided_rate: device_window_decisions.undecided_rate(),
            device_decided_verified_off_road_or_collision: ok
                .iter()
                .flat_map(|r| &r.windows)
                .filter(|w| {
                    w.device_decision == Some(Decision::Verified)
                        && (w.truth_collision || w.truth_failed.contains(&"drivable_area_compliance"))
                })
                .count(),
            device_window_decisions,
            ape_finished_median_m: spread.ape_finished_m.p50,
            never_anchored: ok.iter().filter(|r| r.first_anchor_s.is_none()).count(),
            drives_with_vo_reinit: ok.iter().filter(|r| r.vo_sessions > 1).count(),
            mount_within_half_degree: (with_mount > 0).then(|| within as f64 / ok.len() as f64),
            mount_calibrated: ok.iter().filter(|r| r.mount_calibrated).count(),
            online_within_2sigma,
            online_sigma_poses,
            finished_within_2sigma,
            finished_sigma_poses,
            confusion: Confusions { finished, finished_channel_sensitive: finished_cs, online, device_windows },
            spread,
            disagreements: rows.iter().filter_map(disagreement).collect(),
        }
    }

    /// The summary as a person reads it.
    pub fn text(&self) -> String {
        let mut t = String::new();
        let pct = |x: Option<f64>| x.map_or_else(|| "–".to_owned(), |v| format!("{:.1} %", 100.0 * v));
        let m = |x: Option<f64>| x.map_or_else(|| "–".to_owned(), |v| format!("{v:.2}"));
        let _ = writeln!(
            t,
            "dash2sim scenario sweep — seeds {}, {} driver(s), {} profile, {} receiver, {} anchors, {:.0} s drives (simulated)",
            self.seeds,
            self.drivers.join("+"),
            self.profile,
            self.receiver,
            self.anchors,
            self.duration_s
        );
        if self.oracle_latency {
            let _ = writeln!(
                t,
                "  ORACLE: finishing was told each receiver's true latency; these figures bound what estimating it could gain, they are not the product's"
            );
        }
        if self.relative_motion == "imu-wheels" {
            let _ =
                writeln!(t, "  NO VO: the camera published none; the relative motion is gyro + wheels dead reckoning");
        }
        let _ = writeln!(
            t,
            "  drives        {} ({} failed to run, {} never anchored on the device, {} with a VO re-initialisation)",
            self.drives, self.failed_drives, self.never_anchored, self.drives_with_vo_reinit
        );
        let table = |t: &mut String, name: &str, c: &Confusion| {
            let _ = writeln!(t, "  {name:<40} log verified  log rejected   agreement {}", pct(c.agreement()));
            let _ = writeln!(
                t,
                "  {:<40} {:>12}  {:>12}",
                "    truth verified", c.truth_verified_log_verified, c.truth_verified_log_rejected
            );
            let _ = writeln!(
                t,
                "  {:<40} {:>12}  {:>12}",
                "    truth rejected", c.truth_rejected_log_verified, c.truth_rejected_log_rejected
            );
        };
        table(&mut t, "finished vs truth (channel-insensitive)", &self.confusion.finished);
        table(&mut t, "finished vs truth (channel-sensitive)", &self.confusion.finished_channel_sensitive);
        table(&mut t, "online (whole drive) vs truth", &self.confusion.online);
        table(&mut t, "device windows vs truth's windows", &self.confusion.device_windows);
        let _ = writeln!(
            t,
            "  device windows cover {} of the drives' time; verified where the truth collides: {}",
            pct(self.device_window_coverage),
            self.device_verified_collision_windows
        );
        let d = &self.device_window_decisions;
        let _ = writeln!(
            t,
            "  device window decisions with its doubt   verified  rejected  undecided   (agreement among decided {}, undecided {}, verified where the truth collides or leaves the road {})",
            pct(self.device_window_agreement_among_decided),
            pct(self.device_window_undecided_rate),
            self.device_decided_verified_off_road_or_collision
        );
        for (truth, row) in [("truth verifies", &d.truth_verified), ("truth rejects", &d.truth_rejected)] {
            let _ = writeln!(t, "    {truth:<36} {:>8}  {:>8}  {:>9}", row.verified, row.rejected, row.undecided);
        }
        let _ = writeln!(
            t,
            "  finished decisions with 2σ of doubt   verified  rejected  undecided  failed   (wrong decided {}, undecided {}, agreement among decided {})",
            self.wrong_decided,
            pct(self.undecided_rate),
            pct(self.agreement_among_decided)
        );
        for (driver, d) in &self.finished_decisions_by_driver {
            for (truth, row) in [("verifies", &d.truth_verified), ("rejects", &d.truth_rejected)] {
                if row.verified + row.rejected + row.undecided > 0 {
                    let name = format!("{driver}, truth {truth}");
                    let _ =
                        writeln!(t, "    {name:<36} {:>8}  {:>8}  {:>9}", row.verified, row.rejected, row.undecided);
                }
            }
            if d.failed > 0 {
                let _ = writeln!(
                    t,
                    "    {:<36} {:>8}  {:>8}  {:>9}  {:>6}",
                    format!("{driver}, failed"),
                    "",
                    "",
                    "",
                    d.failed
                );
            }
        }
        let spread = |t: &mut String, name: &str, s: &Spread, scale: f64, unit: &str| {
            let f = |x: Option<f64>| x.map_or_else(|| "–".to_owned(), |v| format!("{:.3}", v * scale));
            let _ = writeln!(
                t,
                "  {name:<28} median {} {unit}, 90 % {}, 95 % {}, max {} (n = {})",
                f(s.p50),
                f(s.p90),
                f(s.p95),
                f(s.max),
                s.n
            );
        };
        let s = &self.spread;
        spread(&mut t, "APE online", &s.ape_online_m, 1.0, "m");
        spread(&mut t, "APE finished", &s.ape_finished_m, 1.0, "m");
        spread(&mut t, "APE finished by UTC", &s.ape_finished_utc_m, 1.0, "m");
        spread(&mut t, "|log clock error| device", &s.clock_error_online_abs_s, 1000.0, "ms");
        spread(&mut t, "|log clock error| finished", &s.clock_error_finished_abs_s, 1000.0, "ms");
        spread(&mut t, "|scale error| online", &s.scale_error_online_abs, 100.0, "%");
        spread(&mut t, "|scale error| finished", &s.scale_error_finished_abs, 100.0, "%");
        spread(&mut t, "MOTA online", &s.mota_online, 1.0, "");
        spread(&mut t, "MOTA finished", &s.mota_finished, 1.0, "");
        spread(&mut t, "first anchored after", &s.first_anchor_s, 1.0, "s");
        spread(&mut t, "mount error (device, end)", &s.mount_error_deg, 1.0, "°");
        spread(&mut t, "mount yaw error (finished)", &s.finished_mount_yaw_error_deg, 1.0, "°");
        spread(&mut t, "NEES device (2: σ right)", &s.nees_online, 1.0, "");
        spread(&mut t, "NEES finished (2: σ right)", &s.nees_finished, 1.0, "");
        spread(&mut t, "|GNSS latency error| device", &s.latency_error_online_abs_s, 1000.0, "ms");
        spread(&mut t, "|GNSS latency error| finished", &s.latency_error_finished_abs_s, 1000.0, "ms");
        spread(&mut t, "fixes' weighted mean error", &s.gnss_mean_error_m, 1.0, "m");
        spread(&mut t, "|wheel factor error| finished", &s.wheel_factor_error_finished_abs, 100.0, "%");
        let _ = writeln!(
            t,
            "  finished agreement {} (false verified {}, false rejected {}); online window agreement {}; finished APE median {} m",
            pct(self.finished_agreement),
            self.finished_false_verified,
            self.finished_false_rejected,
            pct(self.online_window_agreement),
            m(self.ape_finished_median_m)
        );
        let _ = writeln!(
            t,
            "  camera mount within {MOUNT_TARGET_DEG}° of the truth at the end on {} of drives ({} called calibrated)",
            pct(self.mount_within_half_degree),
            self.mount_calibrated
        );
        let _ = writeln!(
            t,
            "  poses within 2σ of the truth: device {} of {}, finished {} of {}",
            pct(self.online_within_2sigma),
            self.online_sigma_poses,
            pct(self.finished_within_2sigma),
            self.finished_sigma_poses
        );
        if !self.disagreements.is_empty() {
            let mut causes: Vec<(&str, usize)> = Vec::new();
            for d in &self.disagreements {
                match causes.iter_mut().find(|(c, _)| *c == d.cause) {
                    Some((_, n)) => *n += 1,
                    None => causes.push((d.cause, 1)),
                }
            }
            let causes: Vec<String> = causes.iter().map(|(c, n)| format!("{n} {c}")).collect();
            let _ = writeln!(t, "  disagreements by cause: {}", causes.join(", "));
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_are_linear_between_ranks_as_numpy_s() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quantile(&v, 0.5), Some(2.5));
        assert_eq!(quantile(&v, 0.0), Some(1.0));
        assert_eq!(quantile(&v, 1.0), Some(4.0));
        // numpy.percentile([1, 2, 3, 4], 90) = 3.7
        assert!((quantile(&v, 0.9).unwrap_or(f64::NAN) - 3.7).abs() < 1e-12);
        assert_eq!(quantile(&[], 0.5), None);
    }

    /// A drive that failed to run counts against every rate over drives and is listed as a
    /// disagreement of its own kind.
    #[test]
    fn a_failed_drive_is_a_disagreement_not_a_drive_left_out() {
        use crate::scenario::profile::{Profile, Receiver};
        use crate::scenario::Driver;
        let args = SweepRequest {
            seeds: 1..=3,
            driver: crate::scenario::Drivers::One(Driver::Careful),
            profile: Profile::Typical,
            receiver: Receiver::Good,
            anchors: super::super::drive::Anchors::Street,
            oracle_latency: true,
            relative_motion: RelativeMotion::Vo,
            doubt: dash2sim_verify::decide::DoubtSettings::default(),
            duration: 40.0,
            jobs: None,
            output: std::path::PathBuf::new(),
            keep: false,
        };
        let verdict = |verified: bool, decision: Decision| {
            let score = if verified { 100.0 } else { 0.0 };
            let v = Verdict {
                score,
                verified,
                failed: Vec::new(),
                decision,
                score_interval: [score; 2],
                in_doubt: Vec::new(),
            };
            Verdicts { insensitive: v.clone(), sensitive: v }
        };
        let decided = |verified| if verified { Decision::Verified } else { Decision::Rejected };
        let agreed = |seed: u64, verified: bool| Row {
            truth: Some(verdict(verified, decided(verified))),
            finished: Some(verdict(verified, decided(verified))),
            ..Row::empty(seed, Driver::Careful, &args)
        };
        let failed = Row {
            error: Some("record: the drive's files are unreadable".to_owned()),
            ..Row::empty(3, Driver::Careful, &args)
        };
        let window = |start_s: f64, end_s: f64| super::super::drive::WindowPair {
            start_s,
            end_s,
            device_score: 100.0,
            device_verified: true,
            device_decision: Some(Decision::Undecided),
            device_failed: Vec::new(),
            truth_score: 100.0,
            truth_verified: true,
            truth_collision: false,
            truth_failed: Vec::new(),
        };
        let with_windows = Row { windows: vec![window(3.0, 18.0), window(18.0, 33.0)], ..agreed(1, true) };
        let rows = [with_windows, agreed(2, false), failed];
        let summary = Summary::of(&args, &rows);
        assert_eq!(summary.failed_drives, 1);
        assert_eq!(summary.finished_agreement, Some(2.0 / 3.0), "two of three drives agree");
        assert_eq!(summary.disagreements.len(), 1);
        assert_eq!((summary.disagreements[0].seed, summary.disagreements[0].cause), (3, "failed"));
        assert!(summary.disagreements[0].metrics[0].contains("unreadable"));
        // 30 s of windows over three 40 s drives, the failed one's included.
        assert_eq!(summary.device_window_coverage, Some(0.25));
        // Both windows undecided where the truth verifies: none decided.
        let w = summary.device_window_decisions;
        assert_eq!((w.truth_verified.undecided, w.decided()), (2, 0));
        assert_eq!(
            (summary.device_window_undecided_rate, summary.device_window_agreement_among_decided),
            (Some(1.0), None)
        );
        // Every row says the oracle was in.
        assert!(rows.iter().all(|r| r.oracle_latency));
        assert!(summary.text().contains("1 failed"), "{}", summary.text());
        // The 2 × 3 table: the failed drive is counted, and counts in the undecided rate's
        // denominator.
        let d = summary.finished_decisions;
        assert_eq!((d.truth_verified.verified, d.truth_rejected.rejected, d.failed, d.drives()), (1, 1, 1, 3));
        assert_eq!((summary.wrong_decided, summary.undecided_rate), (0, Some(0.0)));
        let undecided = Row { finished: Some(verdict(true, Decision::Undecided)), ..agreed(4, false) };
        let wrong = Row { finished: Some(verdict(true, Decision::Verified)), ..agreed(5, false) };
        let summary = Summary::of(&args, &[agreed(1, true), undecided, wrong, Row::empty(6, Driver::Careful, &args)]);
        assert_eq!(summary.wrong_decided, 1, "the truth rejects seed 5, its log is decided verified");
        assert_eq!(summary.undecided_rate, Some(0.25), "one of four drives undecided");
        assert_eq!(summary.agreement_among_decided, Some(0.5));
        assert_eq!(summary.finished_decisions.failed, 1, "a row without a truth did not come through");
    }

    #[test]
    fn confusion_counts_each_pair_once() {
        let c = Confusion::of([(true, true), (true, false), (false, true), (false, false), (true, true)].into_iter());
        assert_eq!(c.total(), 5);
        assert_eq!(c.truth_verified_log_verified, 2);
        assert_eq!(c.agreement(), Some(0.6));
        assert_eq!(Confusion::default().agreement(), None);
    }
}
