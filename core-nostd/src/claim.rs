//! Claim-and-suppress (Algorithm 1 of the Dash2Sim paper; docs/tracking.md): turning per-frame
//! detections into object tracks with a video propagator (the paper's SAM3) that, given
//! prompts in one frame, follows each prompted object through the clip.
//!
//! Per class, in rounds: the highest-scoring still-active detection is the exemplar
//! (stop when it scores below τ_ex or after K_c rounds); same-frame, same-class active
//! detections scoring at least τ_co join as co-prompts; the propagator returns one
//! tubelet per prompt; every active detection of the class that a tubelet box overlaps
//! in its frame with IoU > τ_iou is retired (claimed), each non-empty tubelet gets a new
//! globally unique id, and the prompts are retired. If the propagator returns nothing,
//! only the exemplar is retired, so the co-prompts get their own turn.
//!
//! Allocation-free: the caller owns the detections; `Claimer<N, P>` keeps N activity
//! flags and at most P prompts per round.

use crate::box2d::Box2d;

/// A detection to claim.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClaimDetection {
    /// Frame index.
    pub frame: u32,
    /// Class.
    pub class: u16,
    /// Box.
    pub bbox: Box2d,
    /// Score in [0, 1].
    pub score: f64,
}

/// Thresholds of Algorithm 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClaimConfig {
    /// τ_ex: least score of an exemplar.
    pub exemplar_score: f64,
    /// τ_co: least score of a co-prompt.
    pub co_prompt_score: f64,
    /// τ_iou: a tubelet claims detections it overlaps with more than this IoU.
    pub claim_iou: f64,
    /// K_c: rounds per class at most.
    pub max_rounds: u32,
}

impl Default for ClaimConfig {
    fn default() -> Self {
        ClaimConfig { exemplar_score: 0.5, co_prompt_score: 0.7, claim_iou: 0.5, max_rounds: 64 }
    }
}

/// Follows prompted objects through the clip (a video segmenter, or a test double).
pub trait Propagator {
    /// `prompts` index `detections` (all in one frame). Call `emit(k, frame, box)` for
    /// every box of the tubelet of prompt `k`.
    fn propagate(&mut self, detections: &[ClaimDetection], prompts: &[usize], emit: &mut dyn FnMut(usize, u32, Box2d));
}

/// Why a detection was retired.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Retired {
    /// It was the exemplar of a round.
    Exemplar,
    /// It was a co-prompt of a round with a non-empty result.
    CoPrompt,
    /// A tubelet of track `id` overlapped it.
    Claimed {
        /// The claiming track.
        id: u32,
    },
}

/// What the claimer reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClaimEvent {
    /// One box of a track.
    TrackBox {
        /// Globally unique track id.
        id: u32,
        /// Frame.
        frame: u32,
        /// Box.
        bbox: Box2d,
    },
    /// A detection left the active set.
    Retired {
        /// Its index.
        detection: usize,
        /// Why.
        reason: Retired,
    },
}

/// Why a run was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClaimError {
    /// More detections than the claimer's capacity.
    TooMany,
}

impl core::fmt::Display for ClaimError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ClaimError::TooMany => write!(f, "more detections than the claimer holds"),
        }
    }
}

impl core::error::Error for ClaimError {}

/// Counters of one run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClaimStats {
    /// Propagator calls.
    pub rounds: u32,
    /// Tracks created.
    pub tracks: u32,
    /// Detections retired.
    pub retired: u32,
    /// Detections ignored: bad box or score outside [0, 1].
    pub rejected: u32,
    /// Co-prompts left out because a round already had P prompts.
    pub prompts_dropped: u32,
}

/// Claim-and-suppress over up to `N` detections with up to `P` prompts per round.
#[derive(Clone, Debug)]
pub struct Claimer<const N: usize, const P: usize = 8> {
    config: ClaimConfig,
    active: [bool; N],
    next_id: u32,
}

impl<const N: usize, const P: usize> Claimer<N, P> {
    /// A claimer whose first track id is 1.
    pub fn new(config: ClaimConfig) -> Self {
        Claimer { config, active: [false; N], next_id: 1 }
    }

