//! The camera's pitch on the car from where the objects it detects stand.
//!
//! With VO the mount calibration reads the camera's pitch off the direction of travel
//! ([`super::calibration`]). Without it (gyro + wheels) nothing sees that direction from the
//! camera: the dead-reckoned camera is pitched as gravity says, and gravity's pitch carries
//! the accelerometer's bias and the sensor's tilt in its housing — 1–1.5° on the sweep's
//! drives. A camera pitch 1° off puts an object 30 m ahead half a metre above or below the
//! road, where the tracker refuses it as not standing on the ground: without VO it refused
//! most detections.
//!
//! But every object a dashcam's detector reports — cars, people, cones, drums — stands on
//! the road. Turned into the body frame by the mount with the pitch left out, a detection's
//! bottom is at height `u.z + h_camera − h/2` at distance `u.x` ahead of the camera; the
//! pitch that brings it to the ground is, to first order, that height over that distance.
//! The estimate is the median of those pitches over every detection at least
//! [`MIN_RANGE_M`] ahead (near ones are dominated by the box's height error), kept as a
//! histogram of [`BIN_RAD`] bins within [`HALF_RANGE_RAD`] of the nominal pitch: a fixed
//! 200 bytes, and a wrong box or a kerb does not move a median.

use super::mount::CameraMount;
use crate::track3d::Detection3d;

/// Width of a bin, rad (0.1°).
pub const BIN_RAD: f64 = 0.1 * core::f64::consts::PI / 180.0;
/// Bins either side of the nominal pitch.
const HALF_BINS: usize = 50;
/// Pitches further than this from the nominal one are not counted, rad (5°).
pub const HALF_RANGE_RAD: f64 = HALF_BINS as f64 * BIN_RAD;
/// Detections nearer than this (m ahead of the camera) are not counted: a box's height
/// error over a short distance is a large angle.
pub const MIN_RANGE_M: f64 = 10.0;
/// Detections before the median is used.
pub const MIN_SAMPLES: u32 = 50;
/// Consecutive detections counted as one independent one (the same objects seen frame
/// after frame) for the estimate's σ.
const CORRELATED: f64 = 20.0;

/// The histogram of ground-contact pitches.
#[derive(Clone, Debug, PartialEq)]
pub struct GroundPitch {
    nominal: f64,
    bins: [u16; 2 * HALF_BINS],
    count: u32,
}

impl GroundPitch {
    /// An empty histogram around the nominal mount's pitch (rad).
    pub const fn new(nominal_pitch: f64) -> Self {
        GroundPitch { nominal: nominal_pitch, bins: [0; 2 * HALF_BINS], count: 0 }
    }

    /// One detection (camera frame) seen through `mount` (its position and roll; its pitch
    /// is what is measured). Returns whether it was counted.
    pub fn push(&mut self, mount: &CameraMount, d: &Detection3d) -> bool {
        let b = &d.bbox;
        let (s, c) = libm::sincos(mount.roll_pitch_yaw[0]);
        // The detection's centre with the mount's roll only (camera → body before pitch).
        let (ux, uz) = (b.x, s * b.y + c * b.z);
        if !(ux.is_finite() && uz.is_finite() && b.h.is_finite() && ux >= MIN_RANGE_M) {
            return false;
        }
        let pitch = (uz + mount.position[2] - 0.5 * b.h) / ux;
        let offset = (pitch - self.nominal) / BIN_RAD + HALF_BINS as f64;
        if !(0.0..(2 * HALF_BINS) as f64).contains(&offset) {
            return false;
        }
        let Some(bin) = self.bins.get_mut(offset as usize) else { return false };
        if *bin == u16::MAX {
            // Full: halve every bin, which keeps the median where it is.
            self.bins.iter_mut().for_each(|b| *b /= 2);
            self.count = self.bins.iter().map(|&b| u32::from(b)).sum();
        }
        if let Some(bin) = self.bins.get_mut(offset as usize) {
            *bin += 1;
            self.count += 1;
        }
        true
    }

    /// The value below which `fraction` of the counted pitches lie (rad), interpolated
    /// within its bin.
    fn quantile(&self, fraction: f64) -> f64 {
        let target = fraction * f64::from(self.count);
        let mut below = 0.0;
        for (k, &n) in self.bins.iter().enumerate() {
            let n = f64::from(n);
            if n > 0.0 && below + n >= target {
                let within = ((target - below) / n).clamp(0.0, 1.0);
                return self.nominal + ((k as f64 + within) - HALF_BINS as f64) * BIN_RAD;
            }
            below += n;
        }
        self.nominal + HALF_RANGE_RAD
    }

