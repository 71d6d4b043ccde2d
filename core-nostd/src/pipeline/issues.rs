//! What the pipeline refused or could not use, counted per reason and written to the log
//! as events — at most one event per reason per second, each with the running count, so
//! that a flood of bad input (10 000 CAN frames in a burst, a detector gone mad) cannot
//! flood the log.

/// Why an input (or part of one) was not used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Issue {
    /// A VO pose with NaN or infinite values.
    VoNotFinite,
    /// A VO pose not after the previous one (time or frame number).
    VoOutOfOrder,
    /// A speed sample earlier than the previous one, or not finite.
    SpeedRefused,
    /// A GNSS fix the anchorer refused (out of order, bad σ, not finite).
    GnssRefused,
    /// A GNSS fix without a position, or outside the WGS84 range.
    GnssNoPosition,
    /// A GNSS fix whose UTC disagreed with the clock (ignored as a time source).
    GnssTimeIgnored,
    /// An NMEA sentence with a bad checksum, malformed, or with bad fields.
    NmeaBadSentence,
    /// Bytes the NMEA framer dropped (too long, binary, interrupted).
    NmeaDropped,
    /// A CAN frame of a decoded message that was malformed, or a fast packet given up.
    CanBadFrame,
    /// Detections of a frame not after the previous frame.
    DetectionsOutOfOrder,
    /// 3D detections with no VO pose of their frame (before the first pose, or a gap).
    DetectionsWithoutPose,
    /// Detections the tracker refused (implausible, over capacity).
    DetectionsRefused,
    /// A device clock reset (the clock went back by more than a second).
    ClockReset,
    /// The log could not take a record (an event text too long).
    RecordRefused,
    /// Frame numbers skipped between consecutive VO poses (counted per missing frame): the
    /// camera process dropped frames, or was restarted.
    FramesMissing,
    /// Inputs the host dropped before the pipeline (a logger slower than its inputs).
    InputsDropped,
    /// The camera's frame numbers started again (its process restarted).
    CameraRestarted,
    /// A VO session number lower than the one before (taken as a new session).
    VoSessionBackwards,
    /// An IMU sample not finite or beyond any consumer sensor's full scale.
    ImuRefused,
    /// An IMU sample not after the previous one.
    ImuOutOfOrder,
    /// IMU samples refused because the stream's units are not rad/s and m/s² (gravity
    /// reads about 1: g; the gyro turns ~57 times as fast as the GNSS course: °/s).
    ImuUnits,
    /// IMU samples refused because gravity is far off the body's up: the sensor's axes or
    /// its mount are not as configured.
    ImuAxes,
    /// A VO pose not used: the relative motion is gyro + wheels.
    VoNotUsed,
}

impl Issue {
    /// Every reason, in counter order.
    pub const ALL: [Issue; 23] = [
        Issue::VoNotFinite,
        Issue::VoOutOfOrder,
        Issue::SpeedRefused,
        Issue::GnssRefused,
        Issue::GnssNoPosition,
        Issue::GnssTimeIgnored,
        Issue::NmeaBadSentence,
        Issue::NmeaDropped,
        Issue::CanBadFrame,
        Issue::DetectionsOutOfOrder,
        Issue::DetectionsWithoutPose,
        Issue::DetectionsRefused,
        Issue::ClockReset,
        Issue::RecordRefused,
        Issue::FramesMissing,
        Issue::InputsDropped,
        Issue::CameraRestarted,
        Issue::VoSessionBackwards,
        Issue::ImuRefused,
        Issue::ImuOutOfOrder,
        Issue::ImuUnits,
        Issue::ImuAxes,
        Issue::VoNotUsed,
    ];

