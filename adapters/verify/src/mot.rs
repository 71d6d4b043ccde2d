//! Multi-object tracking metrics: MOTChallenge rows ([`dash2sim_linux::ingest::motchallenge`]) in,
//! CLEAR-MOT and identity metrics out — with motmetrics' definitions, names and conventions (motmetrics 1.4,
//! `compare_to_groundtruth(gt, test, 'iou', distth=0.5)`), so the numbers can be compared
//! one to one. docs/mot.md states each definition.

use std::collections::{BTreeSet, HashMap};

use dash2sim_core::assign::{AssignError, Workspace};

use dash2sim_linux::ingest::motchallenge::MotRow;

/// What happened to an object or hypothesis in one frame (motmetrics' event types; the
/// RAW events are kept separately, as per-frame counts).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventKind {
    /// Object matched to the hypothesis it had before (or its first one).
    Match,
    /// Object matched to a different hypothesis than before.
    Switch,
    /// Object not matched.
    Miss,
    /// Hypothesis not matched.
    FalsePositive,
    /// A switch to a hypothesis never matched before.
    Ascend,
    /// The hypothesis was matched to a different object before.
    Transfer,
    /// A transfer to an object never matched before.
    Migrate,
}

/// One event.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Event {
    /// Frame.
    pub frame: i64,
    /// Kind.
    pub kind: EventKind,
    /// Object id.
    pub object: Option<i64>,
    /// Hypothesis id.
    pub hypothesis: Option<i64>,
    /// 1 − IoU for matches.
    pub distance: Option<f64>,
}

/// Who appeared in a frame and which pairs were close enough to match.
#[derive(Clone, Debug, Default)]
struct Raw {
    /// Frames in which each object appeared.
    object_frames: HashMap<i64, u64>,
    /// Frames in which each hypothesis appeared.
    hypothesis_frames: HashMap<i64, u64>,
    /// Frames in which each (object, hypothesis) pair was within the threshold.
    pair_frames: HashMap<(i64, i64), u64>,
}

/// motmetrics' `MOTAccumulator`: frame-by-frame events with carried-forward matches.
#[derive(Clone, Debug, Default)]
pub struct Accumulator {
    events: Vec<Event>,
    raw: Raw,
    frames: u64,
    /// Object → hypothesis it was last matched to.
    m: HashMap<i64, i64>,
    /// Hypothesis → object it was last matched to (set by the assignment step only).
    res_m: HashMap<i64, i64>,
    last_match: HashMap<i64, i64>,
    hypothesis_history: HashMap<i64, i64>,
}

/// Solve an assignment of any size on the heap with the core's algorithm.
pub fn solve_sparse(
    rows: usize,
    cols: usize,
    cost: impl Fn(usize, usize) -> Option<f64>,
) -> Result<Vec<Option<usize>>, AssignError> {
    let n = rows.max(cols);
    let (mut u, mut v, mut shortest) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut path, mut col4row, mut row4col, mut remaining) = (vec![0; n], vec![0; n], vec![0; n], vec![0; n]);
    let (mut seen_rows, mut seen_cols) = (vec![false; n], vec![false; n]);
    let mut workspace = Workspace {
        u: &mut u,
        v: &mut v,
        shortest: &mut shortest,
        path: &mut path,
        col4row: &mut col4row,
        row4col: &mut row4col,
        seen_rows: &mut seen_rows,
        seen_cols: &mut seen_cols,
        remaining: &mut remaining,
    };
    let mut out = vec![None; rows];
    workspace.solve_sparse(rows, cols, cost, &mut out)?;
    Ok(out)
}

