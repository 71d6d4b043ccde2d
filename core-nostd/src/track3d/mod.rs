//! 3D track manager in the AB3DMOT style (Weng et al. 2020; docs/tracking.md): one constant-
//! velocity Kalman filter per object on [x y z θ l w h vx vy vz], association per class by
//! 3D GIoU or centre distance through the optimal solver, tracks reported after
//! `min_hits` hits and dropped after `max_age` missed frames.
//!
//! Orientation: detectors often flip a box by π; when a detection's yaw differs from the
//! prediction by more than π/2 the prediction is turned by π first (AB3DMOT's
//! correction), and yaw is kept in [−π, π). Class priors refuse impossible detections
//! (sizes outside bounds, centres too far from the ground). Tracks whose speed stays
//! below a threshold are reported static — cones and barrels — the rest dynamic.
//!
//! Capacity is in the type: `Tracker3d<N>` keeps at most N tracks; when full, the track
//! with the fewest hits makes room or the candidate is dropped, and it is counted.
//!
//! A detector's stated covariances are scaled by a factor learnt from the innovations
//! ([`consistency`]): a detector too sure of itself would otherwise make every track too
//! sure of itself too.
//!
//! Offline, [`smooth_track`] runs the RTS smoother over one track's reported states.

pub mod consistency;

use core::f64::consts::PI;

use nalgebra::{SMatrix, SVector};

use crate::assign::Solver;
use crate::box3d::Box3d;
use crate::ekf::{rts_smooth, Kalman, SmoothStep};
use crate::frame_order::FrameOrder;
pub use crate::track2d::TrackError;
use consistency::CovarianceScale;

/// How detections of a class are matched to tracks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Association {
    /// 3D GIoU at least this (AB3DMOT uses −0.2 for cars).
    Giou(f64),
    /// Horizontal centre distance at most this, metres (small objects: cones).
    Distance(f64),
}

/// Per-class settings and priors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassConfig {
    /// Matching rule.
    pub association: Association,
    /// Smallest plausible (l, w, h), metres.
    pub min_size: [f64; 3],
    /// Largest plausible (l, w, h).
    pub max_size: [f64; 3],
    /// Largest |centre z − (ground + h/2)|, metres.
    pub max_ground_offset: f64,
    /// Process noise per frame: the diagonal of Q over [x y z θ l w h vx vy vz]
    /// ([`AB3DMOT_PROCESS_NOISE`] by default; a cone that never moves wants far less).
    pub process_noise: [f64; 10],
    /// Measurement noise: the diagonal of R over [x y z θ l w h]
    /// ([`AB3DMOT_MEASUREMENT_NOISE`]; the detector's real variance is better).
    pub measurement_noise: [f64; 7],
    /// Variance of a new track's velocity, (m/frame)² (AB3DMOT: 1e4, i.e. unknown). A
    /// small value is the prior that objects of the class stand still; it still moves
    /// if the measurements say so, but a few noisy detections no longer make a cone drive.
    pub initial_velocity_variance: f64,
}

/// AB3DMOT's Q: 1 on the box, 0.01 on the velocity.
pub const AB3DMOT_PROCESS_NOISE: [f64; 10] = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.01, 0.01, 0.01];

/// AB3DMOT's R: the identity.
pub const AB3DMOT_MEASUREMENT_NOISE: [f64; 7] = [1.0; 7];

/// Tracker settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Config3d<'a> {
    /// Settings per class id (detections of other classes are refused).
    pub classes: &'a [ClassConfig],
    /// Hits before a track is reported (AB3DMOT: 3; reported at once in the first frames).
    pub min_hits: u32,
    /// Missed frames before a track is dropped (AB3DMOT: 2).
    pub max_age: u32,
    /// Ground height in the tracking frame, metres.
    pub ground_z: f64,
    /// Below this speed (m per frame) a track is static.
    pub static_speed: f64,
}

/// A 3D detection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection3d {
    /// Class id (index into [`Config3d::classes`]).
    pub class: u16,
    /// Box.
    pub bbox: Box3d,
    /// Score in [0, 1].
    pub score: f64,
    /// Covariance of the horizontal centre (xx, xy, yy), m², when the detector reports
    /// it: it replaces the class's R for x and y. A monocular detector's depth error grows
    /// with range and lies along the viewing ray, which one R per class cannot describe.
    pub position_covariance: Option<[f64; 3]>,
}

