//! A lane's centreline (a polyline) as an OpenDRIVE plan view: straight lines joined at each
//! vertex by a circular arc tangent to both, so that the heading is continuous along the road
//! (OpenDRIVE's reference lines are G1; a polyline's corners are not).
//!
//! Each arc is as wide as the two segments beside it allow (it takes at most half of each)
//! and no wider than keeps it within [`TOLERANCE_M`] of the corner it rounds: the reference
//! line stays within that distance of the tile's centreline, and the map's lanes are where
//! the tile has them. A corner too sharp for the segments beside it gets a tight arc, which
//! is still the polyline's shape.

use dash2sim_core::track3d::wrap_angle;

/// The largest distance of an arc from the corner it rounds, m.
pub const TOLERANCE_M: f64 = 0.05;

/// A corner turning by less than this is no corner (no arc), rad.
const STRAIGHT_RAD: f64 = 1e-9;
/// Consecutive points closer than this are one point, m.
const SAME_POINT_M: f64 = 1e-4;
/// The line [`PlanView::fit_between`] puts at an end to hold its heading: at most this long,
/// and a quarter of the end's own segment, m.
const END_LINE_M: f64 = 0.5;
/// An element shorter than this is left out (what it leaves of a gap is far below the
/// millimetres the document is written in), m.
const MIN_ELEMENT_M: f64 = 1e-5;

/// One element of a plan view: a line (`curvature` 0) or an arc.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    /// Arc length at its start along the reference line, m.
    pub s: f64,
    /// Start, m.
    pub x: f64,
    /// Start, m.
    pub y: f64,
    /// Heading at the start, rad (counter-clockwise from x).
    pub heading: f64,
    /// Length, m.
    pub length: f64,
    /// Curvature, 1/m (positive turns left); 0 for a line.
    pub curvature: f64,
}

impl Element {
    /// The point and heading `d` metres along the element.
    fn at(&self, d: f64) -> (f64, f64, f64) {
        let (s, c) = self.heading.sin_cos();
        if self.curvature == 0.0 {
            return (self.x + c * d, self.y + s * d, self.heading);
        }
        let turned = self.heading + self.curvature * d;
        let r = 1.0 / self.curvature;
        (self.x + r * (turned.sin() - s), self.y - r * (turned.cos() - c), turned)
    }
}

/// A reference line: its elements in order, end to end.
#[derive(Clone, Debug, Default)]
pub struct PlanView {
    /// The elements.
    pub elements: Vec<Element>,
}

