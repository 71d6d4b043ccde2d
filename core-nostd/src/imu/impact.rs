//! The G-sensor's trigger: an impact is a spike of the specific force past what gravity
//! and the car's own motion explain, beyond a configurable threshold (a dashcam's "G-sensor
//! sensitivity"; [`DEFAULT_THRESHOLD_MPS2`]). One impact is counted once: the trigger
//! re-arms after [`REARM_S`] below half the threshold. Like a collision in a verification
//! window, an impact keeps its file under loop recording.

use nalgebra::Vector3;

/// Default threshold, m/s² (2 g: a kerb strike or a collision; potholes stay below).
pub const DEFAULT_THRESHOLD_MPS2: f64 = 2.0 * super::GRAVITY;
/// Quiet time before the trigger re-arms, s.
pub const REARM_S: f64 = 2.0;

/// The trigger's state.
#[derive(Clone, Copy, Debug, Default)]
pub struct Impact {
    quiet_s: f64,
    fired: bool,
}

impl Impact {
    /// One sample over `dt` s: the specific force not explained by gravity and motion
    /// (body frame, m/s²) against `threshold`; the spike's magnitude when an impact begins.
    pub fn push(&mut self, dt: f64, unexplained: &Vector3<f64>, threshold: f64) -> Option<f64> {
        let magnitude = unexplained.norm();
        if !(magnitude.is_finite() && dt.is_finite()) {
            return None;
        }
        if self.fired {
            if magnitude < 0.5 * threshold {
                self.quiet_s += dt.max(0.0);
            } else {
                self.quiet_s = 0.0;
            }
            if self.quiet_s >= REARM_S {
                self.fired = false;
            }
            return None;
        }
        if magnitude >= threshold {
            self.fired = true;
            self.quiet_s = 0.0;
            return Some(magnitude);
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_knock_is_one_impact_and_the_trigger_rearms() {
        let mut i = Impact::default();
        let quiet = Vector3::new(0.5, 0.2, 0.3);
        let knock = Vector3::new(-30.0, 5.0, 2.0);
        assert_eq!(i.push(0.01, &quiet, DEFAULT_THRESHOLD_MPS2), None);
        let fired = i.push(0.01, &knock, DEFAULT_THRESHOLD_MPS2);
        assert!(fired.is_some_and(|m| (m - knock.norm()).abs() < 1e-12));
        // The ringing after it is the same impact.
        for k in 0..50 {
            let ring = if k % 2 == 0 { knock } else { quiet };
            assert_eq!(i.push(0.01, &ring, DEFAULT_THRESHOLD_MPS2), None);
        }
        for _ in 0..199 {
            assert_eq!(i.push(0.01, &quiet, DEFAULT_THRESHOLD_MPS2), None);
        }
        assert_eq!(i.push(0.01, &quiet, DEFAULT_THRESHOLD_MPS2), None);
        assert!(i.push(0.01, &knock, DEFAULT_THRESHOLD_MPS2).is_some(), "re-armed after 2 s of quiet");
        // A higher threshold ignores the same knock.
        assert_eq!(Impact::default().push(0.01, &knock, 4.0 * super::super::GRAVITY), None);
    }
}
