//! What moves and what stands in a generated scenario: the object classes, the work zone
//! laid out along a taper, the other vehicles, and the ego drive with its lane change
//! through the closure.

use dash2sim_core::box3d::Box3d;
use dash2sim_core::pipeline::profile::{ClassProfile, WORK_ZONE};
use rand::Rng;

use super::gauss;
use super::road::{lane_change, wrap, Road};

/// Object classes of a work-zone scene; the discriminant is the class id used by the
/// trackers (the index into the core's work-zone profile).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u16)]
pub enum Class {
    /// Passenger car.
    Car = 0,
    /// Truck.
    Truck = 1,
    /// Traffic cone.
    Cone = 2,
    /// Channelizing drum (barrel).
    Drum = 3,
    /// Type III barricade across a closed lane.
    Barricade = 4,
    /// Trailer-mounted arrow board.
    ArrowBoard = 5,
    /// Work-zone sign on the shoulder.
    Sign = 6,
}

impl Class {
    /// Every class, by id.
    pub const ALL: [Class; 7] =
        [Class::Car, Class::Truck, Class::Cone, Class::Drum, Class::Barricade, Class::ArrowBoard, Class::Sign];

    /// The class with this id.
    pub fn from_id(id: u16) -> Option<Class> {
        Class::ALL.get(usize::from(id)).copied()
    }

    /// This class in the work-zone profile (name, size, priors) the trackers share.
    pub fn profile(self) -> &'static ClassProfile {
        &WORK_ZONE[self as usize]
    }

    /// Lower-case name as written to files.
    pub fn name(self) -> &'static str {
        self.profile().name
    }

    /// Nominal size (length along the heading, width, height), metres.
    pub fn size(self) -> [f64; 3] {
        self.profile().size
    }

    /// Whether objects of this class are placed once and never move.
    pub fn is_static(self) -> bool {
        self.profile().is_static
    }

    /// Whether its heading can be told from its shape (cones and drums are round).
    pub fn has_heading(self) -> bool {
        self.profile().has_heading
    }

    /// Farthest range at which the detector sees it, metres.
    pub fn max_range(self) -> f64 {
        match self {
            Class::Car => 80.0,
            Class::Truck => 90.0,
            Class::Cone => 45.0,
            Class::Drum => 55.0,
            Class::Barricade => 60.0,
            Class::ArrowBoard => 90.0,
            Class::Sign => 70.0,
        }
    }
}

/// Ground truth of one object at one frame (world ENU frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjectState {
    /// Object id, from 1, stable over the scenario.
    pub id: u32,
    /// Class.
    pub class: Class,
    /// Box; `z` is the centre (ground at 0).
    pub bbox: Box3d,
    /// Horizontal velocity, m/s.
    pub velocity: [f64; 2],
}

impl ObjectState {
    /// Static ground truth: the object does not move.
    pub fn is_static(&self) -> bool {
        self.class.is_static()
    }
}

/// Where the work zone lies along the road (s, metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkZone {
    /// Start of the taper that closes the right lane.
    pub taper_start: f64,
    /// Taper length.
    pub taper_length: f64,
    /// Length of the closure after the taper.
    pub closure_length: f64,
    /// Length of the taper that opens the lane again.
    pub end_taper_length: f64,
}

impl WorkZone {
    /// End of the closure (start of the end taper).
    pub fn closure_end(&self) -> f64 {
        self.taper_start + self.taper_length + self.closure_length
    }

    /// End of the whole zone.
    pub fn end(&self) -> f64 {
        self.closure_end() + self.end_taper_length
    }
}

/// A box standing on the ground at road coordinates (s, d), turned `yaw_offset` from the
/// road heading.
fn standing_box(road: &Road, class: Class, s: f64, d: f64, yaw_offset: f64, scale: f64) -> Box3d {
    let (x, y) = road.point(s, d);
    let [l, w, h] = class.size().map(|v| v * scale);
    Box3d { x, y, z: h / 2.0, yaw: wrap(road.pose(s).heading + yaw_offset), l, w, h }
}