    /// Run Algorithm 1 over `detections`. Ids continue across runs (global re-id).
    pub fn run(
        &mut self,
        detections: &[ClaimDetection],
        propagator: &mut impl Propagator,
        mut emit: impl FnMut(ClaimEvent),
    ) -> Result<ClaimStats, ClaimError> {
        let active = self.active.get_mut(..detections.len()).ok_or(ClaimError::TooMany)?;
        let mut stats = ClaimStats::default();
        for (flag, d) in active.iter_mut().zip(detections) {
            let b = d.bbox;
            *flag = Box2d::new(b.x, b.y, b.w, b.h).is_ok() && (0.0..=1.0).contains(&d.score);
            stats.rejected += u32::from(!*flag);
        }
        // Classes in order of first appearance, each handled once.
        for (first, class) in detections.iter().map(|d| d.class).enumerate() {
            if detections[..first].iter().any(|d| d.class == class) {
                continue;
            }
            for _ in 0..self.config.max_rounds {
                let Some(exemplar) = (0..detections.len())
                    .filter(|&i| self.active[i] && detections[i].class == class)
                    .max_by(|&a, &b| detections[a].score.total_cmp(&detections[b].score).then(b.cmp(&a)))
                    .filter(|&i| detections[i].score >= self.config.exemplar_score)
                else {
                    break;
                };
                let frame = detections[exemplar].frame;
                let mut prompts = heapless::Vec::<usize, P>::new();
                if prompts.push(exemplar).is_err() {
                    break; // P == 0: nothing can be prompted.
                }
                for (i, d) in detections.iter().enumerate() {
                    if i != exemplar
                        && self.active[i]
                        && d.class == class
                        && d.frame == frame
                        && d.score >= self.config.co_prompt_score
                        && prompts.push(i).is_err()
                    {
                        stats.prompts_dropped += 1;
                    }
                }
                stats.rounds += 1;
                let mut ids = [None::<u32>; P];
                let (config, active, next_id) = (&self.config, &mut self.active, &mut self.next_id);
                let mut any = false;
                propagator.propagate(detections, &prompts, &mut |k, box_frame, bbox| {
                    let Some(slot) = ids.get_mut(k) else { return };
                    let id = *slot.get_or_insert_with(|| {
                        let id = *next_id;
                        *next_id = next_id.wrapping_add(1).max(1);
                        stats.tracks += 1;
                        id
                    });
                    any = true;
                    emit(ClaimEvent::TrackBox { id, frame: box_frame, bbox });
                    for (i, d) in detections.iter().enumerate() {
                        if active[i]
                            && d.class == class
                            && d.frame == box_frame
                            && !prompts.contains(&i)
                            && d.bbox.iou(&bbox) > config.claim_iou
                        {
                            active[i] = false;
                            stats.retired += 1;
                            emit(ClaimEvent::Retired { detection: i, reason: Retired::Claimed { id } });
                        }
                    }
                });
                for &i in prompts.iter().take(if any { P } else { 1 }) {
                    self.active[i] = false;
                    stats.retired += 1;
                    let reason = if i == exemplar { Retired::Exemplar } else { Retired::CoPrompt };
                    emit(ClaimEvent::Retired { detection: i, reason });
                }
            }
        }
        Ok(stats)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A propagator that knows the true objects: each prompt becomes the object whose
    /// box in the prompt's frame overlaps it most, returned over every frame.
    struct Oracle<'a> {
        /// (object, frame, box)
        truth: &'a [(u8, u32, Box2d)],
        /// Return nothing for this many calls (to test empty tubelets).
        empty_calls: u32,
    }

