//! The device's clocks: a monotonic time that survives a device clock reset, and the
//! offset from it to UTC that GNSS fixes reveal.
//!
//! Camera, CAN and serial inputs carry the device's clock; GNSS fixes carry UTC. The log
//! is written in UTC, and every part of the pipeline (anchoring, tracking, scoring) runs
//! on one *monotonic* time so that a clock step never reorders its inputs:
//!
//! * **Device clock reset.** A device time more than [`RESET_THRESHOLD_US`] before the
//!   latest one means the clock restarted (a watchdog reset, a counter wrap). Monotonic
//!   time goes on from where it was (the reset is assumed instantaneous); the next GNSS
//!   fix then sets the UTC offset afresh, whatever it says.
//! * **UTC offset.** Each fix gives `UTC − receive time`, which is the true offset minus
//!   the receiver's latency. The largest sample of the last [`WINDOW`] fixes is the one
//!   with the least latency, so it is the estimate (as NTP keeps the sample with the least
//!   delay). It is the true offset less the receiver's latency.
//! * **Receiver latency.** The latency as the device knows it (the anchorer's estimate,
//!   [`Clock::receiver_latency`]) is added to the offset, so that the log's UTC is the
//!   world's and not early by it. It is slewed in, as NTP slews a clock: a millisecond per
//!   [`SLEW_INTERVAL_US`] of input time ([`Clock::slew`]), so the log's time never jumps
//!   by the latency (a 0.1 s jump would be a jolt in every speed and acceleration read
//!   off the poses); its speeds read 1 % slow (or fast) while it does.
//! * **GNSS time step.** A sample more than [`STEP_THRESHOLD_US`] from the estimate is
//!   ignored — unless [`STEP_CONFIRMATIONS`] in a row agree with each other, in which case
//!   UTC really stepped (a leap second, a receiver that fixed its time) and the offset
//!   follows.

use heapless::Deque;

use crate::time::Timestamp;

/// A device time this much before the latest one is a clock reset, µs.
pub const RESET_THRESHOLD_US: i64 = 1_000_000;
/// A UTC sample this far from the estimate is a step candidate, µs.
pub const STEP_THRESHOLD_US: i64 = 500_000;
/// Consecutive agreeing step candidates that make a step real.
pub const STEP_CONFIRMATIONS: usize = 3;
/// Step candidates agree when within this of each other, µs.
const STEP_AGREEMENT_US: i64 = 100_000;
/// Samples the offset estimate is the maximum of.
pub const WINDOW: usize = 16;
/// A change of the estimate smaller than this is neither reported nor applied, µs.
pub const REPORT_CHANGE_US: i64 = 1_000;
/// A new latency estimate closer than this to the one aimed at is not taken, µs: the
/// estimate wanders by some milliseconds from fix to fix.
pub const LATENCY_CHANGE_US: i64 = 10_000;
/// The applied latency moves by [`SLEW_STEP_US`] each time this much input time has passed,
/// µs: 1 %.
pub const SLEW_INTERVAL_US: i64 = 100_000;
/// One step of the slew, µs.
pub const SLEW_STEP_US: i64 = 1_000;

/// What a UTC sample did to the offset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OffsetChange {
    /// Nothing worth reporting.
    None,
    /// The first offset: UTC is known from here on.
    First(i64),
    /// The estimate moved by more than a millisecond (clock drift).
    Drift(i64),
    /// UTC stepped and the offset followed; the difference to the previous offset, µs.
    Step {
        /// The new offset.
        offset: i64,
        /// New − old, µs.
        by: i64,
    },
    /// After a device clock reset, the first fix set the offset anew.
    AfterReset(i64),
    /// The receiver's latency as estimated was slewed in by a step; the new offset.
    Latency(i64),
    /// A sample this far from the estimate was ignored (a step candidate), µs.
    Ignored(i64),
}

