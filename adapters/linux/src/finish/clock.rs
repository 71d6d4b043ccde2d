//! The finished log's clock: its UTC moved onto the world's.
//!
//! A device reads UTC off each GNSS fix as it arrives, so its log's UTC is early by the
//! receiver's latency (`pipeline::clock`). The latency is measured two ways. The solve finds
//! it from where the fixes put the car (`solve`), where an along-track error of the fixes
//! looks like a latency at constant speed. The fixes' speed over ground says it more
//! directly: the finished ego's speed (from the camera's frames, on the device's clock)
//! speeds up and slows down with the car, and the fixes' speeds follow it one latency late
//! ([`latency_from_speed`]).

use std::collections::BTreeMap;

use dash2sim_core::binlog::{quantise, EgoPose, Record};

/// Latencies tried, s: from a receiver whose clock runs ahead to one half a second late.
const LATENCY_RANGE_S: (f64, f64) = (-0.2, 0.6);
/// Their step, s.
const LATENCY_STEP_S: f64 = 0.001;
/// The ego's speed is the chord over ±this, s (its positions are 50 ms apart).
const SPEED_HALF_SPAN_S: f64 = 0.1;
/// Fixes with a speed needed.
const MIN_FIXES: usize = 20;
/// A speed residual counts at most this much, m/s (a multipath jump, a skid).
const RESIDUAL_CLIP_MPS: f64 = 1.0;
/// The speed's latency is used only when it is this well determined (1-σ, s): at steady
/// speed it says nothing, and the solve's stands.
pub const MAX_SIGMA_S: f64 = 0.02;

/// The receiver's latency (s) from its fixes' speed over ground against the finished ego's
/// speed (`ego`, log time), or `None` with too few fixes or too little change of speed to
/// tell it to [`MAX_SIGMA_S`]. `records` are the device's (fix times are arrivals).
pub fn latency_from_speed(records: &[Record], ego: &BTreeMap<i64, EgoPose>) -> Option<f64> {
    let track: Vec<(f64, f64, f64)> =
        ego.values().map(|p| (p.t_us as f64 * 1e-6, p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3)).collect();
    let at = |t: f64| -> Option<(f64, f64)> {
        let k = track.partition_point(|p| p.0 <= t);
        let (a, b) = (track.get(k.checked_sub(1)?)?, track.get(k)?);
        if b.0 - a.0 > 1.0 {
            return None;
        }
        let w = (t - a.0) / (b.0 - a.0);
        Some((a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2)))
    };
    let speed = |t: f64| -> Option<f64> {
        let (a, b) = (at(t - SPEED_HALF_SPAN_S)?, at(t + SPEED_HALF_SPAN_S)?);
        Some((b.0 - a.0).hypot(b.1 - a.1) / (2.0 * SPEED_HALF_SPAN_S))
    };
    let fixes: Vec<(f64, f64)> = records
        .iter()
        .filter_map(|r| match r {
            Record::GnssFix(f) if f.mode >= 2 => Some((f.t_us as f64 * 1e-6, f.speed_mm_s as f64 * 1e-3)),
            _ => None,
        })
        .collect();
    let cost = |tau: f64| -> (f64, usize) {
        fixes
            .iter()
            .filter_map(|(t, sog)| Some((sog - speed(t - tau)?).clamp(-RESIDUAL_CLIP_MPS, RESIDUAL_CLIP_MPS)))
            .fold((0.0, 0), |(sum, n), r| (sum + r * r, n + 1))
    };
    let steps = ((LATENCY_RANGE_S.1 - LATENCY_RANGE_S.0) / LATENCY_STEP_S).round() as usize;
    let (best, (sum, n)) = (0..=steps)
        .map(|k| LATENCY_RANGE_S.0 + k as f64 * LATENCY_STEP_S)
        .map(|tau| (tau, cost(tau)))
        .filter(|(_, (_, n))| *n >= MIN_FIXES)
        .min_by(|a, b| (a.1 .0 / a.1 .1 as f64).total_cmp(&(b.1 .0 / b.1 .1 as f64)))?;
    // σ of the latency: the residuals' variance over the information the speed's changes
    // carry (Σ acceleration² at the fixes).
    let information: f64 = fixes
        .iter()
        .filter_map(|(t, _)| {
            let t = t - best;
            let a = (speed(t + SPEED_HALF_SPAN_S)? - speed(t - SPEED_HALF_SPAN_S)?) / (2.0 * SPEED_HALF_SPAN_S);
            Some(a * a)
        })
        .sum();
    let variance = sum / (n.saturating_sub(1).max(1)) as f64;
    let sigma = (variance / information).sqrt();
    (sigma.is_finite() && sigma <= MAX_SIGMA_S).then_some(best)
}