    /// How the event names it.
    pub const fn text(self) -> &'static str {
        match self {
            Issue::VoNotFinite => "VO pose not finite",
            Issue::VoOutOfOrder => "VO pose out of order",
            Issue::SpeedRefused => "speed sample refused (out of order or not finite)",
            Issue::GnssRefused => "GNSS fix refused by the anchorer",
            Issue::GnssNoPosition => "GNSS fix without a usable position",
            Issue::GnssTimeIgnored => "GNSS time disagrees with the clock (ignored as time source)",
            Issue::NmeaBadSentence => "NMEA sentence rejected (checksum, format or fields)",
            Issue::NmeaDropped => "NMEA bytes dropped by the framer",
            Issue::CanBadFrame => "CAN frame malformed or fast packet given up",
            Issue::DetectionsOutOfOrder => "detections out of order",
            Issue::DetectionsWithoutPose => "3D detections without a VO pose of their frame (logged raw)",
            Issue::DetectionsRefused => "detections refused by the tracker (implausible or over capacity)",
            Issue::ClockReset => "device clock reset",
            Issue::RecordRefused => "record refused by the log writer",
            Issue::FramesMissing => "camera frames missing (frame numbers skipped)",
            Issue::InputsDropped => "inputs dropped before the pipeline (logger behind)",
            Issue::CameraRestarted => "camera process restarted (frame numbers started again)",
            Issue::VoSessionBackwards => "VO session number went back (taken as a new session)",
            Issue::ImuRefused => "IMU sample refused (not finite or beyond full scale)",
            Issue::ImuOutOfOrder => "IMU sample out of order",
            Issue::ImuUnits => "IMU sample refused (units not rad/s and m/s²)",
            Issue::ImuAxes => "IMU sample refused (axes or mount not as configured)",
            Issue::VoNotUsed => "VO pose not used (the relative motion is gyro + wheels)",
        }
    }

    fn index(self) -> usize {
        self as usize
    }
}

/// Counts per reason and when each was last written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Issues {
    counts: [u64; Issue::ALL.len()],
    /// Monotonic µs of the last event per reason, and the count it reported.
    reported: [Option<(i64, u64)>; Issue::ALL.len()],
}

/// An event is written at most this often per reason, µs.
pub const EVENT_INTERVAL_US: i64 = 1_000_000;

impl Issues {
    /// Count `n` occurrences at monotonic time `now_us`; returns the running count when an
    /// event should be written now.
    pub fn count(&mut self, issue: Issue, n: u64, now_us: i64) -> Option<u64> {
        let i = issue.index();
        let total = self.counts.get(i).copied().unwrap_or(0).saturating_add(n);
        if let Some(c) = self.counts.get_mut(i) {
            *c = total;
        }
        let due =
            self.reported.get(i).copied().flatten().is_none_or(|(t, _)| now_us.saturating_sub(t) >= EVENT_INTERVAL_US);
        if due {
            if let Some(r) = self.reported.get_mut(i) {
                *r = Some((now_us, total));
            }
            return Some(total);
        }
        None
    }

    /// How many of this reason so far.
    pub fn get(&self, issue: Issue) -> u64 {
        self.counts.get(issue.index()).copied().unwrap_or(0)
    }

    /// Reasons whose latest count has not been written yet, with that count.
    pub fn unreported(&self) -> impl Iterator<Item = (Issue, u64)> + '_ {
        Issue::ALL.iter().zip(self.counts.iter().zip(&self.reported)).filter_map(|(issue, (count, reported))| {
            (*count > 0 && reported.is_none_or(|(_, written)| written != *count)).then_some((*issue, *count))
        })
    }

    /// Total of every reason (saturating: a count comes from the input, e.g. the drops a
    /// logger reports, and each saturates on its own).
    pub fn total(&self) -> u64 {
        self.counts.iter().fold(0u64, |sum, c| sum.saturating_add(*c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts taken from the input (a logger's drop count) can be anything: the total
    /// saturates instead of overflowing (a fuzz crash, `fuzz/fuzz_targets/pipeline_inputs.rs`).
    #[test]
    fn the_total_of_huge_counts_saturates() {
        let mut issues = Issues::default();
        issues.count(Issue::InputsDropped, u64::MAX - 1, 0);
        issues.count(Issue::CanBadFrame, 7, 0);
        issues.count(Issue::InputsDropped, 5, 1);
        assert_eq!(issues.get(Issue::InputsDropped), u64::MAX);
        assert_eq!(issues.total(), u64::MAX);
    }

    #[test]
    fn events_are_rate_limited_per_reason_and_the_tail_is_reported_at_the_end() {
        let mut issues = Issues::default();
        assert_eq!(issues.count(Issue::CanBadFrame, 1, 0), Some(1));
        for k in 0..9_999 {
            assert_eq!(issues.count(Issue::CanBadFrame, 1, 10 + k), None);
        }
        assert_eq!(issues.count(Issue::VoNotFinite, 1, 20), Some(1), "another reason has its own budget");
        assert_eq!(issues.get(Issue::CanBadFrame), 10_000);
        let tail: heapless::Vec<(Issue, u64), 4> = issues.unreported().collect();
        assert_eq!(tail.as_slice(), &[(Issue::CanBadFrame, 10_000)]);
        assert_eq!(issues.count(Issue::CanBadFrame, 1, EVENT_INTERVAL_US), Some(10_001));
        assert_eq!(issues.total(), 10_002);
    }
}