impl Detection3d {
    /// A detection without its own covariance (the class's R applies).
    pub fn new(class: u16, bbox: Box3d, score: f64) -> Self {
        Detection3d { class, bbox, score, position_covariance: None }
    }
}

/// A reported track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Track3dOutput {
    /// Id, from 1, never reused.
    pub id: u32,
    /// Class id.
    pub class: u16,
    /// Filtered box.
    pub bbox: Box3d,
    /// Velocity (x, y, z) per frame.
    pub velocity: [f64; 3],
    /// Speed below the static threshold.
    pub is_static: bool,
    /// The filter's posterior (state and covariance), for offline smoothing.
    pub state: Kalman<10>,
}

/// Counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats3d {
    /// Frames processed.
    pub frames: u64,
    /// Detections refused: non-finite, unknown class, score outside [0, 1], a covariance
    /// that is not positive definite, or outside the class priors.
    pub rejected: u64,
    /// Detections beyond capacity.
    pub dropped_detections: u64,
    /// Tracks evicted or candidates dropped for lack of capacity.
    pub dropped_tracks: u64,
    /// Updates the filter refused (numerically singular).
    pub refused_updates: u64,
    /// Frames refused because their number was not after the previous one.
    pub out_of_order_frames: u64,
}

#[derive(Clone, Copy, Debug)]
struct Track {
    id: u32,
    class: u16,
    kf: Kalman<10>,
    hits: u32,
    since_update: u32,
}

/// Wrap an angle into [−π, π).
pub fn wrap_angle(a: f64) -> f64 {
    let mut r = libm::fmod(a + PI, 2.0 * PI);
    if r < 0.0 {
        r += 2.0 * PI;
    }
    let wrapped = r - PI;
    if wrapped.is_finite() {
        wrapped
    } else {
        0.0
    }
}

fn state_of(b: &Box3d) -> SVector<f64, 7> {
    SVector::<f64, 7>::from_column_slice(&[b.x, b.y, b.z, wrap_angle(b.yaw), b.l, b.w, b.h])
}

/// `b` turned by π when its heading points against the motion `v`. The filter follows a
/// detector's π flips (AB3DMOT's correction keeps it from averaging the two headings), so
/// its yaw is the box's axis, not the way the object goes; what reads a reported heading as
/// the direction of travel (the score's projection of an agent, a simulator replaying the
/// log) gets the one the track moves along.
fn heading_along(b: Box3d, v: [f64; 3]) -> Box3d {
    let (s, c) = libm::sincos(b.yaw);
    if c * v[0] + s * v[1] < 0.0 {
        Box3d { yaw: wrap_angle(b.yaw + PI), ..b }
    } else {
        b
    }
}

fn box_of(x: &SVector<f64, 10>) -> Box3d {
    Box3d { x: x[0], y: x[1], z: x[2], yaw: x[3], l: x[4], w: x[5], h: x[6] }
}

/// The motion model for one frame: F (constant velocity) and Q = diag(`process_noise`).
pub fn motion_model(process_noise: &[f64; 10]) -> (SMatrix<f64, 10, 10>, SMatrix<f64, 10, 10>) {
    let mut f = SMatrix::<f64, 10, 10>::identity();
    f[(0, 7)] = 1.0;
    f[(1, 8)] = 1.0;
    f[(2, 9)] = 1.0;
    (f, SMatrix::from_diagonal(&SVector::from(*process_noise)))
}

/// The measurement model: H = [I7 0], R = diag(`measurement_noise`).
fn measurement_model(measurement_noise: &[f64; 7]) -> (SMatrix<f64, 7, 10>, SMatrix<f64, 7, 7>) {
    let mut h = SMatrix::<f64, 7, 10>::zeros();
    for i in 0..7 {
        h[(i, i)] = 1.0;
    }
    (h, SMatrix::from_diagonal(&SVector::from(*measurement_noise)))
}

/// Why a track's history could not be smoothed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SmoothError {
    /// `frames` and `steps` differ in length.
    LengthMismatch,
    /// Frame numbers do not increase.
    NotIncreasing,
}

