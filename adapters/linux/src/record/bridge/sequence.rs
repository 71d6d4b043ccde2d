//! What the logger missed on the bridge: gaps in each service's sequence numbers (issue #57).
//!
//! A subscriber keeps [`super::SUBSCRIBER_BUFFER`] samples per service (the IMU
//! [`super::IMU_SUBSCRIBER_BUFFER`]); a logger further behind loses the oldest to
//! iceoryx2's safe overflow, and nothing tells it so. Every message is numbered — frames,
//! VO poses and detections by their frame, IMU samples by the publisher's own count — so a
//! number that jumps ahead says how many were lost. A number that goes back is a restarted
//! camera process (nothing lost); an IMU number of 0 is a publisher that does not count.
//! A VO pose the camera never published (its VO had lost track) is a gap too: the count is
//! of frames without one, as the pipeline's "frame numbers skipped" issue counts them.
//! What was lost before the first message the logger received is not counted: nothing
//! says where the numbers began (a camera process that started before the logger).

/// A count per camera service.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ServiceCounts {
    /// Frame metadata messages.
    pub frames: u64,
    /// VO poses.
    pub vo_poses: u64,
    /// 3D detection messages (one per frame).
    pub detections3d: u64,
    /// 2D detection messages (one per frame).
    pub detections2d: u64,
    /// IMU samples.
    pub imu_samples: u64,
}

impl ServiceCounts {
    /// All services together.
    pub fn total(&self) -> u64 {
        self.frames + self.vo_poses + self.detections3d + self.detections2d + self.imu_samples
    }
}

impl std::fmt::Display for ServiceCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} frames, {} VO poses, {} 3D and {} 2D detection messages, {} IMU samples",
            self.frames, self.vo_poses, self.detections3d, self.detections2d, self.imu_samples
        )
    }
}

/// One service's numbers: the last seen.
#[derive(Clone, Copy, Debug, Default)]
struct Sequence {
    last: Option<u64>,
}

impl Sequence {
    /// The messages skipped before number `n`: none when it follows the last or goes back.
    fn skipped(&mut self, n: u64) -> u64 {
        let gap = match self.last {
            Some(last) if n > last => n - last - 1,
            _ => 0,
        };
        self.last = Some(n);
        gap
    }
}

/// The services' messages received and skipped.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tally {
    /// Received.
    pub received: ServiceCounts,
    /// Skipped in the numbers (lost to the subscriber's overflow, or never published).
    pub skipped: ServiceCounts,
    numbers: [Sequence; 5],
}

/// A camera service, for [`Tally::count`].
#[derive(Clone, Copy, Debug)]
pub enum Service {
    /// Frame metadata.
    Frame,
    /// VO poses.
    Vo,
    /// 3D detections.
    Detections3d,
    /// 2D detections.
    Detections2d,
    /// IMU samples (`number` 0: not numbered).
    Imu,
}

impl Tally {
    /// The last IMU sample's number (`None` before one, or from a publisher that does not
    /// number them).
    pub fn last_imu(&self) -> Option<u32> {
        self.numbers[4].last.and_then(|n| u32::try_from(n).ok())
    }

    /// One message of `service` numbered `number`.
    pub fn count(&mut self, service: Service, number: u64) {
        let (received, skipped, sequence) = match service {
            Service::Frame => (&mut self.received.frames, &mut self.skipped.frames, 0),
            Service::Vo => (&mut self.received.vo_poses, &mut self.skipped.vo_poses, 1),
            Service::Detections3d => (&mut self.received.detections3d, &mut self.skipped.detections3d, 2),
            Service::Detections2d => (&mut self.received.detections2d, &mut self.skipped.detections2d, 3),
            Service::Imu => (&mut self.received.imu_samples, &mut self.skipped.imu_samples, 4),
        };
        *received += 1;
        if matches!(service, Service::Imu) && number == 0 {
            return;
        }
        *skipped += self.numbers[sequence].skipped(number);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_jump_in_the_numbers_is_counted_and_a_restart_is_not() {
        let mut tally = Tally::default();
        for k in [1, 2, 5, 6, 1, 2, 4] {
            tally.count(Service::Frame, k);
        }
        assert_eq!(tally.received.frames, 7);
        assert_eq!(tally.skipped.frames, 2 + 1, "3 and 4 before the restart, 3 after it");
        for n in [0, 0, 0] {
            tally.count(Service::Imu, n);
        }
        assert_eq!((tally.received.imu_samples, tally.skipped.imu_samples), (3, 0), "not numbered");
        for n in [10, 11, 15] {
            tally.count(Service::Imu, n);
        }
        assert_eq!(tally.skipped.imu_samples, 3);
        assert_eq!(tally.skipped.vo_poses, 0, "services are counted apart");
    }
}
