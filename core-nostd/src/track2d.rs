//! Online 2D tracking-by-detection in the ByteTrack style (Zhang et al. 2022; docs/tracking.md):
//! detections split by score, high ones matched first to every live track, low ones then
//! rescue tracks the high ones missed, new tracks only from high detections, confirmed
//! on their second hit. Box motion is a constant-velocity Kalman filter on
//! (centre x, centre y, aspect, height) with noise proportional to the height, as in
//! ByteTrack.
//!
//! Capacity is part of the type: `Tracker2d<N>` holds at most N tracks and considers at
//! most N detections per frame (the lowest-scoring extras are dropped and counted).

use nalgebra::{SMatrix, SVector};

use crate::assign::Solver;
use crate::box2d::Box2d;
use crate::ekf::Kalman;

/// A detection: a box and a confidence in [0, 1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    /// The box.
    pub bbox: Box2d,
    /// Confidence in [0, 1].
    pub score: f64,
}

/// Thresholds (ByteTrack's defaults for MOT17).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackerConfig {
    /// Detections at or above this are "high".
    pub high_score: f64,
    /// Detections below this are ignored.
    pub low_score: f64,
    /// A new track needs at least this score.
    pub new_track_score: f64,
    /// First stage (high detections ↔ all live tracks): least IoU to match.
    pub first_min_iou: f64,
    /// Second stage (low detections ↔ tracks still unmatched): least IoU.
    pub second_min_iou: f64,
    /// Unconfirmed tracks ↔ remaining high detections: least IoU.
    pub unconfirmed_min_iou: f64,
    /// Frames a lost track is kept for re-identification.
    pub max_lost_frames: u64,
}

impl TrackerConfig {
    /// ByteTrack's defaults for MOT17 (what [`Default`] gives).
    pub const BYTETRACK: TrackerConfig = TrackerConfig {
        high_score: 0.6,
        low_score: 0.1,
        new_track_score: 0.7,
        first_min_iou: 0.2,
        second_min_iou: 0.5,
        unconfirmed_min_iou: 0.3,
        max_lost_frames: 30,
    };
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig::BYTETRACK
    }
}

/// Counters of what was refused or dropped.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Stats {
    /// Frames processed.
    pub frames: u64,
    /// Detections with a non-finite or empty box, or a score outside [0, 1].
    pub rejected_detections: u64,
    /// Detections beyond the per-frame capacity (lowest scores first).
    pub dropped_detections: u64,
    /// Frames given out of order (refused).
    pub out_of_order_frames: u64,
    /// Track candidates not started, or lost tracks evicted, for lack of capacity.
    pub dropped_tracks: u64,
}

use crate::frame_order::FrameOrder;
pub use crate::frame_order::TrackError;

/// A confirmed track in this frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrackOutput {
    /// Track id (from 1, never reused).
    pub id: u32,
    /// The filtered box.
    pub bbox: Box2d,
    /// Score of the detection that updated it.
    pub score: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Started, not yet confirmed by a second hit.
    New,
    Tracked,
    Lost,
}

#[derive(Clone, Copy, Debug)]
struct Track {
    id: u32,
    kf: Kalman<8>,
    state: State,
    last_frame: u64,
    score: f64,
}

const POSITION_WEIGHT: f64 = 1.0 / 20.0;
const VELOCITY_WEIGHT: f64 = 1.0 / 160.0;

fn measurement(b: &Box2d) -> SVector<f64, 4> {
    SVector::<f64, 4>::new(b.x + b.w / 2.0, b.y + b.h / 2.0, b.w / b.h, b.h)
}

fn diag<const N: usize>(std: [f64; N]) -> SMatrix<f64, N, N> {
    SMatrix::<f64, N, N>::from_diagonal(&SVector::<f64, N>::from(std.map(|s| s * s)))
}

impl Track {
    fn start(id: u32, d: &Detection, frame: u64, confirmed: bool) -> Self {
        let z = measurement(&d.bbox);
        let h = z[3];
        let (p, v) = (2.0 * POSITION_WEIGHT * h, 10.0 * VELOCITY_WEIGHT * h);
        let x = SVector::<f64, 8>::from_column_slice(&[z[0], z[1], z[2], z[3], 0.0, 0.0, 0.0, 0.0]);
        Track {
            id,
            kf: Kalman::new(x, diag([p, p, 1e-2, p, v, v, 1e-5, v])),
            state: if confirmed { State::Tracked } else { State::New },
            last_frame: frame,
            score: d.score,
        }
    }

