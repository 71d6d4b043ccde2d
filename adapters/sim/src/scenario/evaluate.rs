//! Judging the 3D track manager on a generated scenario: CLEAR-MOT and identity metrics
//! with a 2 m centre-distance gate (motmetrics' accumulator), the position error of the
//! raw detections against the filtered and the RTS-smoothed tracks on the same
//! object-frames, and how often a track's static/dynamic label is right.
//!
//! The detections are moved into the world frame with the true ego pose, so the figures
//! are the tracker's own, not the anchoring's.

use std::collections::HashMap;

use dash2sim_core::box3d::Box3d;
use dash2sim_core::ekf::SmoothStep;
use dash2sim_core::track3d::{smooth_track, Config3d, Detection3d, Stats3d, Track3dOutput, Tracker3d};

use super::sensors::detection_to_world;
use super::Scenario;
use dash2sim_verify::mot::{self, Accumulator, EventKind};

/// Largest horizontal centre distance at which a track or detection matches an object.
pub const MATCH_DISTANCE_M: f64 = 2.0;

/// What the evaluation measured.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackingReport {
    /// Frames run.
    pub frames: usize,
    /// Visible object-frames (the ground truth the metrics count).
    pub object_frames: usize,
    /// Distinct objects seen.
    pub objects: usize,
    /// Detections fed to the tracker.
    pub detections: usize,
    /// motmetrics' summary over the run (`mota`, `idf1`, `num_switches`, …).
    pub summary: mot::Summary,
    /// Object-frames with both a matched detection and a matched track.
    pub paired: usize,
    /// RMS horizontal error of the matched detections on those object-frames, m.
    pub rmse_detections: f64,
    /// Same for the filtered tracks.
    pub rmse_filtered: f64,
    /// Same for the tracks after RTS smoothing.
    pub rmse_smoothed: f64,
    /// Matched track-frames whose static/dynamic label equals the truth.
    pub static_correct: usize,
    /// Matched track-frames judged.
    pub static_judged: usize,
    /// The tracker's counters.
    pub stats: Stats3d,
    /// Every track report, with its frame number.
    pub tracks: Vec<(u64, Track3dOutput)>,
}

impl TrackingReport {
    /// Fraction of matched track-frames labelled static/dynamic correctly.
    pub fn static_accuracy(&self) -> f64 {
        self.static_correct as f64 / self.static_judged.max(1) as f64
    }

    /// A metric of the summary by motmetrics' name (NaN when absent).
    pub fn metric(&self, name: &str) -> f64 {
        self.summary.get(name).unwrap_or(f64::NAN)
    }
}

