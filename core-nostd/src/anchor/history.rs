//! Recent visual-odometry samples and the wheel odometer, for looking a little into the
//! past: a GNSS fix describes where the antenna was some tens of milliseconds before it
//! arrived, so anchors are paired with the VO position at `t_rx − latency`.

use heapless::Deque;
use nalgebra::Vector3;

use crate::time::Timestamp;

/// One VO sample with the wheel odometer reading at the same instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VoSample {
    pub t: Timestamp,
    pub position: Vector3<f64>,
    /// Distance travelled by the wheels since the start (m), when speed is known.
    pub odometer_m: Option<f64>,
}

/// The last `N` VO samples, oldest first.
#[derive(Clone, Debug)]
pub(crate) struct VoHistory<const N: usize> {
    samples: Deque<VoSample, N>,
}

impl<const N: usize> VoHistory<N> {
    pub const fn new() -> Self {
        VoHistory { samples: Deque::new() }
    }

    /// The positions in other coordinates, p → `r`·p.
    pub fn turn(&mut self, r: &nalgebra::Matrix3<f64>) {
        for s in self.samples.iter_mut() {
            s.position = r * s.position;
        }
    }

    pub fn latest(&self) -> Option<&VoSample> {
        self.samples.back()
    }

    pub fn push(&mut self, sample: VoSample) {
        if self.samples.is_full() {
            self.samples.pop_front();
        }
        // Cannot fail: a slot was freed above when full.
        let _ = self.samples.push_back(sample);
    }

    /// Linear interpolation of position and odometer at `t`; `None` when `t` lies
    /// outside the stored span.
    pub fn at(&self, t: Timestamp) -> Option<(Vector3<f64>, Option<f64>)> {
        let mut prev: Option<&VoSample> = None;
        for s in self.samples.iter() {
            if s.t == t {
                return Some((s.position, s.odometer_m));
            }
            if s.t > t {
                let p = prev?;
                let span = (s.t - p.t).as_secs_f64();
                let f = (t - p.t).as_secs_f64() / span;
                let odo = match (p.odometer_m, s.odometer_m) {
                    (Some(a), Some(b)) => Some(a + (b - a) * f),
                    _ => None,
                };
                return Some((p.position + (s.position - p.position) * f, odo));
            }
            prev = Some(s);
        }
        None
    }
}

/// Integrates wheel/vehicle speed into travelled distance.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Odometer {
    last: Option<(Timestamp, f64)>,
    distance_m: f64,
}

/// Speed older than this no longer describes the motion at a VO frame.
const MAX_SPEED_AGE_S: f64 = 0.5;

impl Odometer {
    /// Trapezoidal integration between consecutive samples.
    pub fn push(&mut self, t: Timestamp, speed_mps: f64) {
        if let Some((t0, v0)) = self.last {
            let dt = (t - t0).as_secs_f64();
            if dt <= MAX_SPEED_AGE_S {
                self.distance_m += 0.5 * (v0 + speed_mps) * dt;
            }
        }
        self.last = Some((t, speed_mps));
    }

    pub fn last_time(&self) -> Option<Timestamp> {
        self.last.map(|(t, _)| t)
    }

    /// The odometer reading at `t`, extrapolated at the latest speed; `None` when no
    /// recent speed is known.
    pub fn at(&self, t: Timestamp) -> Option<f64> {
        let (t0, v0) = self.last?;
        let dt = (t - t0).as_secs_f64();
        (libm::fabs(dt) <= MAX_SPEED_AGE_S).then_some(self.distance_m + v0 * dt)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ts(s: f64) -> Timestamp {
        Timestamp::from_secs_f64(s).expect("finite")
    }

    #[test]
    fn interpolates_inside_and_refuses_outside() {
        let mut h: VoHistory<4> = VoHistory::new();
        for k in 0..6 {
            h.push(VoSample {
                t: ts(k as f64 * 0.1),
                position: Vector3::new(k as f64, 0.0, 0.0),
                odometer_m: Some(k as f64 * 2.0),
            });
        }
        // Oldest two were evicted.
        assert_eq!(h.at(ts(0.1)), None);
        let (p, odo) = h.at(ts(0.35)).expect("inside");
        assert!((p.x - 3.5).abs() < 1e-9);
        assert!((odo.expect("known") - 7.0).abs() < 1e-9);
        assert_eq!(h.at(ts(0.6)), None);
    }

    #[test]
    fn odometer_integrates_and_expires() {
        let mut o = Odometer::default();
        o.push(ts(0.0), 10.0);
        o.push(ts(0.1), 12.0);
        assert!((o.at(ts(0.1)).expect("fresh") - 1.1).abs() < 1e-12);
        assert!((o.at(ts(0.2)).expect("fresh") - 2.3).abs() < 1e-12);
        assert_eq!(o.at(ts(5.0)), None);
    }
}
