//! Junctions for nuPlan: where lanes cross or join, nuPlan wants lane connectors, not lanes.
//!
//! Two lanes under one point make nuPlan's route extraction fail ("2 map objects found"),
//! and OSM ways are not split where other ways join them, so the tile's lanes (offset
//! copies of the ways) overlap at every junction. This module cuts each lane into
//! **pieces** that overlap no other lane: it samples every centreline, marks where another
//! lane comes closer than their half widths together, and leaves those stretches — and the
//! ends of lanes that join their successors — as **gaps**. Gaps that overlap each other or
//! meet through a successor relation form one **junction**; every piece ending at a
//! junction is joined to every piece leaving it, except U-turns and lane changes.
//!
//! Lanes of one roadblock (same-direction neighbours) are cut at the same places, so that
//! a roadblock is a run of pieces side by side.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use dash2sim_linux::geometry::{band, cut, heading_at, is_simple, nearest_arc, point_at, segment_distance};

/// Sampling step along a centreline when looking for overlaps, m.
const STEP_M: f64 = 0.5;
/// Lanes overlap when their centrelines come closer than the sum of their half widths
/// minus this (side-by-side lanes are exactly that far apart), m.
const TOLERANCE_M: f64 = 0.005;
/// Length kept as a gap at a lane end that joins another lane, m (at most a quarter of the
/// lane): room for the connector where two ways meet at an angle.
const TRIM_M: f64 = 2.0;
/// Pieces shorter than this are left to the junction, m.
const MIN_PIECE_M: f64 = 1.0;
/// Turns sharper than this are U-turns and get no connector, rad (150°).
const MAX_TURN: f64 = 2.618;
/// Entries and exits of a junction farther apart than this are not joined, m.
const MAX_JOIN_M: f64 = 50.0;
/// Where a lane meets its successor, the stretch of the other lane (from the shared end)
/// whose nearness is the joint itself, not an overlap, m.
const JOINT_M: f64 = 0.5;
/// Grid cell of the segment index, m.
const CELL_M: f64 = 20.0;

/// One tile lane as the junction finder sees it.
#[derive(Debug, Clone)]
pub struct LaneShape {
    /// Centreline in driving order, projected metres.
    pub centre: Vec<(f64, f64)>,
    /// Width, m.
    pub width: f64,
    /// Lanes it continues into (tile indices).
    pub successors: Vec<usize>,
    /// Whether some lane continues into it.
    pub has_predecessor: bool,
    /// Its roadblock: lanes side by side in one direction share it.
    pub group: usize,
    /// Whether overlaps are looked for (lanes with exact polygon areas, from Lanelet2, are
    /// drawn as they come).
    pub carve: bool,
}

/// A joined pair: from piece (lane, index) to piece (lane, index). Within one lane the path
/// is its centreline; between lanes, a curve from one's end to the other's start (the
/// offset copies of two ways do not meet where the ways do).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Join {
    /// The piece ending at the junction.
    pub from: (usize, usize),
    /// The piece leaving it.
    pub to: (usize, usize),
}

/// The cut map: pieces per lane and the joins through junctions.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    /// Per lane, its pieces as arc-length intervals in driving order. Lanes of one
    /// roadblock are cut alike: piece k of every member lies side by side.
    pub pieces: Vec<Vec<(f64, f64)>>,
    /// Every connector to draw.
    pub joins: Vec<Join>,
}

/// Per lane, sorted arc-length intervals (pieces or gaps).
type PerLane = Vec<Vec<(f64, f64)>>;

/// A stretch of a lane closer to `other` than their half widths, at arc length `at` on the
/// lane and `other_at` on `other`.
struct Overlap {
    lane: usize,
    at: f64,
    other: usize,
    other_at: f64,
}

