//! Road geometry of a generated scenario: a reference line made of straights and circular
//! arcs, with lanes on either side, addressed in road coordinates (s along, d to the left).
//!
//! The reference line is the divider between the two directions. Forward lanes lie to its
//! right (d < 0) and are driven with increasing s; backward lanes lie to its left.

use std::f64::consts::PI;

/// One piece of the reference line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Segment {
    /// A straight of this length, metres.
    Straight(f64),
    /// An arc: length (m) and curvature (1/m, positive turns left).
    Arc(f64, f64),
}

/// A point of the reference line with its heading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoadPose {
    /// East, metres.
    pub x: f64,
    /// North, metres.
    pub y: f64,
    /// Direction of increasing s, radians from east (counter-clockwise).
    pub heading: f64,
    /// Curvature at this point, 1/m.
    pub curvature: f64,
}

/// A road: reference line, lane width and lane counts.
#[derive(Clone, Debug, PartialEq)]
pub struct Road {
    /// Pieces of the reference line, in order.
    pub segments: Vec<Segment>,
    /// Start of the reference line (east, north) and its heading.
    pub start: RoadPose,
    /// Width of every lane, metres.
    pub lane_width: f64,
    /// Lanes driven with increasing s (right of the reference line).
    pub lanes_forward: u8,
    /// Lanes driven with decreasing s (left of it).
    pub lanes_backward: u8,
    /// Speed limit, m/s.
    pub speed_limit: f64,
}

impl Road {
    /// Length of the reference line, metres.
    pub fn length(&self) -> f64 {
        self.segments
            .iter()
            .map(|s| match s {
                Segment::Straight(l) | Segment::Arc(l, _) => *l,
            })
            .sum()
    }

    /// The reference line at `s` (clamped to the road; beyond its ends it continues straight).
    pub fn pose(&self, s: f64) -> RoadPose {
        let mut p = self.start;
        let mut remaining = s;
        for segment in &self.segments {
            let (length, curvature) = match *segment {
                Segment::Straight(l) => (l, 0.0),
                Segment::Arc(l, k) => (l, k),
            };
            let along = remaining.min(length);
            p = advance(p, along, curvature);
            remaining -= along;
            if remaining <= 0.0 {
                return p;
            }
        }
        advance(RoadPose { curvature: 0.0, ..p }, remaining, 0.0)
    }

    /// The point at road coordinates (s, d): d metres left of the reference line.
    pub fn point(&self, s: f64, d: f64) -> (f64, f64) {
        let p = self.pose(s);
        (p.x - d * p.heading.sin(), p.y + d * p.heading.cos())
    }

    /// Lateral offset of the centre of forward lane `lane` (0 = outermost, on the right).
    pub fn forward_lane(&self, lane: u8) -> f64 {
        -(f64::from(self.lanes_forward) - f64::from(lane) - 0.5) * self.lane_width
    }

    /// Lateral offset of the centre of backward lane `lane` (0 = outermost, on the left).
    pub fn backward_lane(&self, lane: u8) -> f64 {
        (f64::from(self.lanes_backward) - f64::from(lane) - 0.5) * self.lane_width
    }

    /// Lateral offset of the right edge of the forward carriageway.
    pub fn right_edge(&self) -> f64 {
        -f64::from(self.lanes_forward) * self.lane_width
    }
}

/// Move `along` metres on a path of constant `curvature`.
fn advance(p: RoadPose, along: f64, curvature: f64) -> RoadPose {
    let heading = p.heading + curvature * along;
    let (x, y) = if curvature.abs() < 1e-12 {
        (p.x + along * p.heading.cos(), p.y + along * p.heading.sin())
    } else {
        (p.x + (heading.sin() - p.heading.sin()) / curvature, p.y - (heading.cos() - p.heading.cos()) / curvature)
    };
    RoadPose { x, y, heading, curvature }
}

/// Smooth lateral move from `from` to `to` between `s0` and `s1` (quintic: zero lateral
/// velocity and acceleration at both ends, as a comfortable lane change).
pub fn lane_change(s: f64, s0: f64, s1: f64, from: f64, to: f64) -> f64 {
    let u = ((s - s0) / (s1 - s0)).clamp(0.0, 1.0);
    from + (to - from) * u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
}

/// Wrap an angle into (−π, π].
pub fn wrap(a: f64) -> f64 {
    let r = (a + PI).rem_euclid(2.0 * PI) - PI;
    if r <= -PI {
        r + 2.0 * PI
    } else {
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn road() -> Road {
        Road {
            segments: vec![Segment::Straight(100.0), Segment::Arc(50.0 * PI, 1.0 / 100.0), Segment::Straight(10.0)],
            start: RoadPose { x: 0.0, y: 0.0, heading: 0.0, curvature: 0.0 },
            lane_width: 3.5,
            lanes_forward: 2,
            lanes_backward: 2,
            speed_limit: 22.0,
        }
    }

    #[test]
    fn a_quarter_circle_turns_left_by_ninety_degrees() {
        let r = road();
        let end_of_arc = r.pose(100.0 + 50.0 * PI);
        assert!((end_of_arc.x - 200.0).abs() < 1e-9 && (end_of_arc.y - 100.0).abs() < 1e-9, "{end_of_arc:?}");
        assert!((end_of_arc.heading - PI / 2.0).abs() < 1e-12);
        let beyond = r.pose(r.length() + 5.0);
        assert!((beyond.y - 115.0).abs() < 1e-9);
        // Halfway round the arc the point is on the circle about (100, 100).
        let mid = r.pose(100.0 + 25.0 * PI);
        assert!(((mid.x - 100.0).hypot(mid.y - 100.0) - 100.0).abs() < 1e-9);
    }

    #[test]
    fn lanes_lie_either_side_of_the_reference_line() {
        let r = road();
        assert_eq!((r.forward_lane(0), r.forward_lane(1)), (-5.25, -1.75));
        assert_eq!((r.backward_lane(0), r.backward_lane(1)), (5.25, 1.75));
        // Heading east, left is north.
        assert_eq!(r.point(10.0, 2.0), (10.0, 2.0));
        assert_eq!(r.right_edge(), -7.0);
    }

    #[test]
    fn lane_change_is_smooth_and_ends_where_asked() {
        assert_eq!(lane_change(0.0, 10.0, 70.0, -5.25, -1.75), -5.25);
        assert_eq!(lane_change(80.0, 10.0, 70.0, -5.25, -1.75), -1.75);
        assert!((lane_change(40.0, 10.0, 70.0, -5.25, -1.75) + 3.5).abs() < 1e-12);
        assert!((wrap(3.0 * PI) - PI).abs() < 1e-12 && (wrap(-PI / 2.0) + PI / 2.0).abs() < 1e-12);
    }
}