impl Accumulator {
    /// Add one frame: object ids, hypothesis ids and their distances (`None` = may not
    /// pair). Follows motmetrics' `MOTAccumulator.update`.
    pub fn update(
        &mut self,
        frame: i64,
        objects: &[i64],
        hypotheses: &[i64],
        distance: impl Fn(usize, usize) -> Option<f64>,
    ) {
        self.frames += 1;
        for &o in objects {
            *self.raw.object_frames.entry(o).or_default() += 1;
        }
        for &h in hypotheses {
            *self.raw.hypothesis_frames.entry(h).or_default() += 1;
        }
        for (i, &o) in objects.iter().enumerate() {
            for (j, &h) in hypotheses.iter().enumerate() {
                if distance(i, j).is_some() {
                    *self.raw.pair_frames.entry((o, h)).or_default() += 1;
                }
            }
        }
        let mut object_done = vec![false; objects.len()];
        let mut hypothesis_done = vec![false; hypotheses.len()];
        let event = |kind, object, hypothesis, distance| Event { frame, kind, object, hypothesis, distance };
        if !objects.is_empty() && !hypotheses.is_empty() {
            // 1. Carry forward established pairs that are still close enough.
            for (i, &o) in objects.iter().enumerate() {
                let Some(&previous) = self.m.get(&o) else { continue };
                let Some(j) = (0..hypotheses.len()).find(|&j| !hypothesis_done[j] && hypotheses[j] == previous) else {
                    continue;
                };
                if let Some(d) = distance(i, j) {
                    object_done[i] = true;
                    hypothesis_done[j] = true;
                    self.last_match.insert(o, frame);
                    self.hypothesis_history.insert(previous, frame);
                    self.events.push(event(EventKind::Match, Some(o), Some(previous), Some(d)));
                }
            }
            // 2. Minimum-cost assignment of the rest.
            let free = |i: usize, j: usize| if object_done[i] || hypothesis_done[j] { None } else { distance(i, j) };
            let assignment = solve_sparse(objects.len(), hypotheses.len(), free).unwrap_or_default();
            for (i, j) in assignment.iter().enumerate() {
                let Some(j) = *j else { continue };
                let Some(d) = free(i, j) else { continue };
                let (o, h) = (objects[i], hypotheses[j]);
                let switch = self.m.get(&o).is_some_and(|&previous| previous != h);
                if switch && !self.hypothesis_history.contains_key(&h) {
                    self.events.push(event(EventKind::Ascend, Some(o), Some(h), Some(d)));
                }
                if self.res_m.get(&h).is_some_and(|&previous| previous != o) {
                    if !self.last_match.contains_key(&o) {
                        self.events.push(event(EventKind::Migrate, Some(o), Some(h), Some(d)));
                    }
                    self.events.push(event(EventKind::Transfer, Some(o), Some(h), Some(d)));
                }
                self.hypothesis_history.insert(h, frame);
                self.last_match.insert(o, frame);
                let kind = if switch { EventKind::Switch } else { EventKind::Match };
                self.events.push(event(kind, Some(o), Some(h), Some(d)));
                self.m.insert(o, h);
                self.res_m.insert(h, o);
            }
            // `free` borrowed the masks; mark the assigned pairs now.
            for (i, j) in assignment.iter().enumerate() {
                if let Some(j) = *j {
                    if !object_done[i] && !hypothesis_done[j] && distance(i, j).is_some() {
                        object_done[i] = true;
                        hypothesis_done[j] = true;
                    }
                }
            }
        }
        for (i, &o) in objects.iter().enumerate() {
            if !object_done[i] {
                self.events.push(event(EventKind::Miss, Some(o), None, None));
            }
        }
        for (j, &h) in hypotheses.iter().enumerate() {
            if !hypothesis_done[j] {
                self.events.push(event(EventKind::FalsePositive, None, Some(h), None));
            }
        }
    }

    /// Every event so far, in order.
    pub fn events(&self) -> &[Event] {
        &self.events
    }
}

/// Compare ground truth with a tracker's output frame by frame (IoU distance, pairs with
/// 1 − IoU above `max_distance` may not match).
pub fn compare(gt: &[MotRow], test: &[MotRow], max_distance: f64) -> Accumulator {
    let frames: BTreeSet<i64> = gt.iter().chain(test).map(|r| r.frame).collect();
    let mut by_frame: HashMap<i64, (Vec<&MotRow>, Vec<&MotRow>)> = HashMap::new();
    for r in gt {
        by_frame.entry(r.frame).or_default().0.push(r);
    }
    for r in test {
        by_frame.entry(r.frame).or_default().1.push(r);
    }
    let mut acc = Accumulator::default();
    for frame in frames {
        let (objects, hypotheses) = by_frame.remove(&frame).unwrap_or_default();
        let oids: Vec<i64> = objects.iter().map(|r| r.id).collect();
        let hids: Vec<i64> = hypotheses.iter().map(|r| r.id).collect();
        let distance = |i: usize, j: usize| {
            let d = 1.0 - objects[i].bbox.iou(&hypotheses[j].bbox);
            (d <= max_distance).then_some(d)
        };
        acc.update(frame, &oids, &hids, distance);
    }
    acc
}