/// Device → monotonic → UTC.
#[derive(Clone, Debug, Default)]
pub struct Clock {
    latest_device: Option<i64>,
    /// monotonic = device + correction.
    correction: i64,
    /// UTC − monotonic − the receiver's latency: what the fixes' arrivals say.
    offset: Option<i64>,
    /// The receiver's latency applied, µs.
    latency: i64,
    /// The receiver's latency the slew is heading for, µs.
    latency_target: i64,
    /// Monotonic time of the slew's last step (or of the last input while none was due).
    slewed_at: i64,
    /// The offset last reported (the latency included).
    reported: i64,
    samples: Deque<i64, WINDOW>,
    candidates: heapless::Vec<i64, STEP_CONFIRMATIONS>,
    after_reset: bool,
    resets: u32,
}

impl Clock {
    /// A clock that has seen nothing.
    pub fn new() -> Self {
        Self::default()
    }

    /// Monotonic time of a device time; the second value is the size of a device clock
    /// reset this input revealed (µs the clock went back), if any.
    pub fn monotonic(&mut self, device: Timestamp) -> (Timestamp, Option<i64>) {
        let d = device.micros();
        let mut reset = None;
        if let Some(latest) = self.latest_device {
            if d < latest.saturating_sub(RESET_THRESHOLD_US) {
                // Go on from the latest monotonic time, one microsecond later.
                let back = latest.saturating_sub(d);
                self.correction = self.correction.saturating_add(back.saturating_add(1));
                self.latest_device = Some(d);
                self.after_reset = true;
                self.resets = self.resets.saturating_add(1);
                reset = Some(back);
            } else if d > latest {
                self.latest_device = Some(d);
            }
        } else {
            self.latest_device = Some(d);
        }
        (Timestamp::from_micros(d.saturating_add(self.correction)), reset)
    }

    /// Device clock resets seen.
    pub fn resets(&self) -> u32 {
        self.resets
    }

    /// UTC − monotonic in force: the offset last reported (a change smaller than
    /// [`REPORT_CHANGE_US`] is not applied until it grows), so that a reader that knows
    /// the reported offsets recovers every device time exactly.
    pub fn offset(&self) -> Option<i64> {
        self.offset.map(|_| self.reported)
    }

    /// The log's time for a monotonic time: UTC once known, the monotonic time before.
    pub fn log_time(&self, monotonic: Timestamp) -> i64 {
        monotonic.micros().saturating_add(self.offset().unwrap_or(0))
    }

    /// A fix stamped `utc` was received at monotonic time `received`.
    pub fn utc_sample(&mut self, utc: Timestamp, received: Timestamp) -> OffsetChange {
        let sample = utc.micros().saturating_sub(received.micros());
        let in_force = sample.saturating_add(self.latency);
        let Some(offset) = self.offset else {
            return self.restart(sample, OffsetChange::First(in_force));
        };
        if self.after_reset {
            return self.restart(sample, OffsetChange::AfterReset(in_force));
        }
        let off_by = sample.saturating_sub(offset);
        if off_by.saturating_abs() < STEP_THRESHOLD_US {
            self.candidates.clear();
            if self.samples.is_full() {
                self.samples.pop_front();
            }
            // Cannot fail: a slot is free.
            let _ = self.samples.push_back(sample);
            let estimate = self.samples.iter().copied().max().unwrap_or(sample);
            self.offset = Some(estimate);
            let in_force = estimate.saturating_add(self.latency);
            if in_force.saturating_sub(self.reported).saturating_abs() >= REPORT_CHANGE_US {
                self.reported = in_force;
                return OffsetChange::Drift(in_force);
            }
            return OffsetChange::None;
        }
        let agrees = self.candidates.iter().all(|c| c.saturating_sub(sample).saturating_abs() < STEP_AGREEMENT_US);
        if !agrees {
            self.candidates.clear();
        }
        // Cannot fail: the list is emptied when it fills (below).
        let _ = self.candidates.push(sample);
        if self.candidates.is_full() {
            let step = self.candidates.iter().copied().max().unwrap_or(sample);
            self.candidates.clear();
            let by = step.saturating_sub(offset);
            return self.restart(step, OffsetChange::Step { offset: step.saturating_add(self.latency), by });
        }
        OffsetChange::Ignored(off_by)
    }