/// A device reads UTC off each fix as it arrives (`pipeline::clock`): its log's UTC is
/// early by the receiver's latency, and everything in it — the ego, the tracks, the fixes'
/// arrivals — is stamped that much before the instant it describes. Every record and clock
/// offset is moved later by the latency (`latency_s`, [`latency_from_speed`] or the solve's), so that the
/// finished log's UTC is the world's. A log that never learnt UTC (no clock offset) is on
/// the device's clock and is left there. Returns the shift, µs.
pub fn utc_onto_the_fixes(records: &mut [Record], latency_s: f64) -> i64 {
    if !records.iter().any(|r| matches!(r, Record::ClockOffset(_))) || !latency_s.is_finite() {
        return 0;
    }
    let shift = quantise(latency_s, 1e-6);
    for r in records.iter_mut() {
        r.set_t_us(r.t_us().saturating_add(shift));
        if let Record::ClockOffset(c) = r {
            c.offset_us = c.offset_us.saturating_add(shift);
        }
    }
    shift
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::binlog::GnssFix;

    /// A car whose speed swings between 10 and 20 m/s every 8 s, its ego every 50 ms, and a
    /// receiver 137 ms late whose speeds are off by up to 0.1 m/s.
    fn swinging(latency: f64, swing: f64) -> (Vec<Record>, BTreeMap<i64, EgoPose>) {
        let distance =
            |t: f64| 15.0 * t - swing * 8.0 / std::f64::consts::TAU * (std::f64::consts::TAU * t / 8.0).cos();
        let speed = |t: f64| 15.0 + swing * (std::f64::consts::TAU * t / 8.0).sin();
        let ego = (0..=800)
            .map(|k| {
                let t = 0.05 * k as f64;
                let t_us = quantise(t, 1e-6);
                (t_us, EgoPose { t_us, x_mm: quantise(distance(t), 1e-3), ..EgoPose::default() })
            })
            .collect();
        let records = (1..390)
            .map(|k| {
                let valid = 0.1 * k as f64;
                let noise = 0.1 * (k as f64 * 12.9898).sin();
                let t_us = quantise(valid + latency, 1e-6);
                let speed_mm_s = quantise(speed(valid) + noise, 1e-3);
                Record::GnssFix(GnssFix { t_us, speed_mm_s, mode: 3, ..GnssFix::default() })
            })
            .collect();
        (records, ego)
    }

    #[test]
    fn the_fixes_speeds_follow_the_car_one_latency_late() {
        let (records, ego) = swinging(0.137, 5.0);
        let found = latency_from_speed(&records, &ego).expect("the speed swings");
        assert!((found - 0.137).abs() < 0.005, "{found}");
        // At steady speed the speeds say nothing.
        let (records, ego) = swinging(0.137, 0.0);
        assert_eq!(latency_from_speed(&records, &ego), None);
    }

    #[test]
    fn the_log_s_utc_moves_later_by_the_receiver_s_latency() {
        use dash2sim_core::binlog::{ClockOffset, VehicleSpeed};
        let speed = |t_us| Record::VehicleSpeed(VehicleSpeed { t_us, ..VehicleSpeed::default() });
        let mut records = vec![
            Record::ClockOffset(ClockOffset { t_us: 1_000_000, offset_us: 900_000, reason: 0 }),
            speed(1_000_000),
            Record::ClockOffset(ClockOffset { t_us: 2_000_000, offset_us: 900_400, reason: 1 }),
            speed(2_500_000),
        ];
        assert_eq!(utc_onto_the_fixes(&mut records, 0.1234567), 123_457);
        let times: Vec<i64> = records.iter().map(Record::t_us).collect();
        assert_eq!(times, [1_123_457, 1_123_457, 2_123_457, 2_623_457]);
        // The device's clock is where it was: UTC − offset is unchanged.
        for r in &records {
            if let Record::ClockOffset(c) = r {
                assert!(c.t_us - c.offset_us == 100_000 || c.t_us - c.offset_us == 1_099_600, "{c:?}");
            }
        }
        // A log on the device's clock has no UTC to correct.
        let mut device_clock = vec![speed(5)];
        assert_eq!(utc_onto_the_fixes(&mut device_clock, 0.1), 0);
        assert_eq!(device_clock[0].t_us(), 5);
    }
}