impl PlanView {
    /// The lines and arcs through `points` (at least two distinct points; `None` otherwise).
    pub fn fit(points: &[(f64, f64)]) -> Option<Self> {
        let mut p: Vec<(f64, f64)> = Vec::with_capacity(points.len());
        for &q in points {
            if p.last().is_none_or(|l: &(f64, f64)| (q.0 - l.0).hypot(q.1 - l.1) > SAME_POINT_M) {
                p.push(q);
            }
        }
        if p.len() < 2 {
            return None;
        }
        let headings: Vec<f64> = p.windows(2).map(|w| (w[1].1 - w[0].1).atan2(w[1].0 - w[0].0)).collect();
        let lengths: Vec<f64> = p.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).collect();
        // At each inner vertex: how far before and after it the arc starts and ends, and the
        // arc itself (turn, radius).
        let mut corners = vec![(0.0, 0.0, 0.0); p.len()];
        for k in 1..p.len() - 1 {
            let turn = wrap_angle(headings[k] - headings[k - 1]);
            let half = 0.5 * turn.abs().min(std::f64::consts::PI - 1e-6);
            if half < 0.5 * STRAIGHT_RAD {
                continue;
            }
            // Half of each neighbouring segment, and the tolerance: r (1/cos − 1) ≤ tol.
            let by_room = 0.5 * lengths[k - 1].min(lengths[k]) / half.tan();
            let by_tolerance = TOLERANCE_M / (1.0 / half.cos() - 1.0);
            let r = by_room.min(by_tolerance);
            corners[k] = (r * half.tan(), turn, r);
        }
        let mut view = PlanView::default();
        let mut s = 0.0;
        let mut push = |view: &mut PlanView, x: f64, y: f64, heading: f64, length: f64, curvature: f64| {
            if length <= MIN_ELEMENT_M {
                return;
            }
            // A line on from a line in the same direction is the same line (OpenDRIVE's
            // checkers call two a redundant declaration).
            match view.elements.last_mut() {
                Some(last)
                    if curvature == 0.0
                        && last.curvature == 0.0
                        && wrap_angle(heading - last.heading).abs() < STRAIGHT_RAD =>
                {
                    last.length += length;
                }
                _ => view.elements.push(Element { s, x, y, heading, length, curvature }),
            }
            s += length;
        };
        for k in 0..p.len() - 1 {
            let (h, (dx, dy)) = (headings[k], (headings[k].cos(), headings[k].sin()));
            // The line from the end of vertex k's arc to the start of vertex k+1's.
            let start = corners[k].0;
            let end = lengths[k] - corners[k + 1].0;
            push(&mut view, p[k].0 + dx * start, p[k].1 + dy * start, h, end - start, 0.0);
            let (_, turn, r) = corners[k + 1];
            if r > 0.0 {
                push(&mut view, p[k].0 + dx * end, p[k].1 + dy * end, h, r * turn.abs(), turn.signum() / r);
            }
        }
        Some(view)
    }

    /// The lines and arcs through `points` leaving the first along `start` and reaching the
    /// last along `end` (headings, rad): a road that continues another without a kink, where
    /// two linked lanes' borders meet only if their headings do. A short first (last) line
    /// along the heading is put in front of (after) the points' own, its corner rounded as
    /// the others.
    pub fn fit_between(points: &[(f64, f64)], start: f64, end: f64) -> Option<Self> {
        let (Some(&first), Some(&last)) = (points.first(), points.last()) else { return None };
        let chord = |a: (f64, f64), b: (f64, f64)| (b.0 - a.0).hypot(b.1 - a.1);
        let lead = |l: f64| (0.25 * l).min(END_LINE_M);
        let mut p = Vec::with_capacity(points.len() + 2);
        p.push(first);
        if let Some(&second) = points.get(1) {
            let d = lead(chord(first, second));
            p.push((first.0 + d * start.cos(), first.1 + d * start.sin()));
        }
        p.extend_from_slice(&points[1..points.len().saturating_sub(1)]);
        if let Some(&before) = points.len().checked_sub(2).and_then(|i| points.get(i)) {
            let d = lead(chord(before, last));
            p.push((last.0 - d * end.cos(), last.1 - d * end.sin()));
        }
        p.push(last);
        Self::fit(&p)
    }

    /// Its length, m.
    pub fn length(&self) -> f64 {
        self.elements.last().map_or(0.0, |e| e.s + e.length)
    }

    /// The point and heading at arc length `s` (clamped to the line).
    pub fn at(&self, s: f64) -> (f64, f64, f64) {
        let i = self.elements.partition_point(|e| e.s <= s).saturating_sub(1);
        match self.elements.get(i) {
            Some(e) => e.at((s - e.s).clamp(0.0, e.length)),
            None => (0.0, 0.0, 0.0),
        }
    }

    /// The point `t` metres to the left of the line at `s`.
    pub fn offset(&self, s: f64, t: f64) -> (f64, f64) {
        let (x, y, h) = self.at(s);
        (x - t * h.sin(), y + t * h.cos())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_linux::geometry::segment_distance;

    fn distance_to(line: &[(f64, f64)], p: (f64, f64)) -> f64 {
        line.windows(2).map(|w| segment_distance(p, w[0], w[1]).0).fold(f64::INFINITY, f64::min)
    }

    #[test]
    fn a_straight_line_is_one_line_element() {
        let v = PlanView::fit(&[(0.0, 0.0), (5.0, 0.0), (10.0, 0.0)]).expect("two points");
        // Two collinear segments: one line, no arc.
        assert_eq!(v.elements.len(), 1);
        assert!((v.length() - 10.0).abs() < 1e-12);
        let (x, y, h) = v.at(7.5);
        assert!((x - 7.5).abs() < 1e-12 && y.abs() < 1e-12 && h.abs() < 1e-12);
    }

    #[test]
    fn a_corner_is_rounded_within_the_tolerance_and_the_heading_is_continuous() {
        let line = [(0.0, 0.0), (20.0, 0.0), (20.0 + 20.0 * 0.5f64.cos(), 20.0 * 0.5f64.sin()), (40.0, 25.0)];
        let v = PlanView::fit(&line).expect("a line");
        // Ends exactly where the polyline does, with its end segments' headings.
        let (x0, y0, h0) = v.at(0.0);
        assert!(x0.abs() < 1e-12 && y0.abs() < 1e-12 && h0.abs() < 1e-12);
        let (x1, y1, _) = v.at(v.length());
        assert!((x1 - 40.0).abs() < 1e-9 && (y1 - 25.0).abs() < 1e-9, "{x1} {y1}");
        // Each element starts where the previous ends, heading on.
        for w in v.elements.windows(2) {
            let (x, y, h) = w[0].at(w[0].length);
            assert!((x - w[1].x).hypot(y - w[1].y) < 1e-9, "gap at s = {}", w[1].s);
            assert!(wrap_angle(h - w[1].heading).abs() < 1e-9, "kink at s = {}", w[1].s);
        }
        // Two corners, two arcs, and every point within the tolerance of the polyline.
        assert_eq!(v.elements.iter().filter(|e| e.curvature != 0.0).count(), 2);
        let n = 2000;
        let worst = (0..=n)
            .map(|i| {
                let (x, y, _) = v.at(v.length() * i as f64 / n as f64);
                distance_to(&line, (x, y))
            })
            .fold(0.0, f64::max);
        assert!(worst <= TOLERANCE_M + 1e-9 && worst > 0.5 * TOLERANCE_M, "{worst}");
    }

    #[test]
    fn short_segments_limit_the_arcs_to_half_of_each() {
        // A gentle polyline arc of 1 m chords: the arcs take the whole of each chord between
        // them (no line elements of length left but the ends' halves) and stay on it.
        let line: Vec<(f64, f64)> =
            (0..=20).map(|i| (30.0 * (i as f64 * 0.033).sin(), 30.0 * (1.0 - (i as f64 * 0.033).cos()))).collect();
        let v = PlanView::fit(&line).expect("a line");
        assert!(v.elements.iter().filter(|e| e.curvature != 0.0).all(|e| (e.curvature - 1.0 / 30.0).abs() < 1e-3));
        let (x, y, _) = v.at(v.length());
        let last = line[line.len() - 1];
        assert!((x - last.0).hypot(y - last.1) < 1e-9);
    }

    #[test]
    fn fit_between_leaves_and_arrives_along_the_headings_given() {
        // A chord from (0, 0) to (10, 0) asked to leave heading 0.2 rad and arrive at -0.2.
        let v = PlanView::fit_between(&[(0.0, 0.0), (5.0, 0.3), (10.0, 0.0)], 0.2, -0.2).expect("a line");
        let (x0, y0, h0) = v.at(0.0);
        let (x1, y1, h1) = v.at(v.length());
        assert!(x0.abs() < 1e-12 && y0.abs() < 1e-12 && (h0 - 0.2).abs() < 1e-12, "{x0} {y0} {h0}");
        assert!((x1 - 10.0).abs() < 1e-9 && y1.abs() < 1e-9 && (h1 + 0.2).abs() < 1e-9, "{x1} {y1} {h1}");
    }

    #[test]
    fn fewer_than_two_distinct_points_is_no_line() {
        assert!(PlanView::fit(&[]).is_none());
        assert!(PlanView::fit(&[(1.0, 1.0), (1.0, 1.0)]).is_none());
    }
}
