//! Oriented boxes in the ground plane: the ego footprint and the other road users, as the
//! drivable-area check and the score see them.
//!
//! nuPlan places the ego's pose at the rear axle, so the footprint is not centred on the
//! pose: [`Footprint`] turns a rear-axle pose into the box, [`OrientedBox`] answers the
//! questions the metrics ask of boxes (corners, overlap, does a bumper touch another box).

/// A pose in the plane: position (m) and heading (rad, counter-clockwise from +x / east).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose2 {
    /// East, m.
    pub x: f64,
    /// North, m.
    pub y: f64,
    /// Heading, rad.
    pub heading: f64,
}

impl Pose2 {
    /// A pose.
    pub const fn new(x: f64, y: f64, heading: f64) -> Self {
        Pose2 { x, y, heading }
    }

    /// The point `forward` m ahead and `left` m to the left of the pose.
    pub fn offset(&self, forward: f64, left: f64) -> (f64, f64) {
        let (s, c) = libm::sincos(self.heading);
        (self.x + forward * c - left * s, self.y + forward * s + left * c)
    }

    /// True when every field is finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.heading.is_finite()
    }
}

/// A vehicle's outline relative to its rear axle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Footprint {
    /// Overall width, m.
    pub width: f64,
    /// Rear axle → front bumper, m.
    pub front: f64,
    /// Rear axle → rear bumper, m.
    pub rear: f64,
}

/// nuPlan's ego vehicle (Chrysler Pacifica): width 2.297 m, rear axle → front 4.049 m,
/// rear overhang 1.127 m.
pub const PACIFICA: Footprint = Footprint { width: 2.297, front: 4.049, rear: 1.127 };

impl Footprint {
    /// The box of a vehicle whose rear axle is at `pose`.
    pub fn at(&self, pose: &Pose2) -> OrientedBox {
        let (x, y) = pose.offset((self.front - self.rear) / 2.0, 0.0);
        OrientedBox { centre: Pose2::new(x, y, pose.heading), length: self.front + self.rear, width: self.width }
    }
}

/// A rectangle: centre pose, length along the heading, width across it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct OrientedBox {
    /// Centre and heading.
    pub centre: Pose2,
    /// Length, m.
    pub length: f64,
    /// Width, m.
    pub width: f64,
}

/// Which corner: the order of [`OrientedBox::corners`].
pub const CORNER_NAMES: [&str; 4] = ["front left", "front right", "rear right", "rear left"];

impl OrientedBox {
    /// Corners: front left, front right, rear right, rear left.
    pub fn corners(&self) -> [(f64, f64); 4] {
        let (l, w) = (self.length / 2.0, self.width / 2.0);
        // `Pose2::offset` four times, with the heading's sine and cosine taken once.
        let (s, c) = libm::sincos(self.centre.heading);
        let at =
            |forward: f64, left: f64| (self.centre.x + forward * c - left * s, self.centre.y + forward * s + left * c);
        [at(l, w), at(l, -w), at(-l, -w), at(-l, w)]
    }

    /// The front edge (front left → front right), nuPlan's "front bumper".
    pub fn front_edge(&self) -> [(f64, f64); 2] {
        let [fl, fr, _, _] = self.corners();
        [fl, fr]
    }

    /// The rear edge (rear right → rear left).
    pub fn rear_edge(&self) -> [(f64, f64); 2] {
        let [_, _, rr, rl] = self.corners();
        [rr, rl]
    }

    /// The box moved by (dx, dy).
    pub fn translated(&self, dx: f64, dy: f64) -> OrientedBox {
        OrientedBox { centre: Pose2::new(self.centre.x + dx, self.centre.y + dy, self.centre.heading), ..*self }
    }

    /// Whether the two boxes share any point (separating-axis test; touching counts).
    pub fn overlaps(&self, other: &OrientedBox) -> bool {
        let (a, b) = (self.corners(), other.corners());
        let axes = [self.centre.heading, self.centre.heading + core::f64::consts::FRAC_PI_2]
            .into_iter()
            .chain([other.centre.heading, other.centre.heading + core::f64::consts::FRAC_PI_2]);
        for angle in axes {
            let (s, c) = libm::sincos(angle);
            let project = |p: &(f64, f64)| p.0 * c + p.1 * s;
            let (a_lo, a_hi) =
                a.iter().map(project).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
            let (b_lo, b_hi) =
                b.iter().map(project).fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
            if a_hi < b_lo || b_hi < a_lo {
                return false;
            }
        }
        true
    }