impl core::fmt::Display for SmoothError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SmoothError::LengthMismatch => write!(f, "frames and states differ in number"),
            SmoothError::NotIncreasing => write!(f, "frame numbers do not increase"),
        }
    }
}

impl core::error::Error for SmoothError {}

/// Longest gap between two reports of one track that is bridged by prediction; a track is
/// retired after `max_age` missed frames, so real gaps are short.
const MAX_SMOOTH_GAP: u64 = 1024;

/// Rauch–Tung–Striebel smoothing of one track's reported states (`steps[k].x`, `.p` from
/// [`Track3dOutput::state`], reported at `frames[k]`; `process_noise` of its class), in
/// place: the transition between
/// reports is F^gap with the matching accumulated Q, and yaw is unwrapped by multiples of
/// π (the flip correction turns the filter by π) before smoothing and wrapped after.
/// Returns the number of steps left as filtered (see [`rts_smooth`]).
pub fn smooth_track(
    frames: &[u64],
    steps: &mut [SmoothStep<10>],
    process_noise: &[f64; 10],
) -> Result<usize, SmoothError> {
    if frames.len() != steps.len() {
        return Err(SmoothError::LengthMismatch);
    }
    if frames.windows(2).any(|w| w[1] <= w[0] || w[1] - w[0] > MAX_SMOOTH_GAP) {
        return Err(SmoothError::NotIncreasing);
    }
    let (f1, q1) = motion_model(process_noise);
    let mut previous_yaw = None;
    for (k, step) in steps.iter_mut().enumerate() {
        let gap = match k.checked_sub(1).and_then(|j| frames.get(j)) {
            Some(&before) => frames[k] - before,
            None => 0,
        };
        // F^gap and Σ F^i Q Fᵀ^i over the gap.
        let (mut f, mut q) = (SMatrix::<f64, 10, 10>::identity(), SMatrix::<f64, 10, 10>::zeros());
        for _ in 0..gap {
            f = f1 * f;
            q = f1 * q * f1.transpose() + q1;
        }
        (step.f, step.q) = (f, q);
        if let Some(before) = previous_yaw {
            let turns = libm::round((before - step.x[3]) / PI);
            step.x[3] += turns * PI;
        }
        previous_yaw = Some(step.x[3]);
    }
    let refused = rts_smooth(steps);
    for step in steps.iter_mut() {
        step.x[3] = wrap_angle(step.x[3]);
    }
    Ok(refused)
}

/// AB3DMOT tracker with at most `N` tracks (and N detections per frame).
#[derive(Clone, Debug)]
pub struct Tracker3d<'a, const N: usize> {
    config: Config3d<'a>,
    tracks: heapless::Vec<Track, N>,
    next_id: u32,
    /// The last frame number processed.
    frames: FrameOrder,
    solver: Solver<N>,
    /// Association costs of one frame (NaN: may not pair), computed once per pair: the
    /// solver reads a pair many times and a 3D GIoU is not cheap. f32 is ample for
    /// ranking GIoUs and distances and halves the buffer (16 KiB at N = 64).
    costs: [[f32; N]; N],
    /// What the detections' stated covariances are scaled by, learnt from the innovations.
    covariance_scale: CovarianceScale,
    stats: Stats3d,
}

