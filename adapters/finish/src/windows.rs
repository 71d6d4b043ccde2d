//! Verification of a finished drive: per window of nuPlan scenario length and for the
//! whole drive, channel-insensitive (every lane is drivable, as the device verifies) and
//! channel-sensitive (only lanes along the driven route, which needs the whole route and
//! so is offline work; `docs/verify.md`).

use dash2sim_core::binlog::{quantise, Record};
use dash2sim_core::drivable::Checker;
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{Pose2, PACIFICA};
use dash2sim_core::pipeline::verification_record;
use dash2sim_core::score::Scores;
use serde::Serialize;

use dash2sim_linux::ingest::map_tile::fine_index;
use dash2sim_linux::log::{event, LogContents, RecordStore};
use dash2sim_linux::{Error, Result};
use dash2sim_verify::decide::{decision_or_point, Decision, DoubtSettings};
use dash2sim_verify::{replay_in_doubt, AgentsByTime, Metrics, StatedUncertainty, Verification};

/// nuPlan's scenario length, s.
pub const WINDOW_S: f64 = 15.0;

/// What verification adds to the finished log and the report.
#[derive(Debug)]
pub struct Verified {
    /// `Verification` records (channel-insensitive, one per window, as the device writes
    /// them) and an event per window and for the drive with both modes.
    pub records: Vec<Record>,
    /// The `verification` object of the report.
    pub report: DriveVerification,
}

/// The finished drive verified: per window and whole.
#[derive(Clone, Debug, Serialize)]
pub struct DriveVerification {
    /// The windows' length, s.
    pub window_s: f64,
    /// Each window.
    pub windows: Vec<WindowVerdicts>,
    /// The whole drive.
    pub drive: BothVerdicts,
}

/// One window of the finished drive.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct WindowVerdicts {
    /// Its start from the drive's first pose, s.
    pub start_s: f64,
    /// Its end, s.
    pub end_s: f64,
    /// Every lane drivable (as the device verifies).
    pub channel_insensitive: Verdict,
    /// Only the lanes along the route.
    pub channel_sensitive: Verdict,
}

/// A stretch verified both ways.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct BothVerdicts {
    /// Every lane drivable.
    pub channel_insensitive: Verdict,
    /// Only the lanes along the route.
    pub channel_sensitive: Verdict,
}

/// Score, verdict and the metrics (`verify --json`'s `metrics`), and the decision with the
/// finished poses' σ (`verify --decide-at 2`, [`dash2sim_verify::decide`]).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Verdict {
    /// The score, 0–100.
    pub score: f64,
    /// Score > 90.
    pub verified: bool,
    /// The eight metrics.
    pub metrics: Metrics,
    /// Verified, rejected or undecided within 2σ of the finished ego's stated σ.
    pub decision: Decision,
    /// The score's interval within that doubt.
    pub score_interval: [f64; 2],
}

impl Verdict {
    fn of(v: &Verification) -> Self {
        let s = &v.scores;
        let (decision, score_interval) = decision_or_point(v.decided.as_ref(), s.score);
        Verdict { score: s.score, verified: s.verified, metrics: Metrics::of(s), decision, score_interval }
    }
}

/// The stretch `poses` (with the log's stated `sigmas`) verified without and with the
/// channel, each decided with the default doubt.
fn both(
    checker: Checker<'_>,
    poses: &[(f64, Pose2)],
    sigmas: &StatedUncertainty,
    agents: &AgentsByTime,
) -> Result<(Verification, Verification)> {
    let doubt = Some(DoubtSettings::default());
    let mode = |sensitive| replay_in_doubt(checker, poses, sigmas, agents, sensitive, doubt);
    Ok((mode(false)?, mode(true)?))
}