    /// The median pitch and its σ (rad: the spread's, over the independent detections),
    /// once [`MIN_SAMPLES`] are counted.
    pub fn estimate(&self) -> Option<(f64, f64)> {
        if self.count < MIN_SAMPLES {
            return None;
        }
        // The interquartile range over 1.349 is a normal spread's σ; a median's σ is 1.25
        // times the mean's.
        let spread = (self.quantile(0.75) - self.quantile(0.25)) / 1.349;
        let independent = (f64::from(self.count) / CORRELATED).max(1.0);
        Some((self.quantile(0.5), 1.2533 * spread.max(BIN_RAD) / libm::sqrt(independent)))
    }

    /// Detections counted.
    pub fn count(&self) -> u32 {
        self.count
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::box3d::Box3d;

    /// A drum (0.9 m high) on the road `range` m ahead of a camera 1.3 m up pitched down by
    /// `pitch`, as the camera (x forward, y left, z up) reports it.
    fn drum(range: f64, pitch: f64, noise: f64) -> Detection3d {
        // Body: centre at (range, 0, 0.45) from below the camera; into the camera frame.
        let (x, z) = (range, 0.45 - 1.3 + noise);
        let (s, c) = libm::sincos(pitch);
        let bbox = Box3d { x: c * x - s * z, y: 0.0, z: s * x + c * z, yaw: 0.0, l: 0.6, w: 0.6, h: 0.9 };
        Detection3d::new(0, bbox, 0.9)
    }

    fn mount(roll: f64) -> CameraMount {
        CameraMount { position: [1.8, 0.0, 1.3], roll_pitch_yaw: [roll, 0.0, 0.0] }
    }

    #[test]
    fn the_pitch_that_stands_the_objects_on_the_road_is_found() {
        let truth = 2.0f64.to_radians();
        let mut ground = GroundPitch::new(0.0);
        assert_eq!(ground.estimate(), None);
        for k in 0..400 {
            // Ranges 10–50 m, heights off by up to ±0.3 m, and one box in ten a metre high.
            let range = 10.0 + (k % 41) as f64;
            let noise = if k % 10 == 0 { 1.0 } else { 0.3 * libm::sin(k as f64 * 1.7) };
            ground.push(&mount(0.0), &drum(range, truth, noise));
        }
        // A metre-high box near by is more than 5° off: not counted.
        assert!(ground.count() > 360 && ground.count() < 400, "{}", ground.count());
        let (pitch, sigma) = ground.estimate().expect("enough detections");
        assert!((pitch - truth).abs() < 0.15f64.to_radians(), "{} vs 2°", pitch.to_degrees());
        assert!(sigma > 0.0 && sigma < 0.2f64.to_radians(), "σ {}°", sigma.to_degrees());
    }

    #[test]
    fn near_far_off_and_broken_detections_are_not_counted() {
        let mut ground = GroundPitch::new(0.0);
        assert!(!ground.push(&mount(0.0), &drum(5.0, 0.0, 0.0)));
        assert!(!ground.push(&mount(0.0), &drum(30.0, 8f64.to_radians(), 0.0)));
        let mut broken = drum(30.0, 0.0, 0.0);
        broken.bbox.z = f64::NAN;
        assert!(!ground.push(&mount(0.0), &broken));
        assert_eq!(ground.count(), 0);
    }

    /// A camera reporting its own axes (x forward, y right, z down) has a roll of π.
    #[test]
    fn a_camera_on_its_own_axes_gives_the_same_pitch() {
        let mut ground = GroundPitch::new(0.0);
        for k in 0..60 {
            let mut d = drum(20.0 + k as f64 * 0.5, 1f64.to_radians(), 0.0);
            d.bbox.y = -d.bbox.y;
            d.bbox.z = -d.bbox.z;
            ground.push(&mount(core::f64::consts::PI), &d);
        }
        let (pitch, _) = ground.estimate().expect("enough detections");
        assert!((pitch - 1f64.to_radians()).abs() < 0.1f64.to_radians(), "{}", pitch.to_degrees());
    }

    #[test]
    fn a_full_histogram_keeps_its_median() {
        let mut ground = GroundPitch::new(0.0);
        for k in 0..200_000u32 {
            let pitch = if k % 4 == 0 { 1.5 } else { 0.5 };
            ground.push(&mount(0.0), &drum(30.0, f64::to_radians(pitch), 0.0));
        }
        let (pitch, _) = ground.estimate().expect("enough detections");
        assert!((pitch.to_degrees() - 0.5).abs() < 0.1, "{}", pitch.to_degrees());
        assert!(ground.count() < 200_000);
    }
}
