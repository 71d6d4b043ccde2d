//! What the demo came to: the typed report `summary.json` holds and `dash2sim demo` renders.

use std::collections::BTreeMap;

use dash2sim_core::pipeline::PipelineStats;
use dash2sim_linux::record;
use dash2sim_verify::VerifyReport;
use serde::Serialize;

use crate::datasets::OutputFile;
use crate::fidelity::drive::{Anchors, BothModes, WindowPair};
use crate::scenario::judge::LogJudgement;
use crate::scenario::profile::Profile;
use crate::scenario::Driver;

/// What the demo came to (`summary.json`, and what `dash2sim demo` prints).
#[derive(Clone, Debug, Serialize)]
pub struct DemoReport {
    /// Seed of the drive.
    pub seed: u64,
    /// Its length, s.
    pub duration_s: f64,
    /// Who drove.
    pub driver: Driver,
    /// The sensor profile.
    pub profile: Profile,
    /// Finishing's anchors.
    pub anchors: Anchors,
    /// How the drive was recorded.
    pub recording: RecordingReport,
    /// The ego's anchoring against the truth.
    pub anchoring: AnchoringReport,
    /// The 3D tracks against the truth.
    pub tracking: TrackingReport,
    /// nuPlan's verdicts of the truth and the two logs.
    pub verification: VerificationReport,
    /// The device's log.
    pub log: LogFigures,
    /// Messages in the device log's MCAP.
    pub mcap_messages: u64,
    /// The nuPlan export.
    pub nuplan: NuplanOutcome,
    /// Every file written, and what it holds.
    pub files: Vec<OutputFile>,
}

/// How the drive was recorded.
#[derive(Clone, Debug, Serialize)]
#[serde(tag = "mode", rename_all = "lowercase")]
pub enum RecordingReport {
    /// From the drive's files.
    Offline {
        /// Inputs the files held.
        inputs: u64,
        /// What the pipeline did.
        pipeline: record::Summary,
    },
    /// Live.
    Live {
        /// Frames the camera process published.
        frames_published: u64,
        /// Frames the logger received.
        frames_received: u64,
        /// Inputs the logger dropped.
        inputs_dropped: u64,
        /// Inputs the pipeline refused.
        issues: u64,
        /// Wall-clock time of the recording, s.
        wall_s: f64,
        /// What the pipeline did.
        pipeline: PipelineStats,
    },
}

impl RecordingReport {
    /// What the pipeline did, however the drive was recorded.
    pub fn pipeline(&self) -> &PipelineStats {
        match self {
            RecordingReport::Offline { pipeline, .. } => &pipeline.stats,
            RecordingReport::Live { pipeline, .. } => pipeline,
        }
    }
}

/// The ego's anchoring, online and finished, against the truth.
#[derive(Clone, Debug, Serialize)]
pub struct AnchoringReport {
    /// The device's.
    pub online: OnlineAnchoring,
    /// The finished log's.
    pub finished: FinishedAnchoring,
}

/// The device's anchoring.
#[derive(Clone, Debug, Serialize)]
pub struct OnlineAnchoring {
    /// Drive time of the first anchored frame, s (none: never).
    pub observable_after_s: Option<f64>,
    /// Frames with an anchored ego pose.
    pub anchored_frames: usize,
    /// Frames of the drive.
    pub frames: usize,
    /// Absolute position error against the truth, RMS, m.
    pub ape_rmse_m: f64,
    /// Its largest, m.
    pub ape_max_m: f64,
    /// The anchor's scale at its last observable estimate.
    pub scale_at_end: Option<f64>,
    /// Its error against the VO's true scale then.
    pub scale_error: Option<f64>,
}

/// The finished log's anchoring.
#[derive(Clone, Debug, Serialize)]
pub struct FinishedAnchoring {
    /// Street-imagery anchors finishing used.
    pub anchors_used: usize,
    /// Absolute position error against the truth, RMS, m.
    pub ape_rmse_m: f64,
    /// Its largest, m.
    pub ape_max_m: f64,
    /// The finished scale.
    pub scale: f64,
    /// Its σ relative to it.
    pub scale_sigma_relative: f64,
    /// The VO's true scale averaged over its poses.
    pub true_mean_scale: f64,
    /// The finished scale's error against it.
    pub scale_error: f64,
}