/// The static objects of the zone: signs ahead of it on the shoulder, drums along the
/// taper, cones along the closed lane's line and the end taper, barricades across the
/// closed lane and an arrow board behind the taper. Positions jitter by a few centimetres.
pub fn lay_out_work_zone(road: &Road, zone: &WorkZone, rng: &mut impl Rng, next_id: &mut u32) -> Vec<ObjectState> {
    let edge = road.right_edge();
    let line = edge + road.lane_width; // between the closed lane and the open one
    let closed_lane = road.forward_lane(0);
    let mut placements: Vec<(Class, f64, f64, f64)> = Vec::new();
    for ahead in [200.0, 130.0, 60.0] {
        placements.push((Class::Sign, zone.taper_start - ahead, edge - 1.5, 0.0));
    }
    let drums = 9;
    for k in 0..=drums {
        let u = f64::from(k) / f64::from(drums);
        let s = zone.taper_start + u * zone.taper_length;
        placements.push((Class::Drum, s, edge + 0.3 + u * (line - 0.1 - edge - 0.3), 0.0));
    }
    placements.push((Class::ArrowBoard, zone.taper_start + zone.taper_length - 5.0, closed_lane - 0.4, 0.0));
    for d in [closed_lane + 0.9, closed_lane - 0.9] {
        placements.push((Class::Barricade, zone.taper_start + zone.taper_length + 8.0, d, std::f64::consts::FRAC_PI_2));
    }
    let mut s = zone.taper_start + zone.taper_length + 12.0;
    while s < zone.closure_end() {
        placements.push((Class::Cone, s, line - 0.1, 0.0));
        s += 12.0;
    }
    let end_cones = 4;
    for k in 0..=end_cones {
        let u = f64::from(k) / f64::from(end_cones);
        placements.push((
            Class::Cone,
            zone.closure_end() + u * zone.end_taper_length,
            line - 0.1 + u * (edge - line),
            0.0,
        ));
    }
    placements
        .into_iter()
        .map(|(class, s, d, yaw)| {
            let (ds, dd) = (gauss(rng, 0.08), gauss(rng, 0.08));
            let yaw = if class.has_heading() { yaw + gauss(rng, 0.04) } else { rng.random_range(-3.1..3.1) };
            let scale = 1.0 + gauss(rng, 0.02);
            let id = *next_id;
            *next_id += 1;
            ObjectState { id, class, bbox: standing_box(road, class, s + ds, d + dd, yaw, scale), velocity: [0.0; 2] }
        })
        .collect()
}

/// Another road user: drives its lane at constant speed, optionally changing lanes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vehicle {
    /// Object id.
    pub id: u32,
    /// Car or truck.
    pub class: Class,
    /// s at t = 0.
    pub s0: f64,
    /// Speed along s, m/s (negative in backward lanes).
    pub speed: f64,
    /// Lateral offset of its lane.
    pub d: f64,
    /// A lane change: (start s, end s, target d).
    pub lane_change: Option<(f64, f64, f64)>,
    /// The stretch of road it exists on (s from, to): on a road of several sections each
    /// section's traffic stays in its own.
    pub s_range: (f64, f64),
}

impl Vehicle {
    /// Road coordinates at time `t`: (s, d).
    pub fn road_position(&self, t: f64) -> (f64, f64) {
        let s = self.s0 + self.speed * t;
        let d = match self.lane_change {
            Some((s0, s1, to)) => lane_change(s, s0, s1, self.d, to),
            None => self.d,
        };
        (s, d)
    }

    /// Ground truth at `t`, or `None` when it is off the road.
    pub fn state(&self, road: &Road, t: f64) -> Option<ObjectState> {
        let (s, d) = self.road_position(t);
        if !(0.0..=road.length()).contains(&s) || !(self.s_range.0..=self.s_range.1).contains(&s) {
            return None;
        }
        // The velocity at `t`: the chord from a step before to a step after.
        let dt = 0.05;
        let (s_next, d_next) = self.road_position(t + dt);
        let (s_prev, d_prev) = self.road_position(t - dt);
        let (x, y) = road.point(s, d);
        let (xn, yn) = road.point(s_next, d_next);
        let (xp, yp) = road.point(s_prev, d_prev);
        let velocity = [(xn - xp) / (2.0 * dt), (yn - yp) / (2.0 * dt)];
        let [l, w, h] = self.class.size();
        let yaw = velocity[1].atan2(velocity[0]);
        Some(ObjectState { id: self.id, class: self.class, bbox: Box3d { x, y, z: h / 2.0, yaw, l, w, h }, velocity })
    }
}

/// The ego vehicle at one instant (world frame, reference point at the rear axle on the ground).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EgoState {
    /// Seconds from the start.
    pub t: f64,
    /// Road coordinates.
    pub s: f64,
    /// Lateral offset.
    pub d: f64,
    /// East.
    pub x: f64,
    /// North.
    pub y: f64,
    /// Heading, radians from east.
    pub heading: f64,
    /// Ground speed, m/s.
    pub speed: f64,
}