    /// The receiver's latency as the device now estimates it, µs (the time from a fix's
    /// UTC to its arrival): the slew heads for it when it differs by [`LATENCY_CHANGE_US`]
    /// or more from the latency it heads for now (`true` then). A latency outside 0–1 s is
    /// no receiver's and is ignored.
    pub fn receiver_latency(&mut self, latency_us: i64) -> bool {
        let far = latency_us.saturating_sub(self.latency_target).saturating_abs() >= LATENCY_CHANGE_US;
        if (0..=1_000_000).contains(&latency_us) && far {
            self.latency_target = latency_us;
            return true;
        }
        false
    }

    /// One step of the slew towards the receiver's latency, when one is due at monotonic
    /// time `now`: [`OffsetChange::Latency`] with the new offset (to be written), or
    /// [`OffsetChange::None`].
    pub fn slew(&mut self, now: Timestamp) -> OffsetChange {
        let now = now.micros();
        let Some(offset) = self.offset.filter(|_| self.latency != self.latency_target) else {
            self.slewed_at = now;
            return OffsetChange::None;
        };
        if now.saturating_sub(self.slewed_at) < SLEW_INTERVAL_US {
            return OffsetChange::None;
        }
        let step = self.latency_target.saturating_sub(self.latency).clamp(-SLEW_STEP_US, SLEW_STEP_US);
        self.latency = self.latency.saturating_add(step);
        self.slewed_at = now;
        self.reported = offset.saturating_add(self.latency);
        OffsetChange::Latency(self.reported)
    }