/// The 3D tracks against the truth.
#[derive(Clone, Debug, Serialize)]
pub struct TrackingReport {
    /// The device's log.
    pub online: JudgedFigures,
    /// The finished log.
    pub finished: JudgedFigures,
    /// The tracker fed the true ego pose: what the tracks could be.
    pub tracker_fed_true_pose: MotFigures,
    /// Distinct 3D tracks of the device's log per class.
    pub tracks_by_class: BTreeMap<&'static str, usize>,
    /// The same of the finished log.
    pub finished_tracks_by_class: BTreeMap<&'static str, usize>,
}

/// MOTA and IDF1.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MotFigures {
    /// Multiple-object tracking accuracy.
    pub mota: f64,
    /// Identity F1.
    pub idf1: f64,
}

/// A log judged against the truth.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct JudgedFigures {
    /// Absolute position error, RMS, m.
    pub ape_rmse_m: f64,
    /// Its largest, m.
    pub ape_max_m: f64,
    /// Drive time of the first anchored frame, s.
    pub observable_after_s: Option<f64>,
    /// Frames with an anchored ego pose.
    pub anchored_frames: usize,
    /// MOTA over the whole drive.
    pub mota: f64,
    /// IDF1 over the whole drive.
    pub idf1: f64,
    /// MOTA over the anchored frames.
    pub mota_anchored_frames: f64,
    /// IDF1 over the anchored frames.
    pub idf1_anchored_frames: f64,
    /// MOTA of the tracks seen from the ego (the ego's error taken out).
    pub mota_seen_from_ego: f64,
    /// IDF1 of the same.
    pub idf1_seen_from_ego: f64,
}

impl From<&LogJudgement> for JudgedFigures {
    fn from(t: &LogJudgement) -> Self {
        JudgedFigures {
            ape_rmse_m: t.ego_rmse,
            ape_max_m: t.ego_max,
            observable_after_s: t.first_anchored_s,
            anchored_frames: t.ego_errors.len(),
            mota: t.tracks.0,
            idf1: t.tracks.1,
            mota_anchored_frames: t.tracks_anchored.0,
            idf1_anchored_frames: t.tracks_anchored.1,
            mota_seen_from_ego: t.tracks_relative.0,
            idf1_seen_from_ego: t.tracks_relative.1,
        }
    }
}

/// nuPlan's verdicts, and the windows'.
#[derive(Clone, Debug, Serialize)]
pub struct VerificationReport {
    /// The true drive among the true objects.
    pub ground_truth: Verdicts,
    /// The device's log.
    pub online: Verdicts,
    /// The finished log.
    pub finished: Verdicts,
    /// The device's windows, each with the truth's over the same stretch.
    pub windows_on_device: Vec<WindowPair>,
    /// Finishing's windows (channel-insensitive, as the device scores them).
    pub windows_finished: Vec<WindowVerdict>,
}

/// One trajectory verified both ways; none when there is no ego pose to verify (a device
/// that never anchored: nothing verified).
#[derive(Clone, Debug, Serialize)]
pub struct Verdicts {
    /// Every lane drivable, as the device verifies.
    pub channel_insensitive: Option<VerifyReport>,
    /// Only the lanes along the driven route.
    pub channel_sensitive: Option<VerifyReport>,
}

impl From<Option<&BothModes>> for Verdicts {
    fn from(both: Option<&BothModes>) -> Self {
        Verdicts {
            channel_insensitive: both.map(|b| b.insensitive.clone()),
            channel_sensitive: both.map(|b| b.sensitive.clone()),
        }
    }
}

/// A window's score and verdict.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct WindowVerdict {
    /// nuPlan's score, 0–100.
    pub score: f64,
    /// Above the verification threshold.
    pub verified: bool,
}

/// The device's log in figures.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LogFigures {
    /// Records it holds.
    pub records: usize,
    /// Its size, bytes.
    pub bytes: u64,
    /// Its size per minute of the drive.
    pub bytes_per_minute: f64,
    /// Damaged stretches its reader skipped.
    pub damaged: u64,
    /// The finished log's size, bytes.
    pub finished_bytes: usize,
}

/// The nuPlan export: written, or why not (a short drive makes too few scenes: said, not
/// fatal).
#[derive(Clone, Debug, Serialize)]
#[serde(untagged)]
pub enum NuplanOutcome {
    /// Written.
    Written {
        /// The log database.
        db: String,
        /// The map (GeoPackage).
        map: String,
        /// Scenes.
        scenes: usize,
        /// Ego states.
        ego_states: usize,
    },
    /// Not written.
    NotWritten {
        /// Why.
        error: String,
    },
}