/// What the ego does at one work zone: change into the open lane and back, and slow down.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ZonePlan {
    /// Lane change into the open lane: (start s, end s); and back: (start s, end s).
    pub changes: [(f64, f64); 2],
    /// Where the zone speed applies: (from s, to s).
    pub slow: (f64, f64),
}

/// A swerve off the planned lane and back (a drive that leaves its lane on purpose).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Swerve {
    /// Where the move out starts and ends, s.
    pub out: (f64, f64),
    /// Where the move back starts and ends, s.
    pub back: (f64, f64),
    /// How far from the planned lane, m (positive: left).
    pub offset: f64,
}

impl Swerve {
    fn offset_at(&self, s: f64) -> f64 {
        if s < self.back.0 {
            lane_change(s, self.out.0, self.out.1, 0.0, self.offset)
        } else {
            lane_change(s, self.back.0, self.back.1, self.offset, 0.0)
        }
    }
}

/// Following too closely: the ego closes on a slower vehicle in its lane and brakes only
/// when braking at `brake` just stops it `gap` m behind (then keeps that gap).
#[derive(Clone, Debug, PartialEq)]
pub struct Tailgate {
    /// The vehicles it closes on.
    pub leads: Vec<Vehicle>,
    /// Bumper-to-bumper gap it keeps, m.
    pub gap: f64,
    /// How hard it brakes, m/s².
    pub brake: f64,
}

/// The nuPlan ego's rear axle → front bumper, m (the ego's size in every verdict).
const EGO_FRONT_M: f64 = dash2sim_core::obb::PACIFICA.front;

/// How the ego drives: cruise, slow for each zone, change lanes around each closure and back.
#[derive(Clone, Debug, PartialEq)]
pub struct EgoPlan {
    /// Start s.
    pub s0: f64,
    /// Speed outside the zone, m/s.
    pub cruise_speed: f64,
    /// Speed through the zone, m/s.
    pub zone_speed: f64,
    /// Largest acceleration, m/s².
    pub max_accel: f64,
    /// Largest deceleration, m/s² (it brakes for each zone this hard).
    pub max_brake: f64,
    /// How fast the acceleration may change, m/s³ (none: at once).
    pub max_jerk: Option<f64>,
    /// Lateral offsets of the open lane and the closed lane.
    pub lanes: (f64, f64),
    /// The zones along the road, in order.
    pub zones: Vec<ZonePlan>,
    /// A swerve out of the lane and back.
    pub swerve: Option<Swerve>,
    /// Vehicles it follows too closely.
    pub tailgate: Option<Tailgate>,
}

impl EgoPlan {
    fn lateral(&self, s: f64) -> f64 {
        let (open, closed) = self.lanes;
        let swerve = self.swerve.map_or(0.0, |w| w.offset_at(s));
        // The zone whose change back has not ended yet (past the last, the last).
        let Some(zone) = self.zones.iter().find(|z| s < z.changes[1].1).or(self.zones.last()) else {
            return closed + swerve;
        };
        let [(a0, a1), (b0, b1)] = zone.changes;
        swerve + if s < b0 { lane_change(s, a0, a1, closed, open) } else { lane_change(s, b0, b1, open, closed) }
    }