    impl Propagator for Oracle<'_> {
        fn propagate(
            &mut self,
            detections: &[ClaimDetection],
            prompts: &[usize],
            emit: &mut dyn FnMut(usize, u32, Box2d),
        ) {
            if self.empty_calls > 0 {
                self.empty_calls -= 1;
                return;
            }
            for (k, &p) in prompts.iter().enumerate() {
                let d = &detections[p];
                let best = self
                    .truth
                    .iter()
                    .filter(|t| t.1 == d.frame && t.2.iou(&d.bbox) > 0.3)
                    .max_by(|a, b| a.2.iou(&d.bbox).total_cmp(&b.2.iou(&d.bbox)));
                if let Some(&(object, _, _)) = best {
                    for t in self.truth.iter().filter(|t| t.0 == object) {
                        emit(k, t.1, t.2);
                    }
                }
            }
        }
    }

    fn bx(x: f64) -> Box2d {
        Box2d { x, y: 0.0, w: 10.0, h: 10.0 }
    }

    /// Two objects over three frames; detections jittered, one false positive.
    fn scene() -> ([(u8, u32, Box2d); 6], [ClaimDetection; 7]) {
        let truth =
            [(0, 0, bx(0.0)), (0, 1, bx(2.0)), (0, 2, bx(4.0)), (1, 0, bx(50.0)), (1, 1, bx(52.0)), (1, 2, bx(54.0))];
        let det = |frame, x, score| ClaimDetection { frame, class: 1, bbox: bx(x), score };
        let dets = [
            det(0, 0.5, 0.9),
            det(1, 2.5, 0.6),
            det(2, 3.5, 0.8),
            det(0, 50.5, 0.95),
            det(1, 51.0, 0.7),
            det(2, 54.0, 0.65),
            det(1, 200.0, 0.55),
        ];
        (truth, dets)
    }

    fn collect(
        claimer: &mut Claimer<16, 4>,
        dets: &[ClaimDetection],
        oracle: &mut Oracle<'_>,
    ) -> (heapless::Vec<ClaimEvent, 64>, ClaimStats) {
        let mut events = heapless::Vec::new();
        let stats = claimer.run(dets, oracle, |e| events.push(e).expect("room")).expect("fits");
        (events, stats)
    }

    #[test]
    fn two_objects_two_tracks_and_the_false_positive_retired_alone() {
        let (truth, dets) = scene();
        let mut claimer = Claimer::<16, 4>::new(ClaimConfig::default());
        let (events, stats) = collect(&mut claimer, &dets, &mut Oracle { truth: &truth, empty_calls: 0 });
        // Round 1: exemplar 3 (0.95) with co-prompt 0 (0.9, frame 0) → both objects.
        // Round 2: the false positive (0.55) → empty tubelet, retired as exemplar.
        assert_eq!((stats.rounds, stats.tracks, stats.retired), (2, 2, 7));
        let claimed = |i: usize| {
            events.iter().find_map(|e| match e {
                ClaimEvent::Retired { detection, reason } if *detection == i => Some(*reason),
                _ => None,
            })
        };
        assert_eq!(claimed(3), Some(Retired::Exemplar));
        assert_eq!(claimed(0), Some(Retired::CoPrompt));
        assert_eq!(claimed(4), Some(Retired::Claimed { id: 1 }));
        assert_eq!(claimed(1), Some(Retired::Claimed { id: 2 }));
        assert_eq!(claimed(6), Some(Retired::Exemplar));
    }

    #[test]
    fn an_empty_tubelet_retires_only_its_exemplar() {
        let (truth, dets) = scene();
        let mut claimer = Claimer::<16, 4>::new(ClaimConfig::default());
        let (events, _) = collect(&mut claimer, &dets, &mut Oracle { truth: &truth, empty_calls: 1 });
        // First round returns nothing: only detection 3 is retired; 0 prompts the next.
        assert_eq!(events[0], ClaimEvent::Retired { detection: 3, reason: Retired::Exemplar });
        assert!(matches!(events[1], ClaimEvent::TrackBox { id: 1, frame: 0, .. }));
    }

    proptest! {
        #[test]
        fn every_retirement_is_explained_ids_unique_rounds_bounded_and_deterministic(
            raw in proptest::collection::vec((0u32..4, 0u16..2, 0.0f64..100.0, 0.0f64..1.2), 0..16),
            max_rounds in 0u32..6,
        ) {
            let truth: heapless::Vec<(u8, u32, Box2d), 16> =
                (0..4).flat_map(|f| [(0, f, bx(10.0 * f as f64)), (1, f, bx(60.0 + f as f64))]).collect();
            let dets: heapless::Vec<ClaimDetection, 16> =
                raw.iter().map(|&(frame, class, x, score)| ClaimDetection { frame, class, bbox: bx(x), score }).collect();
            let config = ClaimConfig { max_rounds, ..ClaimConfig::default() };
            let run = || {
                let mut claimer = Claimer::<16, 4>::new(config);
                let mut events = heapless::Vec::<ClaimEvent, 256>::new();
                let stats = claimer.run(&dets, &mut Oracle { truth: &truth, empty_calls: 0 }, |e| { let _ = events.push(e); }).expect("fits");
                (events, stats)
            };
            let (events, stats) = run();
            prop_assert_eq!(&run(), &(events.clone(), stats), "same input, same output");
            // K_c: at most max_rounds propagator calls per class (two classes).
            prop_assert!(stats.rounds <= 2 * max_rounds);
            let mut retired = [false; 16];
            let mut ids = heapless::Vec::<u32, 64>::new();
            let boxes_of = |id: u32, frame: u32| events.iter().filter_map(move |e| match e {
                ClaimEvent::TrackBox { id: i, frame: f, bbox } if *i == id && *f == frame => Some(*bbox),
                _ => None,
            });
            for e in &events {
                match e {
                    ClaimEvent::TrackBox { id, .. } => { if !ids.contains(id) { let _ = ids.push(*id); } }
                    ClaimEvent::Retired { detection, reason } => {
                        prop_assert!(!retired[*detection], "retired twice");
                        retired[*detection] = true;
                        if let Retired::Claimed { id } = reason {
                            let d = &dets[*detection];
                            prop_assert!(boxes_of(*id, d.frame).any(|b| b.iou(&d.bbox) > config.claim_iou), "unexplained claim");
                        }
                    }
                }
            }
            // Ids are 1..=tracks, each once.
            prop_assert_eq!(ids.len() as u32, stats.tracks);
            for (k, id) in ids.iter().enumerate() { prop_assert_eq!(*id, k as u32 + 1); }
        }
    }
}
