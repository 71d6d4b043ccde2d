//! `dash2sim track2d DETS.txt -o TRACKS.txt`: MOTChallenge detections (id column may be
//! −1) through the core's ByteTrack-style tracker, MOTChallenge tracks out.
//!
//! A confidence of −1 (MOTChallenge's "unset", as in tracker outputs used as detections)
//! is read as 1. Rows whose frame goes backwards are skipped and reported; detections the
//! tracker refuses (bad boxes, scores outside [0, 1]) are counted in the summary.

use dash2sim_core::track2d::{Detection, Stats, TrackOutput, Tracker2d, TrackerConfig};

use crate::ingest::motchallenge::MotRow;

/// Tracks and detections per frame the CLI handles.
pub const CAPACITY: usize = 256;

/// Track `rows` (in file order); returns the tracks as MOTChallenge rows, the tracker's
/// counters and the rows skipped for going back in time.
pub fn track(rows: &[MotRow]) -> (Vec<MotRow>, Stats, Vec<(usize, String)>) {
    let mut tracker = Box::new(Tracker2d::<CAPACITY>::new(TrackerConfig::default()));
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    let mut current: Option<i64> = None;
    let mut frame_dets: Vec<Detection> = Vec::new();
    let mut flush = |frame: i64, dets: &mut Vec<Detection>, tracker: &mut Tracker2d<CAPACITY>| {
        let Ok(f) = u64::try_from(frame) else { return };
        let _ = tracker.update(f, dets, |t: TrackOutput| {
            out.push(MotRow { frame, id: i64::from(t.id), bbox: t.bbox, confidence: t.score });
        });
        dets.clear();
    };
    for (i, row) in rows.iter().enumerate() {
        match current {
            Some(f) if row.frame < f => {
                skipped.push((i + 1, format!("row {}: frame {} after frame {f}, skipped", i + 1, row.frame)));
                continue;
            }
            Some(f) if row.frame > f => flush(f, &mut frame_dets, &mut tracker),
            _ => {}
        }
        current = Some(row.frame);
        let score = if row.confidence == -1.0 { 1.0 } else { row.confidence };
        frame_dets.push(Detection { bbox: row.bbox, score });
    }
    if let Some(f) = current {
        flush(f, &mut frame_dets, &mut tracker);
    }
    (out, *tracker.stats(), skipped)
}