    /// The acceleration of the tailgating ego at `s` doing `v` m/s at `t` (its plan's speed
    /// `target`), once the nearest vehicle ahead in its lane is close: `brake` when braking
    /// that hard just stops it `gap` behind, else the vehicle's speed (or `target`, if lower)
    /// as its own; none while the vehicle is far.
    fn tailgate_accel(&self, road: &Road, t: f64, s: f64, v: f64, target: f64) -> Option<f64> {
        let tailgate = self.tailgate.as_ref()?;
        let d = self.lateral(s);
        tailgate
            .leads
            .iter()
            .filter(|lead| lead.state(road, t).is_some())
            .filter_map(|lead| {
                let (ls, ld) = lead.road_position(t);
                let gap = ls - lead.class.size()[0] / 2.0 - s - EGO_FRONT_M;
                ((ld - d).abs() < 0.75 * road.lane_width && ls > s).then_some((gap, lead.speed))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .and_then(|(gap, speed)| {
                let closing = v - speed;
                if closing > 0.0 && closing * closing / (2.0 * tailgate.brake) >= gap - tailgate.gap {
                    Some(-tailgate.brake)
                } else {
                    (gap < tailgate.gap + 5.0)
                        .then(|| ((target.min(speed) - v) / 0.5).clamp(-self.max_brake, self.max_accel))
                }
            })
    }

    /// Integrate the plan at 100 Hz or a little faster (a whole number of steps per state);
    /// one state every `1 / rate_hz` seconds for `duration_s`.
    pub fn drive(&self, road: &Road, duration_s: f64, rate_hz: f64) -> Vec<EgoState> {
        let per_frame = (100.0 / rate_hz).ceil().max(1.0) as usize;
        let dt = 1.0 / (rate_hz * per_frame as f64);
        let steps = (duration_s / dt).round() as usize;
        let (mut s, mut v, mut a) = (self.s0, self.cruise_speed, 0.0_f64);
        let mut states = Vec::with_capacity(steps / per_frame + 1);
        for k in 0..=steps {
            // Brake for the zone early enough to be at zone speed when it starts.
            let braking = (self.cruise_speed.powi(2) - self.zone_speed.powi(2)) / (2.0 * self.max_brake);
            let slow = self.zones.iter().any(|z| s + braking >= z.slow.0 && s < z.slow.1);
            let target = if slow { self.zone_speed } else { self.cruise_speed };
            let t = k as f64 * dt;
            let wanted = self
                .tailgate_accel(road, t, s, v, target)
                .unwrap_or_else(|| ((target - v) / 1.0).clamp(-self.max_brake, self.max_accel));
            a = match self.max_jerk {
                Some(jerk) => a + (wanted - a).clamp(-jerk * dt, jerk * dt),
                None => wanted,
            };
            if k % per_frame == 0 {
                let d = self.lateral(s);
                let (x, y) = road.point(s, d);
                // The heading and speed at `t` itself: the chord from a step before to a
                // step after. A chord from `t` forward points where the car heads half a
                // step later, and the receiver's course made from it was 5 ms ahead of its
                // fix.
                let s_next = s + self.along_reference(road, s, v * dt);
                let s_prev = s - self.along_reference(road, s - v * dt, v * dt);
                let (xn, yn) = road.point(s_next, self.lateral(s_next));
                let (xp, yp) = road.point(s_prev, self.lateral(s_prev));
                let heading = (yn - yp).atan2(xn - xp);
                let speed = (xn - xp).hypot(yn - yp) / (2.0 * dt);
                states.push(EgoState { t, s, d, x, y, heading, speed });
            }
            s += self.along_reference(road, s, (v * dt + 0.5 * a * dt * dt).max(0.0));
            v = (v + a * dt).max(0.0);
        }
        states
    }

    /// How far along the reference line `distance` metres of the ego's own path take it at
    /// `s`: a lane offset d from a line of curvature κ is (1 − κ·d) times as long, so that
    /// the speed plan holds along the ego's path, not along the reference line (otherwise
    /// the onset of a bend would read as a jump in speed on the outer lanes).
    fn along_reference(&self, road: &Road, s: f64, distance: f64) -> f64 {
        let stretch = 1.0 - road.pose(s).curvature * self.lateral(s);
        distance / stretch.max(0.1)
    }
}

#[cfg(test)]
mod tests {
    use super::super::road::{RoadPose, Segment};
    use super::*;

    #[test]
    fn the_speed_plan_holds_along_the_egos_own_path_through_a_bend() {
        // A lane 5.25 m right of a left bend of radius 300 m is 1.75 % longer than the
        // reference line: planned along the line, the ego would speed up by that much (and
        // jump at the bend's onset).
        let road = Road {
            segments: vec![Segment::Straight(100.0), Segment::Arc(300.0, 1.0 / 300.0), Segment::Straight(300.0)],
            start: RoadPose { x: 0.0, y: 0.0, heading: 0.0, curvature: 0.0 },
            lane_width: 3.5,
            lanes_forward: 2,
            lanes_backward: 2,
            speed_limit: 25.0,
        };
        let lane = road.forward_lane(0);
        let plan = EgoPlan {
            s0: 0.0,
            cruise_speed: 20.0,
            zone_speed: 20.0,
            max_accel: 1.5,
            max_brake: 1.5,
            max_jerk: None,
            lanes: (lane, lane),
            zones: vec![ZonePlan { changes: [(1e6, 1e6 + 1.0), (2e6, 2e6 + 1.0)], slow: (1e6, 1e6) }],
            swerve: None,
            tailgate: None,
        };
        let states = plan.drive(&road, 25.0, 10.0);
        assert!(states.iter().any(|e| (150.0..350.0).contains(&e.s)), "the drive passes the bend");
        for e in &states {
            assert!((e.speed - 20.0).abs() < 0.01, "t {}: {} m/s at s {}", e.t, e.speed, e.s);
        }
    }
}