/// motmetrics' summary metrics, by its names.
#[derive(Clone, Debug, PartialEq)]
pub struct Summary {
    /// (name, value) in motmetrics' `motchallenge_metrics` order plus the counts.
    pub values: Vec<(&'static str, f64)>,
}

impl Summary {
    /// A metric by motmetrics' name.
    pub fn get(&self, name: &str) -> Option<f64> {
        self.values.iter().find(|(n, _)| *n == name).map(|(_, v)| *v)
    }
}

/// An object of the metrics by motmetrics' names (`mot --json`, the scenario's `metrics`).
impl serde::Serialize for Summary {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_map(self.values.iter().map(|(k, v)| (k, v)))
    }
}

fn quiet_divide(a: f64, b: f64) -> f64 {
    if b == 0.0 {
        f64::NAN
    } else {
        a / b
    }
}

/// Compute the summary of an accumulator (motmetrics' `compute(..., motchallenge_metrics + counts)`).
pub fn summarize(acc: &Accumulator) -> Summary {
    let events = acc.events();
    let count = |kind: EventKind| events.iter().filter(|e| e.kind == kind).count() as f64;
    let (matches, switches, misses, fps) =
        (count(EventKind::Match), count(EventKind::Switch), count(EventKind::Miss), count(EventKind::FalsePositive));
    let detections = matches + switches;
    let counted = |e: &&Event| {
        matches!(e.kind, EventKind::Match | EventKind::Switch | EventKind::Miss | EventKind::FalsePositive)
    };
    // Per object: appearances and frames tracked; in event order for fragmentation.
    let mut object_events: HashMap<i64, Vec<bool>> = HashMap::new();
    let mut predictions = 0.0;
    let mut distance_sum = 0.0;
    for e in events.iter().filter(counted) {
        if let Some(o) = e.object {
            object_events.entry(o).or_default().push(e.kind != EventKind::Miss);
        }
        if e.hypothesis.is_some() {
            predictions += 1.0;
        }
        distance_sum += e.distance.unwrap_or(0.0);
    }
    let objects: f64 = object_events.values().map(|v| v.len() as f64).sum();
    let (mut mostly_tracked, mut partially_tracked, mut mostly_lost, mut fragmentations) = (0.0, 0.0, 0.0, 0.0);
    for tracked in object_events.values() {
        let ratio = tracked.iter().filter(|&&t| t).count() as f64 / tracked.len() as f64;
        if ratio >= 0.8 {
            mostly_tracked += 1.0;
        } else if ratio >= 0.2 {
            partially_tracked += 1.0;
        } else {
            mostly_lost += 1.0;
        }
        if let (Some(first), Some(last)) = (tracked.iter().position(|&t| t), tracked.iter().rposition(|&t| t)) {
            fragmentations += tracked[first..=last].windows(2).filter(|w| w[0] && !w[1]).count() as f64;
        }
    }
    let (idfp, idfn) = identity_errors(&acc.raw);
    let idtp = objects - idfn;
    Summary {
        values: vec![
            ("idf1", quiet_divide(2.0 * idtp, objects + predictions)),
            ("idp", quiet_divide(idtp, idtp + idfp)),
            ("idr", quiet_divide(idtp, idtp + idfn)),
            ("recall", quiet_divide(detections, objects)),
            ("precision", quiet_divide(detections, fps + detections)),
            ("num_unique_objects", object_events.len() as f64),
            ("mostly_tracked", mostly_tracked),
            ("partially_tracked", partially_tracked),
            ("mostly_lost", mostly_lost),
            ("num_false_positives", fps),
            ("num_misses", misses),
            ("num_switches", switches),
            ("num_fragmentations", fragmentations),
            ("mota", 1.0 - quiet_divide(misses + switches + fps, objects)),
            ("motp", quiet_divide(distance_sum, detections)),
            ("num_transfer", count(EventKind::Transfer)),
            ("num_ascend", count(EventKind::Ascend)),
            ("num_migrate", count(EventKind::Migrate)),
            ("num_frames", acc.frames as f64),
            ("num_objects", objects),
            ("num_predictions", predictions),
            ("num_matches", matches),
            ("num_detections", detections),
            ("idtp", idtp),
            ("idfp", idfp),
            ("idfn", idfn),
        ],
    }
}

