//! The VO session's vertical from gravity: the dashcam's accelerometer knows which way is
//! up in the camera's axes; each VO pose turns that into the VO frame, and their mean —
//! handed to the anchorer ([`crate::anchor::Anchorer::level`]) after 1, 3, 10 and 30 s of
//! the session — lets it solve the session gravity-aligned. On a straight road that is
//! what anchors a phone-grade receiver's fixes at all: the roll about the road is
//! gravity's to give, no position shows it.

use nalgebra::Vector3;

/// The numbers of poses after which the mean is handed on (at 10 Hz: 1, 3, 10 and 30 s).
const LEVEL_AT: [u32; 4] = [10, 30, 100, 300];

/// The running mean of one VO session's vertical.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Vertical {
    session: Option<u32>,
    sum: Vector3<f64>,
    poses: u32,
}

impl Vertical {
    /// The vertical in VO coordinates at a pose of `session` (a unit vector); the session's
    /// mean when it is due to be handed on.
    pub(super) fn push(&mut self, session: u32, up_in_vo: &Vector3<f64>) -> Option<Vector3<f64>> {
        if !up_in_vo.iter().all(|v| v.is_finite()) {
            return None;
        }
        if self.session != Some(session) {
            *self = Vertical { session: Some(session), ..Vertical::default() };
        }
        self.sum += up_in_vo;
        self.poses = self.poses.saturating_add(1);
        LEVEL_AT.contains(&self.poses).then_some(self.sum)
    }

    /// The poses of the current session it rests on.
    pub(super) fn poses(&self) -> u32 {
        self.poses
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_is_handed_on_at_its_steps_and_a_new_session_starts_afresh() {
        let mut v = Vertical::default();
        let up = Vector3::new(0.0, 0.6, 0.8);
        let due: heapless::Vec<u32, 8> = (1..=400).filter(|_| v.push(0, &up).is_some()).collect();
        assert_eq!(due.as_slice(), &LEVEL_AT);
        // Another session: its own count and mean.
        let other = Vector3::new(0.8, 0.0, 0.6);
        assert!(v.push(1, &other).is_none());
        assert_eq!(v.poses(), 1);
        let mean = (2..=10).filter_map(|_| v.push(1, &other)).last().expect("due at 10");
        assert!((mean.normalize() - other).norm() < 1e-12);
        // A pose whose vertical is not finite is not counted.
        assert!(v.push(1, &Vector3::new(f64::NAN, 0.0, 1.0)).is_none());
        assert_eq!(v.poses(), 10);
    }
}