fn horizontal_distance(a: &Box3d, b: &Box3d) -> f64 {
    (a.x - b.x).hypot(a.y - b.y)
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

/// Run `Tracker3d<N>` with `config` over the scenario and judge it.
pub fn evaluate_tracking<const N: usize>(scenario: &Scenario, config: Config3d<'_>) -> TrackingReport {
    let mut tracker = Tracker3d::<N>::new(config);
    let mut outputs: Vec<(u64, Track3dOutput)> = Vec::new();
    let mut accumulator = Accumulator::default();
    let mut detection_errors: HashMap<(u32, u32), f64> = HashMap::new();
    let mut objects_seen = std::collections::HashSet::new();
    let (mut object_frames, mut detections) = (0, 0);
    for frame in &scenario.frames {
        let world: Vec<Detection3d> = frame.detections_3d.iter().map(|d| detection_to_world(&frame.ego, d)).collect();
        detections += world.len();
        let first = outputs.len();
        let index = u64::from(frame.index);
        if tracker.update(index, &world, |o| outputs.push((index, o))).is_err() {
            continue; // generated frames are numbered in order; counted in the stats otherwise
        }
        let truth: Vec<_> = frame.visible.iter().filter_map(|&id| frame.object(id)).collect();
        object_frames += truth.len();
        objects_seen.extend(frame.visible.iter().copied());
        // Detections: the best one-to-one match per frame.
        let gate = |object: &Box3d, class: u16, other_class: u16, other: &Box3d| {
            let d = horizontal_distance(object, other);
            (class == other_class && d <= MATCH_DISTANCE_M).then_some(d)
        };
        let cost = |i: usize, j: usize| gate(&truth[i].bbox, truth[i].class as u16, world[j].class, &world[j].bbox);
        if let Ok(assignment) = mot::solve_sparse(truth.len(), world.len(), cost) {
            for (i, j) in assignment.iter().enumerate() {
                if let Some(d) = j.and_then(|j| cost(i, j)) {
                    detection_errors.insert((frame.index, truth[i].id), d);
                }
            }
        }
        // Tracks: motmetrics' accumulator (carried-forward matches, switches).
        let reported: Vec<_> = outputs[first..].iter().map(|(_, o)| (o.id, o.class, o.bbox)).collect();
        accumulate_frame(&mut accumulator, frame, &reported);
    }
    let smoothed = smooth_all(&outputs, config);
    let track_at: HashMap<(u64, u32), &Track3dOutput> = outputs.iter().map(|(f, o)| ((*f, o.id), o)).collect();
    let (mut det, mut filtered, mut smooth) = (Vec::new(), Vec::new(), Vec::new());
    let (mut static_correct, mut static_judged) = (0, 0);
    for event in accumulator.events() {
        let (Some(object), Some(hypothesis), Some(distance)) = (event.object, event.hypothesis, event.distance) else {
            continue;
        };
        if !matches!(event.kind, EventKind::Match | EventKind::Switch) {
            continue;
        }
        let (Ok(frame), Ok(object), Ok(track)) =
            (u32::try_from(event.frame), u32::try_from(object), u32::try_from(hypothesis))
        else {
            continue;
        };
        let Some(truth) = scenario.frames.get(frame as usize - 1).and_then(|f| f.object(object)) else { continue };
        if let Some(output) = track_at.get(&(u64::from(frame), track)) {
            static_judged += 1;
            static_correct += usize::from(output.is_static == truth.is_static());
        }
        let (Some(&d), Some(s)) = (detection_errors.get(&(frame, object)), smoothed.get(&(u64::from(frame), track)))
        else {
            continue;
        };
        det.push(d);
        filtered.push(distance);
        smooth.push(horizontal_distance(s, &truth.bbox));
    }
    TrackingReport {
        frames: scenario.frames.len(),
        object_frames,
        objects: objects_seen.len(),
        detections,
        summary: mot::summarize(&accumulator),
        paired: det.len(),
        rmse_detections: rms(det.into_iter()),
        rmse_filtered: rms(filtered.into_iter()),
        rmse_smoothed: rms(smooth.into_iter()),
        static_correct,
        static_judged,
        stats: *tracker.stats(),
        tracks: outputs,
    }
}

/// Add one frame's reported tracks `(id, class, box)` to a MOT accumulator: the visible
/// objects are the truth, matched by class within [`MATCH_DISTANCE_M`] (horizontal).
pub fn accumulate_frame(accumulator: &mut Accumulator, frame: &super::Frame, reported: &[(u32, u16, Box3d)]) {
    let truth: Vec<_> = frame.visible.iter().filter_map(|&id| frame.object(id)).collect();
    let object_ids: Vec<i64> = truth.iter().map(|o| i64::from(o.id)).collect();
    let track_ids: Vec<i64> = reported.iter().map(|(id, _, _)| i64::from(*id)).collect();
    accumulator.update(i64::from(frame.index), &object_ids, &track_ids, |i, j| {
        let (_, class, b) = &reported[j];
        let d = horizontal_distance(&truth[i].bbox, b);
        (truth[i].class as u16 == *class && d <= MATCH_DISTANCE_M).then_some(d)
    });
}

/// MOT metrics of tracks reported per frame (`frame index → (id, class, box)`), e.g. the
/// 3D tracks of a 4D log, against the scenario's truth.
pub fn score_tracks(scenario: &Scenario, reported: &HashMap<u32, Vec<(u32, u16, Box3d)>>) -> mot::Summary {
    let mut accumulator = Accumulator::default();
    for frame in &scenario.frames {
        accumulate_frame(&mut accumulator, frame, reported.get(&frame.index).map_or(&[], Vec::as_slice));
    }
    mot::summarize(&accumulator)
}

/// RTS-smooth every track's reports; the smoothed box per (frame, track id).
pub fn smooth_all(outputs: &[(u64, Track3dOutput)], config: Config3d<'_>) -> HashMap<(u64, u32), Box3d> {
    let mut by_track: HashMap<u32, Vec<(u64, &Track3dOutput)>> = HashMap::new();
    for (frame, output) in outputs {
        by_track.entry(output.id).or_default().push((*frame, output));
    }
    let mut smoothed = HashMap::new();
    for (id, reports) in by_track {
        let Some(class) = reports.first().and_then(|(_, o)| config.classes.get(usize::from(o.class))) else {
            continue;
        };
        let frames: Vec<u64> = reports.iter().map(|(f, _)| *f).collect();
        let mut steps: Vec<SmoothStep<10>> = reports.iter().map(|(_, o)| SmoothStep::filtered(&o.state)).collect();
        if smooth_track(&frames, &mut steps, &class.process_noise).is_err() {
            continue;
        }
        for ((frame, _), step) in reports.iter().zip(&steps) {
            let x = &step.x;
            let bbox = Box3d { x: x[0], y: x[1], z: x[2], yaw: x[3], l: x[4], w: x[5], h: x[6] };
            smoothed.insert((*frame, id), bbox);
        }
    }
    smoothed
}