    fn predict(&mut self, steps: u64) {
        let mut f = SMatrix::<f64, 8, 8>::identity();
        for i in 0..4 {
            f[(i, i + 4)] = 1.0;
        }
        for _ in 0..steps.min(64) {
            let h = self.kf.x[3];
            let (p, v) = (POSITION_WEIGHT * h, VELOCITY_WEIGHT * h);
            if self.state != State::Tracked {
                // ByteTrack freezes the height velocity of tracks it is not following.
                self.kf.x[7] = 0.0;
            }
            self.kf.predict(&f, &diag([p, p, 1e-2, p, v, v, 1e-5, v]));
        }
    }

    fn update(&mut self, d: &Detection, frame: u64) {
        let h = self.kf.x[3];
        let p = POSITION_WEIGHT * h;
        let mut hm = SMatrix::<f64, 4, 8>::zeros();
        for i in 0..4 {
            hm[(i, i)] = 1.0;
        }
        // A refused update (singular or non-finite) leaves the prediction in place.
        let _ = self.kf.update(&measurement(&d.bbox), &hm, &diag([p, p, 1e-1, p]));
        self.state = State::Tracked;
        self.last_frame = frame;
        self.score = d.score;
    }

    fn bbox(&self) -> Option<Box2d> {
        let x = &self.kf.x;
        let w = x[2] * x[3];
        Box2d::new(x[0] - w / 2.0, x[1] - x[3] / 2.0, w, x[3]).ok()
    }
}

/// ByteTrack-style tracker with at most `N` tracks.
#[derive(Clone, Debug)]
pub struct Tracker2d<const N: usize> {
    config: TrackerConfig,
    tracks: heapless::Vec<Track, N>,
    next_id: u32,
    frames: FrameOrder,
    solver: Solver<N>,
    stats: Stats,
}

/// Indices into a frame's detections, at most N, keeping the highest scores.
type Picked<const N: usize> = heapless::Vec<usize, N>;

