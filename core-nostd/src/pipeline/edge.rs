//! A collision at a window's end counts in the next window too.
//!
//! The device's ego runs a few metres ahead of or behind the true one along the road (σ
//! 1–2 m: a tenth of a second or two at 10–15 m/s), so a collision the truth has just after a
//! window's end the device may meet just before it, and reject the window before while
//! verifying the one that really holds the collision (seed 1056 of the typical sweep:
//! docs/fidelity.md). A window uploaded as verified must not hold a collision: an at-fault
//! collision in the last [`EDGE_S`] of a window is carried into the next one, which scores
//! it as its own (nuPlan's multiplier, the aggregate and the verdict recomputed).
//!
//! Only this direction: a collision the device meets just *after* a window's end would need
//! the window held open for [`EDGE_S`] more; the sweeps never showed one.

use crate::score::{AgentKind, Collision, Scores, VERIFIED_ABOVE};

/// How close to a window's end a collision is carried into the next window, s.
pub const EDGE_S: f64 = 1.0;

/// nuPlan's no-at-fault-collisions multiplier for one collision: 0 for a vehicle or a
/// vulnerable road user, 0.5 for a static object.
fn multiplier(collision: &Collision) -> f64 {
    match collision.kind {
        AgentKind::Vehicle | AgentKind::Vru => 0.0,
        AgentKind::Object => 0.5,
    }
}

/// The latest at-fault collision the windows met.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EdgeCollisions {
    /// Its time (s) and multiplier.
    last: Option<(f64, f64)>,
}

impl EdgeCollisions {
    /// A collision the window met at `t` s.
    pub fn push(&mut self, t: f64, collision: &Collision) {
        if collision.at_fault && t.is_finite() {
            self.last = Some((t, multiplier(collision)));
        }
    }

    /// The multiplier a window starting at `start` s inherits from a collision in the last
    /// [`EDGE_S`] before it.
    pub fn carried_into(&self, start: f64) -> Option<f64> {
        self.last.filter(|(t, _)| *t < start && start - *t <= EDGE_S).map(|(_, m)| m)
    }
}

/// `scores` with an inherited collision's multiplier: the lower one kept, the aggregate
/// and the verdict recomputed.
pub fn inherit(scores: &Scores, multiplier: f64) -> Scores {
    let own = scores.no_at_fault_collisions;
    let lowered = own.min(multiplier);
    let score = if own > 0.0 { scores.score * lowered / own } else { scores.score };
    Scores { no_at_fault_collisions: lowered, score, verified: score > VERIFIED_ABOVE, ..*scores }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn collision(kind: AgentKind, at_fault: bool) -> Collision {
        Collision { id: 7, kind, at_fault }
    }

    #[test]
    fn a_collision_at_a_window_end_is_carried_into_the_next_only() {
        let mut edge = EdgeCollisions::default();
        assert_eq!(edge.carried_into(10.0), None);
        edge.push(9.5, &collision(AgentKind::Object, false));
        assert_eq!(edge.carried_into(10.0), None, "not at fault");
        edge.push(9.5, &collision(AgentKind::Object, true));
        assert_eq!(edge.carried_into(10.0), Some(0.5));
        assert_eq!(edge.carried_into(10.6), None, "more than EDGE_S before the start");
        assert_eq!(edge.carried_into(9.0), None, "after the start: the window's own");
        edge.push(9.8, &collision(AgentKind::Vru, true));
        assert_eq!(edge.carried_into(10.0), Some(0.0));
    }

    #[test]
    fn an_inherited_collision_rejects_a_verified_window() {
        let verified = Scores {
            no_at_fault_collisions: 1.0,
            drivable_area: 1.0,
            driving_direction: 1.0,
            making_progress: 1.0,
            progress: 1.0,
            ttc: 1.0,
            speed_limit: 1.0,
            comfort: 1.0,
            score: 100.0,
            verified: true,
            poses: 150,
            noncompliant_poses: 0,
            worst_corner: -0.5,
            min_direction_progress: 0.0,
            min_ttc: f64::INFINITY,
            collisions: (0, 0, 0),
            overspeed_integral: 0.0,
            ego_progress: 200.0,
            duration: 15.0,
            comfort_extremes: crate::score::Comfort {
                lon_accel: (-1.0, 1.0),
                lat_accel: 1.0,
                jerk: 1.0,
                lon_jerk: 1.0,
                yaw_rate: 0.1,
                yaw_accel: 0.1,
            },
        };
        let carried = inherit(&verified, 0.5);
        assert_eq!((carried.no_at_fault_collisions, carried.score, carried.verified), (0.5, 50.0, false));
        // A window that hit something itself keeps the lower multiplier.
        let hit = inherit(&carried, 0.5);
        assert_eq!((hit.no_at_fault_collisions, hit.score), (0.5, 50.0));
        let vehicle = inherit(&verified, 0.0);
        assert_eq!((vehicle.score, vehicle.verified), (0.0, false));
    }
}