impl<'a, const N: usize> Tracker3d<'a, N> {
    /// An empty tracker (const, so that a large one can live in a `static` and never be
    /// moved across a microcontroller's stack).
    pub const fn new(config: Config3d<'a>) -> Self {
        Tracker3d {
            config,
            tracks: heapless::Vec::new(),
            next_id: 1,
            frames: FrameOrder::new(),
            solver: Solver::new(),
            // Every entry a frame reads is written first in that frame.
            costs: [[0.0; N]; N],
            covariance_scale: CovarianceScale::new(),
            stats: Stats3d {
                frames: 0,
                rejected: 0,
                dropped_detections: 0,
                dropped_tracks: 0,
                refused_updates: 0,
                out_of_order_frames: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> &Stats3d {
        &self.stats
    }

    /// The factor the detections' stated covariances are scaled by (1 until learnt).
    pub fn covariance_scale(&self) -> f64 {
        self.covariance_scale.factor()
    }

    /// Whether a detection is plausible for its class.
    fn plausible(&self, d: &Detection3d) -> bool {
        let b = &d.bbox;
        let finite = [b.x, b.y, b.z, b.yaw, b.l, b.w, b.h].iter().all(|v| v.is_finite());
        let Some(class) = self.config.classes.get(usize::from(d.class)) else { return false };
        let size_ok = [b.l, b.w, b.h]
            .iter()
            .zip(class.min_size.iter().zip(&class.max_size))
            .all(|(v, (lo, hi))| v >= lo && v <= hi);
        let ground_ok = (b.z - (self.config.ground_z + b.h / 2.0)).abs() <= class.max_ground_offset;
        let covariance_ok = d.position_covariance.is_none_or(|[xx, xy, yy]| {
            [xx, xy, yy].iter().all(|v| v.is_finite()) && xx > 0.0 && yy > 0.0 && xx * yy > xy * xy
        });
        finite && (0.0..=1.0).contains(&d.score) && size_ok && ground_ok && covariance_ok
    }

    /// One frame: predict (over any gap since the previous frame number), associate,
    /// update, start and retire tracks; `emit` receives the tracks to report. A frame
    /// number not after the previous one is refused and counted; nothing changes.
    pub fn update(
        &mut self,
        frame: u64,
        detections: &[Detection3d],
        mut emit: impl FnMut(Track3dOutput),
    ) -> Result<(), TrackError> {
        let steps = self.frames.advance(frame).inspect_err(|_| self.stats.out_of_order_frames += 1)?;
        self.stats.frames += 1;
        let classes = self.config.classes;
        // Past max_age + 1 missed frames a track is retired anyway: no need to predict further.
        let predictions = steps.min(u64::from(self.config.max_age) + 1) as u32;
        for t in self.tracks.iter_mut() {
            // A track's class was checked against the table when it started.
            let Some(class) = classes.get(usize::from(t.class)) else { continue };
            let (f, q) = motion_model(&class.process_noise);
            for _ in 0..predictions {
                t.kf.predict(&f, &q);
            }
            t.kf.x[3] = wrap_angle(t.kf.x[3]);
            t.since_update = t.since_update.saturating_add(predictions);
        }
        // Plausible detections, at most N.
        let mut picked = heapless::Vec::<usize, N>::new();
        for (i, d) in detections.iter().enumerate() {
            if !self.plausible(d) {
                self.stats.rejected += 1;
            } else if picked.push(i).is_err() {
                self.stats.dropped_detections += 1;
            }
        }
        let tracks = &self.tracks;
        let cost = |t: usize, c: usize| -> Option<f64> {
            let (track, d) = (&tracks[t], &detections[picked[c]]);
            if track.class != d.class {
                return None;
            }
            let predicted = box_of(&track.kf.x);
            match classes.get(usize::from(d.class))?.association {
                Association::Giou(min) => {
                    let g = predicted.giou(&d.bbox);
                    (g >= min).then_some(-g)
                }
                Association::Distance(max) => {
                    let dist = predicted.centre_distance(&d.bbox);
                    (dist <= max).then_some(dist)
                }
            }
        };
        for (t, row) in self.costs.iter_mut().enumerate().take(self.tracks.len()) {
            for (c, slot) in row.iter_mut().enumerate().take(picked.len()) {
                *slot = cost(t, c).map_or(f32::NAN, |v| v as f32);
            }
        }
        let costs = &self.costs;
        let cached = |t: usize, c: usize| {
            let v = costs[t][c];
            (!v.is_nan()).then_some(f64::from(v))
        };
        let mut out = [None; N];
        if self.solver.solve_sparse(self.tracks.len(), picked.len(), cached, &mut out).is_err() {
            out = [None; N];
        }
        let mut used = [false; N];
        for (t, c) in out.iter().take(self.tracks.len()).enumerate() {
            let Some(c) = *c else { continue };
            used[c] = true;
            let d = &detections[picked[c]];
            let track = &mut self.tracks[t];
            let Some(class) = classes.get(usize::from(d.class)) else { continue };
            let (h, mut r) = measurement_model(&class.measurement_noise);
            if let Some([xx, xy, yy]) = d.position_covariance {
                let k = self.covariance_scale.factor();
                (r[(0, 0)], r[(0, 1)], r[(1, 0)], r[(1, 1)]) = (k * xx, k * xy, k * xy, k * yy);
                let (x, p) = (&track.kf.x, &track.kf.p);
                let innovation = [d.bbox.x - x[0], d.bbox.y - x[1]];
                self.covariance_scale.push(innovation, p[(0, 0)] + p[(1, 1)], xx + yy);
            }
            // Turn the prediction by π when the detection points the other way.
            let mut z = state_of(&d.bbox);
            let diff = wrap_angle(z[3] - track.kf.x[3]);
            if diff.abs() > PI / 2.0 {
                track.kf.x[3] = wrap_angle(track.kf.x[3] + PI);
            }
            z[3] = track.kf.x[3] + wrap_angle(z[3] - track.kf.x[3]);
            if track.kf.update(&z, &h, &r).is_err() {
                self.stats.refused_updates += 1;
            }
            track.kf.x[3] = wrap_angle(track.kf.x[3]);
            track.hits += 1;
            track.since_update = 0;
        }
        // Retire old tracks.
        let max_age = self.config.max_age;
        self.tracks.retain(|t| t.since_update <= max_age);
        // Start tracks from unmatched detections.
        for (c, &i) in picked.iter().enumerate() {
            if used[c] {
                continue;
            }
            if self.tracks.is_full() {
                self.stats.dropped_tracks += 1;
                let weakest = (0..self.tracks.len())
                    .filter(|&t| self.tracks[t].since_update > 0)
                    .min_by_key(|&t| self.tracks[t].hits);
                match weakest {
                    Some(t) => {
                        self.tracks.swap_remove(t);
                    }
                    None => continue,
                }
            }
            let d = &detections[i];
            let mut x = SVector::<f64, 10>::zeros();
            x.fixed_rows_mut::<7>(0).copy_from(&state_of(&d.bbox));
            let mut p = SMatrix::<f64, 10, 10>::identity() * 10.0;
            let velocity_variance =
                self.config.classes.get(usize::from(d.class)).map_or(1e4, |c| c.initial_velocity_variance);
            for k in 7..10 {
                p[(k, k)] = velocity_variance;
            }
            let _ = self.tracks.push(Track {
                id: self.next_id,
                class: d.class,
                kf: Kalman::new(x, p),
                hits: 1,
                since_update: 0,
            });
            self.next_id = self.next_id.wrapping_add(1).max(1);
        }
        let (min_hits, frames, static_speed) = (self.config.min_hits, self.stats.frames, self.config.static_speed);
        for t in
            self.tracks.iter().filter(|t| t.since_update == 0 && (t.hits >= min_hits || frames <= u64::from(min_hits)))
        {
            let v = [t.kf.x[7], t.kf.x[8], t.kf.x[9]];
            let is_static = libm::hypot(v[0], v[1]) < static_speed;
            let bbox = if is_static { box_of(&t.kf.x) } else { heading_along(box_of(&t.kf.x), v) };
            emit(Track3dOutput { id: t.id, class: t.class, bbox, velocity: v, is_static, state: t.kf });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const CLASSES: [ClassConfig; 2] = [
        // 0: car
        ClassConfig {
            association: Association::Giou(-0.2),
            min_size: [2.5, 1.4, 1.2],
            max_size: [6.5, 2.6, 2.5],
            max_ground_offset: 0.5,
            process_noise: AB3DMOT_PROCESS_NOISE,
            measurement_noise: AB3DMOT_MEASUREMENT_NOISE,
            initial_velocity_variance: 1e4,
        },
        // 1: cone
        ClassConfig {
            association: Association::Distance(1.0),
            min_size: [0.2, 0.2, 0.3],
            max_size: [0.8, 0.8, 1.2],
            max_ground_offset: 0.3,
            process_noise: AB3DMOT_PROCESS_NOISE,
            measurement_noise: AB3DMOT_MEASUREMENT_NOISE,
            initial_velocity_variance: 1e4,
        },
    ];

    fn config() -> Config3d<'static> {
        Config3d { classes: &CLASSES, min_hits: 3, max_age: 2, ground_z: 0.0, static_speed: 0.05 }
    }

    fn car(x: f64, yaw: f64) -> Detection3d {
        Detection3d::new(0, Box3d { x, y: 0.0, z: 0.8, yaw, l: 4.5, w: 1.9, h: 1.6 }, 0.9)
    }

    fn cone(x: f64, y: f64) -> Detection3d {
        Detection3d::new(1, Box3d { x, y, z: 0.35, yaw: 0.0, l: 0.4, w: 0.4, h: 0.7 }, 0.8)
    }

    fn frame<const N: usize>(t: &mut Tracker3d<'_, N>, dets: &[Detection3d]) -> heapless::Vec<Track3dOutput, 8> {
        let mut out = heapless::Vec::new();
        let next = t.stats().frames + 1;
        t.update(next, dets, |o| out.push(o).expect("room")).expect("frames in order");
        out
    }

    #[test]
    fn a_moving_car_and_a_cone_keep_their_ids_and_kinds() {
        let mut tracker = Tracker3d::<8>::new(config());
        let mut last = heapless::Vec::<Track3dOutput, 8>::new();
        let mut moving_frames = 0;
        for k in 0..10 {
            // The detector flips the car by π every third frame.
            let yaw = if k % 3 == 2 { PI - 0.01 } else { -0.01 };
            last = frame(&mut tracker, &[car(1.5 * f64::from(k), yaw), cone(20.0, 3.0 + 0.02 * f64::from(k % 2))]);
            if let Some(car_track) = last.iter().find(|o| o.class == 0) {
                // With the π correction the filter follows the flip instead of averaging
                // the two headings (which would leave it ~90° off) ...
                let off = wrap_angle(car_track.bbox.yaw - yaw).abs();
                assert!(off < 0.1 || (off - PI).abs() < 0.1, "frame {k}: {}", car_track.bbox.yaw);
                // ... and a moving track reports the heading it moves along, not the flip.
                if !car_track.is_static {
                    assert!(car_track.bbox.yaw.abs() < 0.1, "frame {k}: {}", car_track.bbox.yaw);
                    moving_frames += 1;
                }
            }
        }
        // The flipped frames among them (every third) are what the check above is for.
        assert!(moving_frames >= 6, "the car was reported moving in {moving_frames} frames");
        assert_eq!(last.len(), 2);
        let car_track = last.iter().find(|o| o.class == 0).expect("car");
        let cone_track = last.iter().find(|o| o.class == 1).expect("cone");
        assert_eq!((car_track.id, cone_track.id), (1, 2));
        assert!((car_track.velocity[0] - 1.5).abs() < 0.1, "{:?}", car_track.velocity);
        assert!(!car_track.is_static && cone_track.is_static);
    }

    #[test]
    fn frames_out_of_order_are_refused_and_counted() {
        let mut tracker = Tracker3d::<4>::new(config());
        assert_eq!(tracker.update(5, &[cone(1.0, 0.0)], |_| {}), Ok(()));
        assert_eq!(tracker.update(5, &[cone(1.0, 0.0)], |_| {}), Err(TrackError::OutOfOrder { previous: 5, frame: 5 }));
        assert_eq!(tracker.update(3, &[], |_| {}), Err(TrackError::OutOfOrder { previous: 5, frame: 3 }));
        assert_eq!((tracker.stats().out_of_order_frames, tracker.stats().frames), (2, 1));
        assert_eq!(tracker.tracks[0].hits, 1, "refused frames change nothing");
        // A gap longer than max_age retires the track without predicting frame by frame.
        assert_eq!(tracker.update(u64::MAX, &[], |_| {}), Ok(()));
        assert!(tracker.tracks.is_empty());
    }

    #[test]
    fn tracks_need_three_hits_after_the_start_and_die_after_two_misses() {
        let mut tracker = Tracker3d::<8>::new(config());
        for _ in 0..3 {
            frame(&mut tracker, &[]);
        }
        assert!(frame(&mut tracker, &[cone(5.0, 0.0)]).is_empty());
        assert!(frame(&mut tracker, &[cone(5.0, 0.0)]).is_empty());
        assert_eq!(frame(&mut tracker, &[cone(5.0, 0.0)]).len(), 1);
        frame(&mut tracker, &[]);
        frame(&mut tracker, &[]);
        // Two misses survived; the third kills it, so the cone comes back with a new id.
        frame(&mut tracker, &[]);
        let _ = frame(&mut tracker, &[cone(5.0, 0.0)]);
        assert_eq!(tracker.tracks.first().map(|t| t.id), Some(2));
    }

    #[test]
    fn impossible_detections_are_refused_and_counted() {
        let mut tracker = Tracker3d::<2>::new(config());
        let mut floating = cone(0.0, 0.0);
        floating.bbox.z = 3.0;
        let mut huge = car(0.0, 0.0);
        huge.bbox.l = 12.0;
        let mut nan = car(0.0, 0.0);
        nan.bbox.x = f64::NAN;
        let unknown = Detection3d { class: 7, ..car(0.0, 0.0) };
        let indefinite = Detection3d { position_covariance: Some([1.0, 2.0, 1.0]), ..car(0.0, 0.0) };
        let bad = [floating, huge, nan, unknown, Detection3d { score: 1.5, ..car(0.0, 0.0) }, indefinite];
        frame(&mut tracker, &bad);
        assert_eq!(tracker.stats().rejected, 6);
        assert!(tracker.tracks.is_empty());
        // Three cones for two slots.
        frame(&mut tracker, &[cone(0.0, 0.0), cone(5.0, 0.0), cone(10.0, 0.0)]);
        assert_eq!(tracker.stats().dropped_detections, 1);
    }

    /// Deterministic noise in [−a, a] (a small LCG; the core tests have no RNG crate).
    fn noise(state: &mut u64, a: f64) -> f64 {
        *state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0) * a
    }

    #[test]
    fn smoothing_a_track_beats_filtering_and_survives_gaps_and_flips() {
        let mut tracker = Tracker3d::<4>::new(config());
        let mut seed = 7;
        let mut frames = heapless::Vec::<u64, 64>::new();
        let mut steps = heapless::Vec::<SmoothStep<10>, 64>::new();
        let mut truth = heapless::Vec::<f64, 64>::new();
        for k in 0..40u32 {
            let x = 1.2 * f64::from(k);
            // Frames 20 and 21 are missed; from frame 25 on the detector flips the car.
            let yaw = if k >= 25 { PI - 0.02 } else { -0.02 };
            let mut d = car(x + noise(&mut seed, 0.8), yaw);
            d.bbox.y += noise(&mut seed, 0.8);
            if k == 20 || k == 21 {
                continue; // no frame at all: the tracker predicts over the gap
            }
            let reported = tracker.update(u64::from(k) + 1, &[d], |o| {
                let step = SmoothStep::filtered(&o.state);
                assert!(frames.push(u64::from(k) + 1).is_ok() && steps.push(step).is_ok() && truth.push(x).is_ok());
            });
            assert_eq!(reported, Ok(()));
        }
        let error = |steps: &[SmoothStep<10>]| {
            let sse: f64 = steps.iter().zip(&truth).skip(3).map(|(s, x)| (s.x[0] - x).powi(2) + s.x[1].powi(2)).sum();
            libm::sqrt(sse / (steps.len() - 3) as f64)
        };
        let filtered = error(&steps);
        assert_eq!(smooth_track(&frames, &mut steps, &AB3DMOT_PROCESS_NOISE), Ok(0));
        let smoothed = error(&steps);
        // With AB3DMOT's noise (Q = R on the position) filtering alone gains little.
        assert!(smoothed < 0.8 * filtered, "smoothed {smoothed} vs filtered {filtered}");
        // Every smoothed heading is the car's axis (either way round), not an average.
        for s in &steps {
            let off = wrap_angle(s.x[3] + 0.02);
            assert!(off.abs() < 0.1 || (off.abs() - PI).abs() < 0.1, "yaw {}", s.x[3]);
        }
        assert_eq!(smooth_track(&frames[1..], &mut steps, &AB3DMOT_PROCESS_NOISE), Err(SmoothError::LengthMismatch));
        frames.swap(3, 4);
        assert_eq!(smooth_track(&frames, &mut steps, &AB3DMOT_PROCESS_NOISE), Err(SmoothError::NotIncreasing));
    }

    #[test]
    fn learns_that_the_detector_is_too_sure_of_itself() {
        // A cone seen with ±0.6 m uniform noise (σ 0.35 m per axis, 0.12 m²) by a detector
        // stating 0.03 m²: four times too sure. The tracker learns to scale it by about 4.
        // (The factor rests on the filter's own prediction covariance being right: a static
        // class with AB3DMOT's metre of process noise per frame would drown it.)
        let still = ClassConfig {
            process_noise: [1e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4],
            initial_velocity_variance: 0.01,
            ..CLASSES[1]
        };
        let classes = [CLASSES[0], still];
        let config = Config3d { classes: &classes, ..config() };
        let mut state = 7;
        let mut learn = |stated: f64| {
            let mut tracker = Tracker3d::<2>::new(config);
            for _ in 0..400 {
                let d = Detection3d {
                    position_covariance: Some([stated, 0.0, stated]),
                    ..cone(5.0 + noise(&mut state, 0.6), noise(&mut state, 0.6))
                };
                frame(&mut tracker, &[d]);
            }
            tracker.covariance_scale()
        };
        let k = learn(0.03);
        assert!((3.0..5.5).contains(&k), "learnt factor {k}");
        // A detector that states its noise right is left alone.
        let k = learn(0.12);
        assert!((0.7..1.4).contains(&k), "learnt factor {k}");
    }

    #[test]
    fn a_detections_own_covariance_replaces_the_class_noise() {
        let run = |covariance| {
            let mut tracker = Tracker3d::<2>::new(config());
            frame(&mut tracker, &[cone(5.0, 0.0)]);
            let second = Detection3d { position_covariance: covariance, ..cone(6.0, 0.0) };
            frame(&mut tracker, &[second])[0].state.p
        };
        // The predicted variance (~1e4, from the unknown velocity) meets R: the posterior
        // variance is about R, whichever R was used.
        assert!((run(None)[(0, 0)] - 1.0).abs() < 1e-3, "{}", run(None)[(0, 0)]);
        let own = run(Some([1e-6, 0.0, 4e-6]));
        assert!((own[(0, 0)] - 1e-6).abs() < 1e-9 && (own[(1, 1)] - 4e-6).abs() < 1e-9, "{own}");
    }

    fn any_value() -> impl proptest::strategy::Strategy<Value = f64> {
        use proptest::prelude::*;
        prop_oneof![
            -50.0f64..50.0,
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(-1e300),
            Just(0.0),
            proptest::num::f64::ANY,
        ]
    }

    proptest::proptest! {
        /// Whatever the detections — NaN, infinities, huge or zero sizes, any class or
        /// score, any covariance — the tracker never panics, reports each id at most once
        /// per frame and never more than N tracks, and every detection is used, refused or
        /// dropped.
        #[test]
        fn hostile_detections_are_refused_or_tracked_never_a_panic(
            frames in proptest::collection::vec(
                proptest::collection::vec(
                    (0u16..3, proptest::array::uniform7(any_value()), any_value(),
                     proptest::option::of(proptest::array::uniform3(any_value()))),
                    0..12),
                1..12)
        ) {
            let mut tracker = Tracker3d::<4>::new(config());
            let mut plausible = 0u64;
            for frame_detections in &frames {
                let dets: heapless::Vec<Detection3d, 12> = frame_detections
                    .iter()
                    .map(|&(class, [x, y, z, yaw, l, w, h], score, position_covariance)| Detection3d {
                        class,
                        bbox: Box3d { x, y, z, yaw, l, w, h },
                        score,
                        position_covariance,
                    })
                    .collect();
                plausible += dets.iter().filter(|d| tracker.plausible(d)).count() as u64;
                let mut ids = heapless::Vec::<u32, 8>::new();
                let next = tracker.stats().frames + 1;
                let result = tracker.update(next, &dets, |o| {
                    assert!(!ids.contains(&o.id), "id {} twice", o.id);
                    assert!(ids.push(o.id).is_ok(), "more than N tracks reported");
                    assert!(o.state.x.iter().all(|v| v.is_finite()));
                });
                proptest::prop_assert!(result.is_ok());
            }
            let stats = *tracker.stats();
            let total: u64 = frames.iter().map(|f| f.len() as u64).sum();
            proptest::prop_assert_eq!(stats.rejected + plausible, total);
            proptest::prop_assert!(stats.dropped_detections <= plausible);
        }
    }

    #[test]
    fn angles_wrap() {
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_angle(-PI) + PI).abs() < 1e-12);
        assert_eq!(wrap_angle(f64::NAN), 0.0);
    }
}