/// Every place where a sample of one lane lies within overlap distance of another lane
/// that is not its side-by-side neighbour (or of itself, farther along), away from the
/// joints of successive lanes.
fn overlaps(lanes: &[LaneShape], arcs: &[Vec<f64>], totals: &[f64]) -> Vec<Overlap> {
    let max_width = lanes.iter().map(|l| l.width).fold(0.0, f64::max);
    let cell = |p: (f64, f64)| ((p.0 / CELL_M).floor() as i64, (p.1 / CELL_M).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<(usize, usize)>> = HashMap::new();
    for (j, lane) in lanes.iter().enumerate().filter(|(_, l)| l.carve) {
        let reach = lane.width / 2.0 + max_width / 2.0;
        for (k, w) in lane.centre.windows(2).enumerate() {
            let lo = cell((w[0].0.min(w[1].0) - reach, w[0].1.min(w[1].1) - reach));
            let hi = cell((w[0].0.max(w[1].0) + reach, w[0].1.max(w[1].1) + reach));
            for cx in lo.0..=hi.0 {
                for cy in lo.1..=hi.1 {
                    grid.entry((cx, cy)).or_default().push((j, k));
                }
            }
        }
    }
    let mut out = Vec::new();
    for (i, lane) in lanes.iter().enumerate().filter(|(_, l)| l.carve) {
        let total = totals[i];
        // A lane that doubles back over itself overlaps itself: its own segments count when
        // they are farther along it than this.
        let own_reach = 2.0 * lane.width;
        let samples = (total / STEP_M).ceil() as usize;
        for n in 0..=samples {
            let s = (n as f64 * STEP_M).min(total);
            let p = point_at(&lane.centre, s);
            // The nearest segment of each other lane within reach.
            let mut nearest: BTreeMap<usize, (f64, usize, f64)> = BTreeMap::new();
            for &(j, k) in grid.get(&cell(p)).map_or(&[][..], Vec::as_slice) {
                let other = &lanes[j];
                let far_along_itself = j == i && (arcs[i][k + 1] < s - own_reach || arcs[i][k] > s + own_reach);
                if other.group == lane.group && !far_along_itself {
                    continue;
                }
                let (d, f) = segment_distance(p, other.centre[k], other.centre[k + 1]);
                if d < (lane.width + other.width) / 2.0 - TOLERANCE_M
                    && nearest.get(&j).is_none_or(|&(best, _, _)| d < best)
                {
                    nearest.insert(j, (d, k, f));
                }
            }
            for (j, (_, k, f)) in nearest {
                let other_at = arcs[j][k] + f * (arcs[j][k + 1] - arcs[j][k]);
                // A lane and its successor touch where one ends and the other begins; only
                // overlap away from that joint counts (an acute fork, an inner bend).
                let at_joint = (lane.successors.contains(&j) && other_at <= JOINT_M)
                    || (lanes[j].successors.contains(&i) && other_at >= totals[j] - JOINT_M);
                if !at_joint {
                    out.push(Overlap { lane: i, at: s, other: j, other_at });
                }
            }
        }
    }
    out
}

/// Sorted, merged intervals.
fn merge(mut intervals: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    intervals.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (a, b) in intervals {
        match out.last_mut() {
            Some(last) if a <= last.1 => last.1 = last.1.max(b),
            _ => out.push((a, b)),
        }
    }
    out
}

/// The complement of sorted `gaps` in `[0, total]`, without pieces shorter than
/// [`MIN_PIECE_M`].
fn pieces_between(gaps: &[(f64, f64)], total: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut at = 0.0;
    for &(a, b) in gaps.iter().chain([(total, total)].iter()) {
        if a - at >= MIN_PIECE_M {
            out.push((at, a));
        }
        at = at.max(b);
    }
    out
}

/// Minimal union–find over indices.
#[derive(Debug, Clone)]
pub struct DisjointSets(Vec<usize>);

impl DisjointSets {
    /// `n` singletons.
    pub fn new(n: usize) -> Self {
        Self((0..n).collect())
    }

    /// The representative of `i`'s set.
    pub fn root(&mut self, mut i: usize) -> usize {
        while self.0[i] != i {
            self.0[i] = self.0[self.0[i]];
            i = self.0[i];
        }
        i
    }

    /// Joins the sets of `a` and `b` (the smaller root represents both).
    pub fn join(&mut self, a: usize, b: usize) {
        let (a, b) = (self.root(a), self.root(b));
        if a != b {
            self.0[a.max(b)] = a.min(b);
        }
    }
}

fn angle_between(a: f64, b: f64) -> f64 {
    (b - a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Pieces and gaps of every lane from its `raw` gaps: one set of cuts per roadblock, on its
/// first lane's arc length, so that side-by-side lanes are cut alike.
fn cut_groups(lanes: &[LaneShape], totals: &[f64], raw: &[Vec<(f64, f64)>]) -> (PerLane, PerLane) {
    let mut members: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (i, lane) in lanes.iter().enumerate() {
        members.entry(lane.group).or_default().push(i);
    }
    let mut gaps: Vec<Vec<(f64, f64)>> = vec![Vec::new(); lanes.len()];
    let mut pieces: Vec<Vec<(f64, f64)>> = vec![Vec::new(); lanes.len()];
    for group in members.values() {
        let reference = group[0];
        let on_reference = |i: usize, s: f64| {
            if i == reference {
                s
            } else {
                nearest_arc(&lanes[reference].centre, point_at(&lanes[i].centre, s))
            }
        };
        let mut cuts = Vec::new();
        for &i in group {
            for &(a, b) in &raw[i] {
                let (a, b) = (on_reference(i, a), on_reference(i, b));
                cuts.push((a.min(b), a.max(b)));
            }
        }
        let total = totals[reference];
        let kept = pieces_between(&merge(cuts), total);
        for &i in group {
            let onto = |t: f64| {
                if i == reference || t <= 0.0 {
                    t.max(0.0)
                } else if t >= total {
                    totals[i]
                } else {
                    nearest_arc(&lanes[i].centre, point_at(&lanes[reference].centre, t))
                }
            };
            pieces[i] = kept.iter().map(|&(a, b)| (onto(a), onto(b))).filter(|(a, b)| b > a).collect();
            let mut at = 0.0;
            for &(a, b) in pieces[i].iter().chain([(totals[i], totals[i])].iter()) {
                if a > at {
                    gaps[i].push((at, a));
                }
                at = b;
            }
        }
    }
    (pieces, gaps)
}

/// Cuts `lanes` at their junctions and joins the pieces through them.
pub fn layout(lanes: &[LaneShape]) -> Layout {
    // Arc length at every vertex, and every lane's length.
    let arcs: Vec<Vec<f64>> = lanes
        .iter()
        .map(|l| {
            let mut at = 0.0;
            std::iter::once(0.0)
                .chain(l.centre.windows(2).map(|w| {
                    at += (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
                    at
                }))
                .collect()
        })
        .collect();
    let totals: Vec<f64> = arcs.iter().map(|a| a.last().copied().unwrap_or(0.0)).collect();
    let found = overlaps(lanes, &arcs, &totals);
    // Gaps per lane: overlapping samples widened by a step each side (the overlap begins
    // somewhere between two samples), and the trimmed ends that join other lanes.
    let mut raw: Vec<Vec<(f64, f64)>> = vec![Vec::new(); lanes.len()];
    for o in &found {
        raw[o.lane].push(((o.at - STEP_M).max(0.0), (o.at + STEP_M).min(totals[o.lane])));
    }
    for (i, lane) in lanes.iter().enumerate() {
        let trim = TRIM_M.min(0.25 * totals[i]);
        if lane.has_predecessor {
            raw[i].push((0.0, trim));
        }
        if !lane.successors.is_empty() {
            raw[i].push((totals[i] - trim, totals[i]));
        }
    }
    let (mut pieces, mut gaps) = cut_groups(lanes, &totals, &raw);
    // A piece whose band folds over itself (sharp corners on short segments) cannot be a
    // polygon: it goes to the junction around it.
    let mut folded = false;
    for (i, list) in pieces.iter().enumerate() {
        for &(a, b) in list {
            if !is_simple(&band(&cut(&lanes[i].centre, a, b), lanes[i].width / 2.0).0) {
                raw[i].push((a, b));
                folded = true;
            }
        }
    }
    if folded {
        (pieces, gaps) = cut_groups(lanes, &totals, &raw);
    }
    // Gaps as nodes: overlapping gaps and successor relations make junctions.
    let mut gap_ids: Vec<Vec<usize>> = Vec::new();
    let mut count = 0;
    for g in &gaps {
        gap_ids.push((count..count + g.len()).collect());
        count += g.len();
    }
    let gap_at = |i: usize, s: f64| gaps[i].iter().position(|&(a, b)| s >= a - 1e-9 && s <= b + 1e-9);
    let mut junctions = DisjointSets::new(count);
    for o in &found {
        if let (Some(a), Some(b)) = (gap_at(o.lane, o.at), gap_at(o.other, o.other_at)) {
            junctions.join(gap_ids[o.lane][a], gap_ids[o.other][b]);
        }
    }
    for (i, lane) in lanes.iter().enumerate() {
        let Some(end) = gap_at(i, totals[i]) else { continue };
        for &j in &lane.successors {
            if let Some(start) = gap_at(j, 0.0) {
                junctions.join(gap_ids[i][end], gap_ids[j][start]);
            }
        }
    }
    // Entries (pieces ending at a gap) and exits (pieces starting after one) per junction.
    let mut entries: BTreeMap<usize, Vec<(usize, usize)>> = BTreeMap::new();
    let mut exits: BTreeMap<usize, Vec<(usize, usize)>> = BTreeMap::new();
    for (i, list) in pieces.iter().enumerate() {
        for (k, &(a, b)) in list.iter().enumerate() {
            if let Some(g) = gap_at(i, b).filter(|&g| gaps[i][g].1 > b) {
                entries.entry(junctions.root(gap_ids[i][g])).or_default().push((i, k));
            }
            if let Some(g) = gap_at(i, a).filter(|&g| gaps[i][g].0 < a) {
                exits.entry(junctions.root(gap_ids[i][g])).or_default().push((i, k));
            }
        }
    }
    let mut joins = Vec::new();
    let mut seen = BTreeSet::new();
    for (junction, from_list) in &entries {
        for &(i, k) in from_list {
            let end = pieces[i][k].1;
            let (p, heading) = (point_at(&lanes[i].centre, end), heading_at(&lanes[i].centre, end));
            for &(j, l) in exits.get(junction).map_or(&[][..], Vec::as_slice) {
                let start = pieces[j][l].0;
                let (q, next_heading) = (point_at(&lanes[j].centre, start), heading_at(&lanes[j].centre, start));
                if i == j && l != k + 1 {
                    continue;
                }
                if i != j
                    && (lanes[i].group == lanes[j].group
                        || angle_between(heading, next_heading).abs() > MAX_TURN
                        || (q.0 - p.0).hypot(q.1 - p.1) > MAX_JOIN_M)
                {
                    continue;
                }
                if seen.insert(((i, k), (j, l))) {
                    joins.push(Join { from: (i, k), to: (j, l) });
                }
            }
        }
    }
    Layout { pieces, joins }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lane(centre: Vec<(f64, f64)>, group: usize) -> LaneShape {
        LaneShape { centre, width: 3.5, successors: vec![], has_predecessor: false, group, carve: true }
    }

    /// A two-way through road along x (not split at the junction) and a two-way side
    /// street from the north ending on its centreline at x = 50.
    fn t_junction() -> Vec<LaneShape> {
        vec![
            lane(vec![(0.0, -1.75), (100.0, -1.75)], 0), // east-bound
            lane(vec![(100.0, 1.75), (0.0, 1.75)], 1),   // west-bound
            lane(vec![(48.25, 50.0), (48.25, 0.0)], 2),  // south-bound, into the junction
            lane(vec![(51.75, 0.0), (51.75, 50.0)], 3),  // north-bound, out of it
        ]
    }

    #[test]
    fn a_t_junction_cuts_the_through_road_and_joins_every_turn_but_u_turns() {
        let lanes = t_junction();
        let layout = layout(&lanes);
        // The through lanes are cut in two around x = 50, the side street's lanes at its end.
        assert_eq!(layout.pieces[0].len(), 2, "{:?}", layout.pieces[0]);
        assert_eq!(layout.pieces[1].len(), 2);
        let (east_a, east_b) = (layout.pieces[0][0], layout.pieces[0][1]);
        assert!(east_a.1 < 48.25 - 1.75 && east_b.0 > 51.75 + 1.75, "{east_a:?} {east_b:?}");
        assert!(layout.pieces[2][0].1 < 50.0 - 3.5 + 1e-9);
        assert!(layout.pieces[3][0].0 > 3.5 - 1e-9);
        let pairs: BTreeSet<_> = layout.joins.iter().map(|j| (j.from, j.to)).collect();
        let expected = BTreeSet::from([
            ((0, 0), (0, 1)), // straight on, east
            ((0, 0), (3, 0)), // left turn into the side street
            ((1, 0), (1, 1)), // straight on, west
            ((1, 0), (3, 0)), // right turn into the side street
            ((2, 0), (0, 1)), // left turn out, east
            ((2, 0), (1, 1)), // right turn out, west
        ]);
        assert_eq!(pairs, expected);
    }

    #[test]
    fn lanes_joining_end_to_start_keep_their_length_but_the_trim() {
        let mut a = lane(vec![(0.0, 0.0), (40.0, 0.0)], 0);
        a.successors = vec![1];
        let mut b = lane(vec![(40.0, 0.0), (80.0, 0.0)], 1);
        b.has_predecessor = true;
        let layout = layout(&[a, b]);
        assert_eq!(layout.pieces, vec![vec![(0.0, 38.0)], vec![(2.0, 40.0)]]);
        assert_eq!(layout.joins, vec![Join { from: (0, 0), to: (1, 0) }]);
    }

    #[test]
    fn side_by_side_lanes_are_cut_alike() {
        // Two east-bound lanes (one roadblock), a south-bound street crossing the left one
        // only near its end at x = 20.
        let mut lanes = vec![
            lane(vec![(0.0, 1.75), (60.0, 1.75)], 0),
            lane(vec![(0.0, -1.75), (60.0, -1.75)], 0),
            lane(vec![(20.0, 30.0), (20.0, 3.6)], 1),
        ];
        lanes[2].width = 3.0;
        let layout = layout(&lanes);
        assert_eq!(layout.pieces[0].len(), 2, "{:?}", layout.pieces);
        assert_eq!(layout.pieces[0], layout.pieces[1], "the right lane is cut where the left one is");
    }
}