/// IDF1's global assignment (Ristani et al. 2016, as motmetrics builds it): objects and
/// hypotheses matched one to one over the whole sequence, each real pair costing the
/// frames they disagree, each object or hypothesis left alone costing all its frames.
/// Returns (IDFP, IDFN).
fn identity_errors(raw: &Raw) -> (f64, f64) {
    let mut oids: Vec<i64> = raw.object_frames.keys().copied().collect();
    let mut hids: Vec<i64> = raw.hypothesis_frames.keys().copied().collect();
    oids.sort_unstable();
    hids.sort_unstable();
    let (no, nh) = (oids.len(), hids.len());
    let n = no + nh;
    // fp[r][c], fn[r][c]; None = forbidden.
    let fp_fn = |r: usize, c: usize| -> Option<(f64, f64)> {
        match (r < no, c < nh) {
            (true, true) => {
                let (o, h) = (oids[r], hids[c]);
                let tp = raw.pair_frames.get(&(o, h)).copied().unwrap_or(0) as f64;
                Some((raw.hypothesis_frames[&h] as f64 - tp, raw.object_frames[&o] as f64 - tp))
            }
            // Object left unmatched (only its own dummy column).
            (true, false) => (c - nh == r).then(|| (0.0, raw.object_frames[&oids[r]] as f64)),
            // Hypothesis left unmatched (only its own dummy row).
            (false, true) => (r - no == c).then(|| (raw.hypothesis_frames[&hids[c]] as f64, 0.0)),
            (false, false) => Some((0.0, 0.0)),
        }
    };
    let assignment = solve_sparse(n, n, |r, c| fp_fn(r, c).map(|(fp, fn_)| fp + fn_)).unwrap_or_default();
    let (mut idfp, mut idfn) = (0.0, 0.0);
    for (r, c) in assignment.iter().enumerate() {
        if let Some((fp, fn_)) = c.and_then(|c| fp_fn(r, c)) {
            idfp += fp;
            idfn += fn_;
        }
    }
    (idfp, idfn)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn switch_ascend_and_transfer_like_motmetrics() {
        // motmetrics' README example; the expected events are motmetrics 1.4's output.
        let mut acc = Accumulator::default();
        let d = |m: &'static [[Option<f64>; 3]]| move |i: usize, j: usize| m[i][j];
        acc.update(
            0,
            &[1, 2],
            &[1, 2, 3],
            d(&[[Some(0.1), None, Some(0.3)], [Some(0.5), Some(0.2), Some(0.3)], [None; 3]]),
        );
        acc.update(1, &[1, 2], &[1, 2, 3], d(&[[Some(0.6), None, Some(0.1)], [None, Some(0.2), None], [None; 3]]));
        let kinds: Vec<_> = acc.events().iter().map(|e| (e.frame, e.kind, e.object, e.hypothesis)).collect();
        assert_eq!(
            kinds,
            [
                (0, EventKind::Match, Some(1), Some(1)),
                (0, EventKind::Match, Some(2), Some(2)),
                (0, EventKind::FalsePositive, None, Some(3)),
                (1, EventKind::Match, Some(1), Some(1)),
                (1, EventKind::Match, Some(2), Some(2)),
                (1, EventKind::FalsePositive, None, Some(3)),
            ]
        );
        acc.update(2, &[1, 2], &[1, 3], d(&[[None, Some(0.1), None], [Some(0.4), None, None], [None; 3]]));
        let last: Vec<_> = acc.events()[6..].iter().map(|e| (e.kind, e.object, e.hypothesis)).collect();
        assert_eq!(
            last,
            [
                (EventKind::Ascend, Some(1), Some(3)),
                (EventKind::Switch, Some(1), Some(3)),
                (EventKind::Transfer, Some(2), Some(1)),
                (EventKind::Switch, Some(2), Some(1)),
            ]
        );
    }
}
