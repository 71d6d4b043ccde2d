//! Frame numbers that must go up: the 2D and 3D trackers and the pipeline's tracking stage
//! each refuse a frame that is not after the previous one, through this one check.

/// Why a frame was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TrackError {
    /// The frame number is not after the previous one.
    OutOfOrder {
        /// Previous frame.
        previous: u64,
        /// This frame.
        frame: u64,
    },
}

impl core::fmt::Display for TrackError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            TrackError::OutOfOrder { previous, frame } => write!(f, "frame {frame} is not after frame {previous}"),
        }
    }
}

impl core::error::Error for TrackError {}

/// The latest frame accepted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FrameOrder {
    last: Option<u64>,
}

impl FrameOrder {
    /// No frame yet.
    pub const fn new() -> Self {
        FrameOrder { last: None }
    }

    /// The latest frame accepted.
    pub fn last(&self) -> Option<u64> {
        self.last
    }

    /// Accept `frame` when it is after the latest: the frame numbers it moves on by (1 for
    /// the first frame). A frame not after the latest is refused and nothing changes.
    pub fn advance(&mut self, frame: u64) -> Result<u64, TrackError> {
        let steps = match self.last {
            Some(previous) if frame <= previous => return Err(TrackError::OutOfOrder { previous, frame }),
            Some(previous) => frame - previous,
            None => 1,
        };
        self.last = Some(frame);
        Ok(steps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_must_go_up_and_a_refusal_changes_nothing() {
        let mut order = FrameOrder::new();
        assert_eq!(order.advance(7), Ok(1));
        assert_eq!(order.advance(10), Ok(3));
        assert_eq!(order.advance(10), Err(TrackError::OutOfOrder { previous: 10, frame: 10 }));
        assert_eq!(order.advance(4), Err(TrackError::OutOfOrder { previous: 10, frame: 4 }));
        assert_eq!(order.last(), Some(10));
        assert_eq!(order.advance(11), Ok(1));
    }
}