impl<const N: usize> Tracker2d<N> {
    /// An empty tracker.
    pub const fn new(config: TrackerConfig) -> Self {
        Tracker2d {
            config,
            tracks: heapless::Vec::new(),
            next_id: 1,
            frames: FrameOrder::new(),
            solver: Solver::new(),
            stats: Stats {
                frames: 0,
                rejected_detections: 0,
                dropped_detections: 0,
                out_of_order_frames: 0,
                dropped_tracks: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Process the detections of `frame` (strictly increasing; gaps are predicted over);
    /// `emit` receives every confirmed, currently tracked track.
    pub fn update(
        &mut self,
        frame: u64,
        detections: &[Detection],
        mut emit: impl FnMut(TrackOutput),
    ) -> Result<(), TrackError> {
        let first_frame = self.frames.last().is_none();
        let steps = self.frames.advance(frame).inspect_err(|_| self.stats.out_of_order_frames += 1)?;
        self.stats.frames += 1;

        let (mut high, mut low) = (Picked::<N>::new(), Picked::<N>::new());
        for (i, d) in detections.iter().enumerate() {
            let valid = Box2d::new(d.bbox.x, d.bbox.y, d.bbox.w, d.bbox.h).is_ok() && (0.0..=1.0).contains(&d.score);
            if !valid {
                self.stats.rejected_detections += 1;
            } else if d.score >= self.config.high_score {
                self.stats.dropped_detections += keep_best(&mut high, i, detections);
            } else if d.score >= self.config.low_score {
                self.stats.dropped_detections += keep_best(&mut low, i, detections);
            }
        }
        for t in self.tracks.iter_mut() {
            t.predict(steps);
        }

        // 1. High detections ↔ tracked and lost tracks.
        let mut matched_track = [false; N];
        let pool: Picked<N> = (0..self.tracks.len()).filter(|&t| self.tracks[t].state != State::New).collect();
        let high_left = self.associate(&pool, &high, detections, self.config.first_min_iou, frame, &mut matched_track);
        // 2. Low detections ↔ tracked tracks still unmatched.
        let pool: Picked<N> =
            pool.iter().copied().filter(|&t| !matched_track[t] && self.tracks[t].state == State::Tracked).collect();
        self.associate(&pool, &low, detections, self.config.second_min_iou, frame, &mut matched_track);
        for (t, track) in self.tracks.iter_mut().enumerate() {
            if !matched_track[t] && track.state == State::Tracked {
                track.state = State::Lost;
            }
        }
        // 3. Unconfirmed tracks ↔ the high detections left; unmatched ones are dropped.
        let pool: Picked<N> = (0..self.tracks.len()).filter(|&t| self.tracks[t].state == State::New).collect();
        let high_left =
            self.associate(&pool, &high_left, detections, self.config.unconfirmed_min_iou, frame, &mut matched_track);
        let mut t = 0;
        let mut keep = [false; N];
        for (i, track) in self.tracks.iter().enumerate() {
            keep[i] = match track.state {
                State::New => matched_track[i],
                State::Lost => frame - track.last_frame <= self.config.max_lost_frames,
                State::Tracked => true,
            };
        }
        self.tracks.retain(|_| {
            t += 1;
            keep[t - 1]
        });
        // 4. New tracks from confident high detections.
        for &d in &high_left {
            if detections[d].score < self.config.new_track_score {
                continue;
            }
            if self.tracks.is_full() {
                // Evict the longest-lost track, if any; otherwise the candidate is dropped.
                let oldest = (0..self.tracks.len())
                    .filter(|&t| self.tracks[t].state == State::Lost)
                    .min_by_key(|&t| self.tracks[t].last_frame);
                self.stats.dropped_tracks += 1;
                match oldest {
                    Some(t) => {
                        self.tracks.swap_remove(t);
                    }
                    None => continue,
                }
            }
            let track = Track::start(self.next_id, &detections[d], frame, first_frame);
            self.next_id = self.next_id.wrapping_add(1).max(1);
            let _ = self.tracks.push(track);
        }
        for track in self.tracks.iter().filter(|t| t.state == State::Tracked && t.last_frame == frame) {
            if let Some(bbox) = track.bbox() {
                emit(TrackOutput { id: track.id, bbox, score: track.score });
            }
        }
        Ok(())
    }

    /// Match `pool` tracks to `candidates` detections by IoU (at least `min_iou`), update
    /// the matched tracks; returns the candidates left over.
    fn associate(
        &mut self,
        pool: &[usize],
        candidates: &[usize],
        detections: &[Detection],
        min_iou: f64,
        frame: u64,
        matched_track: &mut [bool; N],
    ) -> Picked<N> {
        let mut out = [None; N];
        let boxes: heapless::Vec<Option<Box2d>, N> = pool.iter().map(|&t| self.tracks[t].bbox()).collect();
        let cost = |r: usize, c: usize| {
            let iou = boxes[r]?.iou(&detections[candidates[c]].bbox);
            (iou >= min_iou).then_some(1.0 - iou)
        };
        let solved = self.solver.solve_sparse(pool.len(), candidates.len(), cost, &mut out).is_ok();
        let mut used = [false; N];
        if solved {
            for (r, c) in out.iter().take(pool.len()).enumerate() {
                if let Some(c) = *c {
                    used[c] = true;
                    matched_track[pool[r]] = true;
                    self.tracks[pool[r]].update(&detections[candidates[c]], frame);
                }
            }
        }
        candidates.iter().enumerate().filter(|&(c, _)| !used[c]).map(|(_, &d)| d).collect()
    }
}

/// Add detection `i` to `picked`, replacing the lowest score when full; returns 1 when
/// a detection was dropped.
fn keep_best<const N: usize>(picked: &mut Picked<N>, i: usize, detections: &[Detection]) -> u64 {
    if picked.push(i).is_ok() {
        return 0;
    }
    let weakest =
        (0..picked.len()).min_by(|&a, &b| detections[picked[a]].score.total_cmp(&detections[picked[b]].score));
    if let Some(w) = weakest {
        if detections[picked[w]].score < detections[i].score {
            picked[w] = i;
        }
    }
    1
}

#[cfg(test)]
mod tests {
    use super::*;

    fn det(x: f64, y: f64, score: f64) -> Detection {
        Detection { bbox: Box2d { x, y, w: 20.0, h: 40.0 }, score }
    }

    fn run<const N: usize>(
        tracker: &mut Tracker2d<N>,
        frame: u64,
        dets: &[Detection],
    ) -> heapless::Vec<TrackOutput, 16> {
        let mut out = heapless::Vec::new();
        tracker.update(frame, dets, |t| out.push(t).expect("room")).expect("in order");
        out
    }

    #[test]
    fn tracks_are_confirmed_on_the_second_hit_and_keep_their_ids() {
        let mut tracker = Tracker2d::<8>::new(TrackerConfig::default());
        // First frame: confirmed at once (as ByteTrack).
        assert_eq!(run(&mut tracker, 1, &[det(0.0, 0.0, 0.9)]).len(), 1);
        // A new object appears: unconfirmed until its second frame.
        let out = run(&mut tracker, 2, &[det(2.0, 0.0, 0.9), det(200.0, 0.0, 0.9)]);
        assert_eq!(out.iter().map(|t| t.id).collect::<heapless::Vec<_, 4>>().as_slice(), &[1]);
        let out = run(&mut tracker, 3, &[det(4.0, 0.0, 0.9), det(202.0, 0.0, 0.9)]);
        let mut ids: heapless::Vec<u32, 4> = out.iter().map(|t| t.id).collect();
        ids.sort_unstable();
        assert_eq!(ids.as_slice(), &[1, 2]);
    }

    #[test]
    fn low_detections_rescue_tracks_and_lost_tracks_come_back() {
        let mut tracker = Tracker2d::<8>::new(TrackerConfig::default());
        run(&mut tracker, 1, &[det(0.0, 0.0, 0.9)]);
        run(&mut tracker, 2, &[det(1.0, 0.0, 0.9)]);
        // An occluded frame with only a weak detection keeps the track alive.
        let out = run(&mut tracker, 3, &[det(2.0, 0.0, 0.3)]);
        assert_eq!(out.first().map(|t| t.id), Some(1));
        // Missing for a few frames (lost), then found again with the same id.
        assert!(run(&mut tracker, 4, &[]).is_empty());
        assert!(run(&mut tracker, 5, &[]).is_empty());
        let out = run(&mut tracker, 6, &[det(5.0, 0.0, 0.9)]);
        assert_eq!(out.first().map(|t| t.id), Some(1));
    }

    #[test]
    fn bad_detections_and_frames_are_refused_and_counted() {
        let mut tracker = Tracker2d::<2>::new(TrackerConfig::default());
        let bad = [
            Detection { bbox: Box2d { x: f64::NAN, y: 0.0, w: 1.0, h: 1.0 }, score: 0.9 },
            Detection { bbox: Box2d { x: 0.0, y: 0.0, w: 0.0, h: 1.0 }, score: 0.9 },
            det(0.0, 0.0, 1.5),
            det(0.0, 0.0, -0.1),
        ];
        assert!(run(&mut tracker, 1, &bad).is_empty());
        assert_eq!(tracker.stats().rejected_detections, 4);
        // Three confident detections for two slots: the weakest is dropped.
        let out = run(&mut tracker, 2, &[det(0.0, 0.0, 0.9), det(100.0, 0.0, 0.8), det(200.0, 0.0, 0.95)]);
        assert!(out.is_empty(), "not the first frame processed: unconfirmed");
        assert_eq!(tracker.stats().dropped_detections, 1);
        assert_eq!(tracker.update(2, &[], |_| {}), Err(TrackError::OutOfOrder { previous: 2, frame: 2 }));
        assert_eq!(tracker.stats().out_of_order_frames, 1);
    }

    #[test]
    fn same_input_same_output() {
        let frames: [&[Detection]; 3] = [
            &[det(0.0, 0.0, 0.9), det(50.0, 0.0, 0.7)],
            &[det(1.0, 0.0, 0.9), det(51.0, 0.0, 0.4)],
            &[det(2.0, 0.0, 0.9)],
        ];
        let once = |_: ()| {
            let mut tracker = Tracker2d::<4>::new(TrackerConfig::default());
            let mut all = heapless::Vec::<TrackOutput, 16>::new();
            for (f, dets) in frames.iter().enumerate() {
                all.extend(run(&mut tracker, f as u64 + 1, dets));
            }
            all
        };
        assert_eq!(once(()), once(()));
        assert!(!once(()).is_empty());
    }
}