/// A window's verification as a record, with its decision and score interval.
fn decided_record(t_us: i64, v: &Verification) -> dash2sim_core::binlog::Verification {
    let (decision, [low, high]) = decision_or_point(v.decided.as_ref(), v.scores.score);
    dash2sim_core::binlog::Verification {
        decision: decision.code(),
        score_low_e2: quantise(low, 1e-2),
        score_high_e2: quantise(high, 1e-2),
        ..verification_record(t_us, &v.scores)
    }
}

fn verdict(s: &Scores) -> &'static str {
    if s.verified {
        "verified"
    } else {
        "not verified"
    }
}

/// Verify the finished `records` (ego poses, tracks and their covariances; `source` gives
/// the header) on the map tile `map`.
pub fn verify_finished<R>(source: &LogContents<R>, records: &RecordStore, name: &str, map: &[u8]) -> Result<Verified> {
    let view = MapView::parse(map).map_err(|e| Error::refused("map", e))?;
    // Only what verification reads, decoded: the sensors' records are most of a drive.
    let verified = |r: &Record| matches!(r, Record::EgoPose(_) | Record::Tracks3d(_) | Record::TrackCovariance(_));
    let contents = LogContents {
        header: source.header,
        records: records.iter().filter(verified).collect(),
        damage: Vec::new(),
        stats: source.stats,
        bytes: 0,
        signing: Vec::new(),
    };
    let (poses, agents) = dash2sim_verify::from_contents(&contents, name, &view)?;
    let sigmas = StatedUncertainty::of(&contents);
    // Every pose is checked in its window and in the whole drive, in both modes.
    let index = fine_index::for_checks(&view, 4 * dash2sim_verify::checks_in_doubt(poses.len()));
    let checker = fine_index::checker(view, PACIFICA, index.as_ref());
    let mut out = Vec::new();
    let mut windows = Vec::new();
    let mut start = 0;
    while start < poses.len() {
        let t0 = poses[start].0;
        let end = start + poses[start..].partition_point(|(t, _)| *t < t0 + WINDOW_S);
        // A last window shorter than half a scenario is not one.
        if poses[end - 1].0 - t0 >= 0.5 * WINDOW_S || windows.is_empty() {
            let stretch = both(checker, &poses[start..end], &sigmas.of_poses(start..end), &agents)?;
            let (insensitive, sensitive) = (&stretch.0.scores, &stretch.1.scores);
            let t_us = (poses[end - 1].0 * 1e6).round() as i64;
            out.push(Record::Verification(decided_record(t_us, &stretch.0)));
            out.push(event(
                t_us,
                2,
                &format!(
                    "finished window {:.1}–{:.1} s: score {:.2} channel-insensitive ({}), {:.2} channel-sensitive ({})",
                    t0 - poses[0].0,
                    poses[end - 1].0 - poses[0].0,
                    insensitive.score,
                    verdict(insensitive),
                    sensitive.score,
                    verdict(sensitive)
                ),
            ));
            windows.push(WindowVerdicts {
                start_s: t0 - poses[0].0,
                end_s: poses[end - 1].0 - poses[0].0,
                channel_insensitive: Verdict::of(&stretch.0),
                channel_sensitive: Verdict::of(&stretch.1),
            });
        }
        start = end;
    }
    let drive = both(checker, &poses, &sigmas, &agents)?;
    let (insensitive, sensitive) = (&drive.0.scores, &drive.1.scores);
    if let Some((t, _)) = poses.last() {
        out.push(event(
            (t * 1e6).round() as i64,
            2,
            &format!(
                "finished drive: score {:.2} channel-insensitive ({}), {:.2} channel-sensitive ({})",
                insensitive.score,
                verdict(insensitive),
                sensitive.score,
                verdict(sensitive)
            ),
        ));
    }
    Ok(Verified {
        records: out,
        report: DriveVerification {
            window_s: WINDOW_S,
            windows,
            drive: BothVerdicts {
                channel_insensitive: Verdict::of(&drive.0),
                channel_sensitive: Verdict::of(&drive.1),
            },
        },
    })
}