    /// Whether (x, y) lies in the box (boundary included).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let (s, c) = libm::sincos(self.centre.heading);
        let (dx, dy) = (x - self.centre.x, y - self.centre.y);
        let (along, across) = (dx * c + dy * s, -dx * s + dy * c);
        libm::fabs(along) <= self.length / 2.0 && libm::fabs(across) <= self.width / 2.0
    }

    /// Whether the segment `edge` touches the box.
    pub fn touches_segment(&self, edge: [(f64, f64); 2]) -> bool {
        let [p, q] = edge;
        if self.contains(p.0, p.1) || self.contains(q.0, q.1) {
            return true;
        }
        let c = self.corners();
        (0..4).any(|k| segments_cross(p, q, c[k], c[(k + 1) % 4]))
    }
}

fn orientation(a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> f64 {
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

/// Whether segments p–q and a–b intersect (collinear overlaps included).
fn segments_cross(p: (f64, f64), q: (f64, f64), a: (f64, f64), b: (f64, f64)) -> bool {
    let (d1, d2) = (orientation(a, b, p), orientation(a, b, q));
    let (d3, d4) = (orientation(p, q, a), orientation(p, q, b));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0)) {
        return true;
    }
    let on = |s: (f64, f64), e: (f64, f64), r: (f64, f64), d: f64| {
        d == 0.0 && r.0 >= s.0.min(e.0) && r.0 <= s.0.max(e.0) && r.1 >= s.1.min(e.1) && r.1 <= s.1.max(e.1)
    };
    on(a, b, p, d1) || on(a, b, q, d2) || on(p, q, a, d3) || on(p, q, b, d4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pacifica_box_sits_ahead_of_the_rear_axle() {
        let b = PACIFICA.at(&Pose2::new(10.0, 5.0, core::f64::consts::FRAC_PI_2));
        let [fl, fr, rr, rl] = b.corners();
        let near = |p: (f64, f64), q: (f64, f64)| libm::hypot(p.0 - q.0, p.1 - q.1) < 1e-9;
        // Heading north: front is +y, left is −x.
        assert!(near(fl, (10.0 - 1.1485, 5.0 + 4.049)), "{fl:?}");
        assert!(near(fr, (10.0 + 1.1485, 5.0 + 4.049)), "{fr:?}");
        assert!(near(rr, (10.0 + 1.1485, 5.0 - 1.127)), "{rr:?}");
        assert!(near(rl, (10.0 - 1.1485, 5.0 - 1.127)), "{rl:?}");
    }

    #[test]
    fn overlap_needs_every_axis_to_overlap() {
        let a = OrientedBox { centre: Pose2::new(0.0, 0.0, 0.0), length: 4.0, width: 2.0 };
        // A diamond whose bounding box overlaps a's but which is separated on its own axis.
        let diamond =
            OrientedBox { centre: Pose2::new(2.5, 1.5, core::f64::consts::FRAC_PI_4), length: 1.0, width: 1.0 };
        assert!(!a.overlaps(&diamond) && !diamond.overlaps(&a));
        assert!(a.overlaps(&diamond.translated(-0.5, -0.5)));
        assert!(a.overlaps(&a.translated(4.0, 0.0)), "touching counts");
        assert!(!a.overlaps(&a.translated(4.001, 0.0)));
    }

    #[test]
    fn bumpers_touch_what_is_in_front_or_behind() {
        let ego = OrientedBox { centre: Pose2::new(0.0, 0.0, 0.0), length: 4.0, width: 2.0 };
        let ahead = OrientedBox { centre: Pose2::new(2.5, 0.0, 0.3), length: 1.5, width: 1.0 };
        let beside = OrientedBox { centre: Pose2::new(0.0, 1.4, 0.0), length: 1.0, width: 1.0 };
        assert!(ego.touches_segment(ahead.front_edge()) || ahead.touches_segment(ego.front_edge()));
        assert!(ahead.touches_segment(ego.front_edge()) && !ahead.touches_segment(ego.rear_edge()));
        assert!(!beside.touches_segment(ego.front_edge()) && !beside.touches_segment(ego.rear_edge()));
        assert!(ego.overlaps(&beside));
    }
}