    /// UTC from `offset` (the fixes' arrivals) on, after its first fix, a step or a reset;
    /// `change` says which, with the offset in force.
    fn restart(&mut self, offset: i64, change: OffsetChange) -> OffsetChange {
        self.samples.clear();
        let _ = self.samples.push_back(offset);
        self.candidates.clear();
        self.offset = Some(offset);
        self.reported = offset.saturating_add(self.latency);
        self.after_reset = false;
        change
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(us: i64) -> Timestamp {
        Timestamp::from_micros(us)
    }

    #[test]
    fn the_offset_is_the_sample_with_the_least_latency() {
        let mut c = Clock::new();
        let utc0 = 1_780_300_800_000_000;
        assert_eq!(c.utc_sample(t(utc0), t(80_000)), OffsetChange::First(utc0 - 80_000));
        // Later fixes arrive with less latency: the offset rises to the least-latency one.
        assert!(matches!(c.utc_sample(t(utc0 + 200_000), t(260_000)), OffsetChange::Drift(_)));
        assert_eq!(c.offset(), Some(utc0 - 60_000));
        assert_eq!(c.utc_sample(t(utc0 + 400_000), t(490_000)), OffsetChange::None);
        assert_eq!(c.offset(), Some(utc0 - 60_000));
        // Less latency by half a millisecond: not applied (nor reported) until it grows.
        assert_eq!(c.utc_sample(t(utc0 + 600_000), t(659_500)), OffsetChange::None);
        assert_eq!(c.offset(), Some(utc0 - 60_000));
        assert_eq!(c.log_time(t(1_000_000)), utc0 - 60_000 + 1_000_000);
    }

    #[test]
    fn the_receivers_latency_is_slewed_in_a_millisecond_per_tenth_of_a_second() {
        let mut c = Clock::new();
        let base = 1_000_000_000_000;
        // Within 10 ms of none: not taken.
        assert!(!c.receiver_latency(3_000));
        // Known before UTC is: kept, and slewed in once UTC is known.
        assert!(c.receiver_latency(12_000));
        assert_eq!(c.slew(t(0)), OffsetChange::None);
        assert_eq!(c.utc_sample(t(base), t(0)), OffsetChange::First(base));
        let mut steps: heapless::Vec<(i64, i64), 16> = heapless::Vec::new();
        for k in 1..=100 {
            if let OffsetChange::Latency(o) = c.slew(t(k * 20_000)) {
                steps.push((k * 20_000, o)).expect("twelve steps");
            }
        }
        assert_eq!(steps.len(), 12);
        assert_eq!(steps[..2], [(100_000, base + 1_000), (200_000, base + 2_000)]);
        assert_eq!(steps.last(), Some(&(1_200_000, base + 12_000)));
        assert_eq!(c.offset(), Some(base + 12_000));
        // Within 10 ms of the latency aimed at: not taken; nor a latency beyond 1 s or below 0.
        assert!(!c.receiver_latency(21_000));
        assert!(!c.receiver_latency(1_500_000));
        assert!(!c.receiver_latency(-20_000));
        assert_eq!(c.slew(t(5_000_000)), OffsetChange::None);
        // A new estimate 11 ms lower: down by a millisecond a tenth of a second.
        assert!(c.receiver_latency(1_000));
        assert_eq!(c.slew(t(5_050_000)), OffsetChange::None);
        assert_eq!(c.slew(t(5_100_000)), OffsetChange::Latency(base + 11_000));
        assert_eq!(c.slew(t(5_200_000)), OffsetChange::Latency(base + 10_000));
        for k in 3..=12 {
            c.slew(t(5_000_000 + k * 100_000));
        }
        assert_eq!(c.offset(), Some(base + 1_000));
        assert_eq!(c.slew(t(6_300_000)), OffsetChange::None);
        // The fixes' arrivals move the offset with the latency kept in it.
        assert_eq!(c.utc_sample(t(base + 7_000_000 + 5_000), t(7_000_000)), OffsetChange::Drift(base + 6_000));
    }

    #[test]
    fn a_one_off_time_error_is_ignored_and_a_lasting_step_is_followed() {
        let mut c = Clock::new();
        let base = 1_000_000_000_000;
        c.utc_sample(t(base), t(0));
        // One fix a second early: ignored.
        assert_eq!(c.utc_sample(t(base + 200_000 - 1_000_000), t(200_000)), OffsetChange::Ignored(-1_000_000));
        assert_eq!(c.utc_sample(t(base + 400_000), t(400_000)), OffsetChange::None);
        assert_eq!(c.offset(), Some(base));
        // UTC steps back by a second and stays there: the third agreeing fix moves the offset.
        for k in 0..2 {
            let rx = 600_000 + 200_000 * k;
            assert!(matches!(c.utc_sample(t(base + rx - 1_000_000), t(rx)), OffsetChange::Ignored(_)));
        }
        assert_eq!(
            c.utc_sample(t(base + 1_000_000 - 1_000_000), t(1_000_000)),
            OffsetChange::Step { offset: base - 1_000_000, by: -1_000_000 }
        );
        assert_eq!(c.offset(), Some(base - 1_000_000));
    }

    #[test]
    fn a_device_clock_reset_keeps_monotonic_time_going_and_the_next_fix_resets_utc() {
        let mut c = Clock::new();
        assert_eq!(c.monotonic(t(50_000_000)), (t(50_000_000), None));
        c.utc_sample(t(9_000_000_000), t(50_000_000));
        // Small disorder between streams is not a reset.
        assert_eq!(c.monotonic(t(49_900_000)), (t(49_900_000), None));
        let (m, reset) = c.monotonic(t(1_000));
        assert_eq!(reset, Some(50_000_000 - 1_000));
        assert_eq!(m, t(50_000_001));
        assert_eq!(c.monotonic(t(2_000)).0, t(50_001_001));
        assert_eq!(c.resets(), 1);
        // The device was down for 3 s: the first fix after the reset sets the offset anew.
        let rx = c.monotonic(t(3_000)).0;
        let utc = t(9_000_000_000 + 3_000_000 + 3_000);
        assert_eq!(c.utc_sample(utc, rx), OffsetChange::AfterReset(utc.micros() - rx.micros()));
    }
}
