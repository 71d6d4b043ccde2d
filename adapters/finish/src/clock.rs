//! The finished log's clock: its UTC moved onto the world's.
//!
//! A device reads UTC off each GNSS fix as it arrives, so its log's UTC is early by the
//! receiver's latency (`pipeline::clock`) until its anchorer has estimated the latency and
//! slewed it in. Finishing measures the latency over the whole drive, on one time base: the
//! device's slew is taken out first ([`DeviceSlew`]), so that every record
//! is on the fixes' arrivals as the device first stamped them. The latency is then measured
//! two ways. The solve finds
//! it from where the fixes put the car (`solve`), where an along-track error of the fixes
//! looks like a latency at constant speed. The fixes' motion says it more directly: the
//! finished ego (from the camera's frames, on the device's clock) speeds up, slows down and
//! turns with the car, and the fixes' speed and course over ground follow it one latency
//! late ([`latency_from_motion`]). Each of the two says it to its own precision — the speed
//! where the car changes speed, the course where it turns — and the two are weighed by it.

use std::collections::BTreeMap;
use std::f64::consts::FRAC_PI_2;

use dash2sim_core::binlog::{quantise, EgoPose, GnssFix, Record};
use dash2sim_core::track3d::wrap_angle;
use dash2sim_linux::log::{LogContents, RecordStore};

use crate::anchors::{AnchorFile, AnchorForm};
use crate::timeline::index_after;
use crate::Source;

/// Latencies tried, s: from a receiver whose clock runs ahead to one half a second late.
const LATENCY_RANGE_S: (f64, f64) = (-0.2, 0.6);
/// Their step, s: first coarse over the whole range, then fine around the coarse best
/// (the cost is smooth over the coarse step: the chords span half a second).
const LATENCY_STEPS_S: (f64, f64) = (0.01, 0.001);
/// The ego's speed and direction are the chord over ±this, s: a few VO frames, so that
/// their frame-to-frame noise averages out (±0.1 s: the clock 11.7 ms off in the median
/// drive of seeds 14528–14627, against 10.9 ms), and symmetric, so that it moves nothing in
/// time.
const CHORD_HALF_SPAN_S: f64 = 0.25;
/// Fixes with a speed (or a course) needed.
const MIN_FIXES: usize = 20;
/// The rate a fix's observation changes at (the information it carries on the latency) is
/// taken over ±this, s: over the chord's own span, its noise would be counted as
/// information.
const RATE_HALF_SPAN_S: f64 = 0.5;
/// A speed residual counts at most this much, m/s (a multipath jump, a skid).
const SPEED_CLIP_MPS: f64 = 1.0;
/// A course residual counts at most this much, rad (a multipath jump).
const COURSE_CLIP_RAD: f64 = 0.1;
/// A fix's course is used from this speed on, m/s: slower, a receiver's course is noise.
const MIN_COURSE_SPEED_MPS: f64 = 3.0;
/// The latency is used only when it is this well determined (1-σ, s): at steady speed on
/// a straight road the motion says nothing, and the solve's stands.
pub const MAX_SIGMA_S: f64 = 0.02;

/// The finished ego as a track on the log's clock (s, m), with its chord's speed and
/// direction.
struct Track(Vec<(f64, f64, f64)>);

impl Track {
    fn at(&self, t: f64) -> Option<(f64, f64)> {
        self.between(index_after(&self.0, t, |p| p.0), t)
    }

    /// [`Track::at`] from where the last lookup of `cursor` ended: the latency search asks
    /// for every fix at times a few milliseconds apart, each a few samples from the last.
    fn at_from(&self, t: f64, cursor: &mut usize) -> Option<(f64, f64)> {
        let s = &self.0;
        let mut k = (*cursor).min(s.len());
        while k > 0 && s[k - 1].0 > t {
            k -= 1;
        }
        while k < s.len() && s[k].0 <= t {
            k += 1;
        }
        *cursor = k;
        self.between(k, t)
    }

    /// The position at `t` between the samples before and at `k`.
    fn between(&self, k: usize, t: f64) -> Option<(f64, f64)> {
        let (a, b) = (self.0.get(k.checked_sub(1)?)?, self.0.get(k)?);
        if b.0 - a.0 > 1.0 {
            return None;
        }
        let w = (t - a.0) / (b.0 - a.0);
        Some((a.1 + w * (b.1 - a.1), a.2 + w * (b.2 - a.2)))
    }

    /// The chord over ±[`CHORD_HALF_SPAN_S`] around `t`.
    fn chord(&self, t: f64) -> Option<(f64, f64)> {
        let (a, b) = (self.at(t - CHORD_HALF_SPAN_S)?, self.at(t + CHORD_HALF_SPAN_S)?);
        Some((b.0 - a.0, b.1 - a.1))
    }
}

/// The speed a chord says, m/s. √ rather than `hypot`: no chord of a car's 0.2 s overflows,
/// and glibc's `hypot` was a tenth of finishing an hour's drive.
fn speed_of((dx, dy): (f64, f64)) -> f64 {
    (dx * dx + dy * dy).sqrt() / (2.0 * CHORD_HALF_SPAN_S)
}

/// The direction of travel a chord says, rad counter-clockwise from east.
fn heading_of((dx, dy): (f64, f64)) -> f64 {
    dy.atan2(dx)
}

/// What a channel's observations may differ from the ego's by, besides the latency: a
/// nuisance fitted at every latency tried, so that it is not read as one.
#[derive(Clone, Copy)]
enum Nuisance {
    /// A constant offset: a finished ego turned by a fraction of a degree.
    Offset,
    /// A gain: a finished ego whose scale is off by a fraction of a percent, or wheels that
    /// read fast. Where the car ends the drive faster or slower than it began, a speed off
    /// by 0.1 % looks like a latency of up to 10 ms. (A gain drifting linearly over the drive
    /// took more of the latency's information than it gave: the clock 13.2 ms off in the
    /// median drive of seeds 14528–14627 against 10.9 ms.)
    Gain,
}

/// The sums of a least-squares fit of `y` on one regressor `a`.
#[derive(Clone, Copy, Default)]
struct Fit {
    count: usize,
    aa: f64,
    ay: f64,
}

impl Fit {
    fn add(&mut self, a: f64, y: f64) {
        self.count += 1;
        self.aa += a * a;
        self.ay += a * y;
    }

    /// The coefficient of `a` (0 with no fix).
    fn coefficient(&self) -> f64 {
        if self.aa > 0.0 {
            self.ay / self.aa
        } else {
            0.0
        }
    }

    /// How much of Σy² the regressor explains.
    fn explained(&self) -> f64 {
        self.coefficient() * self.ay
    }
}

/// One kind of observation the fixes make of the car's motion.
struct Channel<'a> {
    /// (arrival, observed) per fix.
    fixes: Vec<(f64, f64)>,
    /// The finished ego.
    track: &'a Track,
    /// What the ego's chord says was observed.
    observe: fn((f64, f64)) -> f64,
    /// Observed − predicted.
    residual: fn(f64, f64) -> f64,
    /// A residual counts at most this much (a multipath jump, a skid), and a fix whose
    /// residual is past it carries no information on the latency.
    clip: f64,
    /// Fitted along with the latency.
    nuisance: Nuisance,
}

impl Channel<'_> {
    /// What the ego says was observed at a time on the log's clock.
    fn predict(&self, t: f64) -> Option<f64> {
        self.track.chord(t).map(self.observe)
    }

    /// The nuisance's regressor for a fix whose prediction is `predicted`.
    fn regressor(&self, predicted: f64) -> f64 {
        match self.nuisance {
            Nuisance::Offset => 1.0,
            Nuisance::Gain => predicted,
        }
    }

    /// Adds a fix to the nuisance's fit: the residual on a constant, or what was seen on
    /// the prediction.
    fn add(&self, fit: &mut Fit, seen: f64, predicted: f64) {
        match self.nuisance {
            Nuisance::Offset => fit.add(1.0, (self.residual)(seen, predicted)),
            Nuisance::Gain => fit.add(predicted, seen),
        }
    }

    /// The residual once the nuisance is taken out: less the mean, or against the
    /// prediction times the gain (as it is where nothing was fitted).
    fn adjusted(&self, fit: &Fit, seen: f64, predicted: f64) -> f64 {
        match self.nuisance {
            Nuisance::Offset => (self.residual)(seen, predicted) - fit.coefficient(),
            Nuisance::Gain if fit.aa > 0.0 => (self.residual)(seen, predicted * fit.coefficient()),
            Nuisance::Gain => (self.residual)(seen, predicted),
        }
    }

    /// Calls `visit(k, seen, predicted)` for every fix at latency `taus[k]`, the fixes in
    /// order for each latency (so that sums over them are what a pass per latency gives).
    fn each_predicted(&self, taus: &[f64], mut visit: impl FnMut(usize, f64, f64)) {
        let Some(&first) = taus.first() else { return };
        let points = &self.track.0;
        for (t, seen) in &self.fixes {
            let mut before = index_after(points, t - first - CHORD_HALF_SPAN_S, |p| p.0);
            let mut after = index_after(points, t - first + CHORD_HALF_SPAN_S, |p| p.0);
            for (k, tau) in taus.iter().enumerate() {
                let at = t - tau;
                let (Some(a), Some(b)) = (
                    self.track.at_from(at - CHORD_HALF_SPAN_S, &mut before),
                    self.track.at_from(at + CHORD_HALF_SPAN_S, &mut after),
                ) else {
                    continue;
                };
                visit(k, *seen, (self.observe)((b.0 - a.0, b.1 - a.1)));
            }
        }
    }

    /// The nuisance's fit at every latency of `taus`, over the fixes within the clip.
    fn fits(&self, taus: &[f64]) -> Vec<Fit> {
        let mut fits = vec![Fit::default(); taus.len()];
        self.each_predicted(taus, |k, seen, predicted| {
            if (self.residual)(seen, predicted).abs() < self.clip {
                self.add(&mut fits[k], seen, predicted);
            }
        });
        fits
    }

    /// The mean squared clipped residual, the nuisance taken out, at every latency of
    /// `taus`; `None` where fewer than [`MIN_FIXES`] fixes have a prediction.
    fn costs(&self, taus: &[f64]) -> Vec<Option<f64>> {
        let fits = self.fits(taus);
        let mut squares = vec![0.0; taus.len()];
        let mut count = vec![0usize; taus.len()];
        self.each_predicted(taus, |k, seen, predicted| {
            squares[k] += self.adjusted(&fits[k], seen, predicted).clamp(-self.clip, self.clip).powi(2);
            count[k] += 1;
        });
        squares.iter().zip(&count).map(|(sum, &n)| (n >= MIN_FIXES).then(|| sum / n as f64)).collect()
    }

    /// How fast the prediction changes at `t`, per s (the information a fix carries on the
    /// latency).
    fn rate(&self, t: f64) -> Option<f64> {
        let change = self.predict(t + RATE_HALF_SPAN_S)? - self.predict(t - RATE_HALF_SPAN_S)?;
        Some((self.residual)(change, 0.0) / (2.0 * RATE_HALF_SPAN_S))
    }

    /// The latency of least cost within `range` tried every `step` (s), and its cost.
    fn best_of(&self, range: (f64, f64), step: f64) -> Option<(f64, f64)> {
        let steps = ((range.1 - range.0) / step).round() as usize;
        let taus: Vec<f64> = (0..=steps).map(|k| range.0 + k as f64 * step).collect();
        taus.iter()
            .zip(self.costs(&taus))
            .filter_map(|(&tau, cost)| Some((tau, cost?)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// The latency this channel finds and its 1-σ, s: the residuals' variance over the
    /// information the changes of the motion carry (Σ rate² at the fixes, less what the
    /// nuisance's regressor explains of it).
    fn latency(&self) -> Option<(f64, f64)> {
        let (coarse, fine) = LATENCY_STEPS_S;
        let (coarse_best, _) = self.best_of(LATENCY_RANGE_S, coarse)?;
        let (best, variance) = self.best_of((coarse_best - coarse, coarse_best + coarse), fine)?;
        let fit = self.fits(&[best])[0];
        // The rates at the fixes within the clip, fitted on the nuisance's regressor.
        let (mut rates, mut total) = (Fit::default(), 0.0);
        for (t, seen) in &self.fixes {
            let Some(predicted) = self.predict(t - best) else { continue };
            if self.adjusted(&fit, *seen, predicted).abs() >= self.clip {
                continue;
            }
            let Some(rate) = self.rate(t - best) else { continue };
            rates.add(self.regressor(predicted), rate);
            total += rate * rate;
        }
        if rates.count < MIN_FIXES {
            return None;
        }
        let n = rates.count as f64;
        let information = total - rates.explained();
        let sigma = (variance * n / (n - 1.0).max(1.0) / information).sqrt();
        sigma.is_finite().then_some((best, sigma))
    }
}

/// The receiver's latency (s) from its fixes' speed and course over ground against the
/// finished ego's (`ego`, log time), or `None` with too few fixes or too little change of
/// speed or direction to tell it to [`MAX_SIGMA_S`]. `fixes` are the device's (their times
/// are arrivals); those without a position are passed over.
pub fn latency_from_motion(fixes: &[GnssFix], ego: &BTreeMap<i64, EgoPose>) -> Option<f64> {
    let track =
        Track(ego.values().map(|p| (p.t_us as f64 * 1e-6, p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3)).collect());
    let fixes = || fixes.iter().filter(|f| f.mode >= 2);
    let speed = Channel {
        fixes: fixes().map(|f| (f.t_us as f64 * 1e-6, f.speed_mm_s as f64 * 1e-3)).collect(),
        track: &track,
        observe: speed_of,
        residual: |seen, predicted| seen - predicted,
        clip: SPEED_CLIP_MPS,
        nuisance: Nuisance::Gain,
    };
    // A fix's course is clockwise from north; the ego's heading counter-clockwise from east.
    let course = Channel {
        fixes: fixes()
            .filter(|f| f.speed_mm_s as f64 * 1e-3 >= MIN_COURSE_SPEED_MPS)
            .map(|f| (f.t_us as f64 * 1e-6, FRAC_PI_2 - f.track_e4 as f64 * 1e-4))
            .collect(),
        track: &track,
        observe: heading_of,
        residual: |seen, predicted| wrap_angle(seen - predicted),
        clip: COURSE_CLIP_RAD,
        nuisance: Nuisance::Offset,
    };
    // Each channel weighed by its precision.
    let (weighted, weight) = [speed.latency(), course.latency()]
        .into_iter()
        .flatten()
        .fold((0.0, 0.0), |(sum, w), (tau, sigma)| (sum + tau / (sigma * sigma), w + 1.0 / (sigma * sigma)));
    let sigma = weight.recip().sqrt();
    (weight > 0.0 && sigma <= MAX_SIGMA_S).then(|| weighted / weight)
}

/// At most this many wheel speeds are compared (every n-th of a long drive's): an hour's
/// 50 Hz bus says the wheels' latency to a fraction of a millisecond long before that.
const MAX_WHEEL_SAMPLES: usize = 20_000;

/// The wheels' latency (s): how much later than the car's motion the vehicle bus reports
/// its speed, from the wheel speeds (`speeds`, (arrival on the log's clock, m/s)) against
/// an ego track (`track`, (s, east m, north m), the VO's positions smoothed without the
/// wheels), and its 1-σ; `None` with too little change of speed to tell it to
/// [`MAX_SIGMA_S`]. The wheels read the speed times a factor of their own (tyre wear,
/// pressure), fitted at every latency tried.
pub fn wheel_latency(speeds: &[(f64, f64)], track: Vec<(f64, f64, f64)>) -> Option<(f64, f64)> {
    let track = Track(track);
    let every = speeds.len().div_ceil(MAX_WHEEL_SAMPLES).max(1);
    let wheels = Channel {
        fixes: speeds.iter().step_by(every).copied().filter(|(t, v)| t.is_finite() && v.is_finite()).collect(),
        track: &track,
        observe: speed_of,
        residual: |seen, predicted| seen - predicted,
        clip: SPEED_CLIP_MPS,
        nuisance: Nuisance::Gain,
    };
    wheels.latency().filter(|(_, sigma)| *sigma <= MAX_SIGMA_S)
}

/// The receiver latency a device slewed into its log's clock (`pipeline::clock`): the
/// `ClockOffset` records of reason 4, each a step of the latency (its offset less the one in
/// force before it). Taken out of the log and of its anchors, everything is on one time
/// base, the fixes' arrivals, as the device first stamped them.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceSlew {
    /// From this log time on (µs), this latency was in the log's clock (µs).
    steps: Vec<(i64, i64)>,
}

impl DeviceSlew {
    /// The slew of `log`'s device; `None` when it slewed nothing.
    pub fn of(log: &Source) -> Option<DeviceSlew> {
        let (mut latency, mut offset, mut steps) = (0i64, None, vec![]);
        for r in log.records.iter() {
            let Record::ClockOffset(c) = r else { continue };
            if c.reason == SLEW_REASON {
                latency = latency.saturating_add(c.offset_us.saturating_sub(offset.unwrap_or(c.offset_us)));
                steps.push((c.t_us, latency));
            }
            offset = Some(c.offset_us);
        }
        (!steps.is_empty()).then_some(DeviceSlew { steps })
    }

    /// The latency in the log's clock at log time `t_us`, µs.
    pub fn latency_at(&self, t_us: i64) -> i64 {
        let k = self.steps.partition_point(|s| s.0 <= t_us);
        k.checked_sub(1).and_then(|k| self.steps.get(k)).map_or(0, |s| s.1)
    }

    /// `log` with the slew taken out, record by record in the order the device wrote them;
    /// a fix keeps its stamp (the receiver's UTC), the slew's records are left out.
    pub fn taken_out_of(&self, log: &Source) -> Source {
        let (mut latency, mut offset) = (0i64, None);
        let records = log
            .records
            .iter()
            .filter_map(|mut r| {
                match &mut r {
                    Record::ClockOffset(c) if c.reason == SLEW_REASON => {
                        latency = latency.saturating_add(c.offset_us.saturating_sub(offset.unwrap_or(c.offset_us)));
                        offset = Some(c.offset_us);
                        return None;
                    }
                    Record::ClockOffset(c) => {
                        offset = Some(c.offset_us);
                        c.offset_us = c.offset_us.saturating_sub(latency);
                    }
                    Record::GnssFix(_) => return Some(r),
                    _ => {}
                }
                r.set_t_us(r.t_us().saturating_sub(latency));
                Some(r)
            })
            .collect();
        LogContents {
            header: log.header,
            records,
            damage: log.damage.clone(),
            stats: log.stats,
            bytes: log.bytes,
            signing: log.signing.clone(),
        }
    }

    /// `file`'s anchors at a log time moved onto the log with the slew taken out.
    pub fn taken_out_of_anchors(&self, file: &AnchorFile) -> AnchorFile {
        let mut moved = file.clone();
        for a in &mut moved.anchors {
            if let AnchorForm::Time(t) = &mut a.at {
                *t -= self.latency_at(quantise(*t, 1e-6)) as f64 * 1e-6;
            }
        }
        moved
    }
}

/// A `ClockOffset` record's reason when the device slewed the receiver's latency in.
const SLEW_REASON: i64 = 4;

/// A device reads UTC off each fix as it arrives (`pipeline::clock`): its log's UTC, the
/// device's slew taken out, is early by the receiver's latency, and everything in it — the
/// ego, the tracks, the fixes' arrivals — is stamped that much before the instant it
/// describes. Every record and clock offset is moved later by the latency (`latency_s`,
/// [`latency_from_motion`] or the solve's), so that the finished log's UTC is the world's. A log that never learnt UTC (no clock offset) is on
/// the device's clock and is left there. Returns the shift, µs.
pub fn utc_onto_the_fixes(records: &mut RecordStore, latency_s: f64) -> i64 {
    if !records.iter().any(|r| matches!(r, Record::ClockOffset(_))) || !latency_s.is_finite() {
        return 0;
    }
    let shift = quantise(latency_s, 1e-6);
    *records = records.map(|r| {
        r.set_t_us(r.t_us().saturating_add(shift));
        if let Record::ClockOffset(c) = r {
            c.offset_us = c.offset_us.saturating_add(shift);
        }
    });
    shift
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// A car whose speed swings between 10 and 20 m/s every 8 s, its ego every 50 ms, and a
    /// receiver 137 ms late whose speeds are off by up to 0.1 m/s.
    fn swinging(latency: f64, swing: f64) -> (Vec<GnssFix>, BTreeMap<i64, EgoPose>) {
        let distance = |t: f64| 15.0 * t - swing * 8.0 / TAU * (TAU * t / 8.0).cos();
        let speed = |t: f64| 15.0 + swing * (TAU * t / 8.0).sin();
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
                GnssFix { t_us, speed_mm_s, mode: 3, ..GnssFix::default() }
            })
            .collect();
        (records, ego)
    }

    #[test]
    fn the_wheels_latency_is_found_whatever_their_factor() {
        // The bus every 20 ms, 60 ms late, reading 2 % fast with ±0.03 m/s of noise.
        let (_, ego) = swinging(0.137, 5.0);
        let track: Vec<(f64, f64, f64)> =
            ego.values().map(|p| (p.t_us as f64 * 1e-6, p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3)).collect();
        let speed = |t: f64| 15.0 + 5.0 * (TAU * t / 8.0).sin();
        let wheels: Vec<(f64, f64)> = (0..1950)
            .map(|k| {
                let t = 0.02 * k as f64;
                (t + 0.06, 1.02 * speed(t) + 0.03 * (k as f64 * 12.9898).sin())
            })
            .collect();
        let (found, sigma) = wheel_latency(&wheels, track).expect("the speed swings");
        assert!((found - 0.06).abs() < 0.003 && sigma < 0.003, "{found} ± {sigma}");
        // At a steady speed they say nothing.
        let steady: Vec<(f64, f64)> =
            wheels.iter().enumerate().map(|(k, &(t, _))| (t, 15.3 + 0.03 * (k as f64 * 12.9898).sin())).collect();
        let (_, ego) = swinging(0.137, 0.0);
        let track: Vec<(f64, f64, f64)> =
            ego.values().map(|p| (p.t_us as f64 * 1e-6, p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3)).collect();
        assert_eq!(wheel_latency(&steady, track), None);
    }

    #[test]
    fn the_fixes_speeds_follow_the_car_one_latency_late() {
        let (records, ego) = swinging(0.137, 5.0);
        let found = latency_from_motion(&records, &ego).expect("the speed swings");
        assert!((found - 0.137).abs() < 0.005, "{found}");
        // At steady speed the speeds say nothing.
        let (records, ego) = swinging(0.137, 0.0);
        assert_eq!(latency_from_motion(&records, &ego), None);
    }

    /// A car at a steady 15 m/s weaving left and right every 6 s (±0.3 rad), its ego every
    /// 50 ms, and a receiver `latency` late whose courses are off by up to half a degree.
    fn weaving(latency: f64) -> (Vec<GnssFix>, BTreeMap<i64, EgoPose>) {
        let heading = |t: f64| 0.3 * (TAU * t / 6.0).sin();
        let mut ego = BTreeMap::new();
        let (mut x, mut y) = (0.0, 0.0);
        for k in 0..=800 {
            let t = 0.05 * k as f64;
            let t_us = quantise(t, 1e-6);
            ego.insert(t_us, EgoPose { t_us, x_mm: quantise(x, 1e-3), y_mm: quantise(y, 1e-3), ..EgoPose::default() });
            let h = heading(t + 0.025);
            (x, y) = (x + 15.0 * 0.05 * h.cos(), y + 15.0 * 0.05 * h.sin());
        }
        let records = (1..390)
            .map(|k| {
                let valid = 0.1 * k as f64;
                let noise = 0.5f64.to_radians() * (k as f64 * 78.233).sin();
                let t_us = quantise(valid + latency, 1e-6);
                let track_e4 = quantise(FRAC_PI_2 - heading(valid) + noise, 1e-4);
                GnssFix { t_us, speed_mm_s: 15_000, track_e4, mode: 3, ..GnssFix::default() }
            })
            .collect();
        (records, ego)
    }

    #[test]
    fn at_steady_speed_the_fixes_course_follows_the_car_one_latency_late() {
        let (records, ego) = weaving(0.137);
        let found = latency_from_motion(&records, &ego).expect("the car turns");
        assert!((found - 0.137).abs() < 0.005, "{found}");
        // A receiver with no course (or a car on a straight road at steady speed) says nothing.
        let no_course: Vec<GnssFix> = records.iter().map(|f| GnssFix { track_e4: 0, ..*f }).collect();
        assert_eq!(latency_from_motion(&no_course, &ego), None);
    }

    #[test]
    fn the_log_s_utc_moves_later_by_the_receiver_s_latency() {
        use dash2sim_core::binlog::{ClockOffset, VehicleSpeed};
        let speed = |t_us| Record::VehicleSpeed(VehicleSpeed { t_us, ..VehicleSpeed::default() });
        let mut records: RecordStore = [
            Record::ClockOffset(ClockOffset { t_us: 1_000_000, offset_us: 900_000, reason: 0 }),
            speed(1_000_000),
            Record::ClockOffset(ClockOffset { t_us: 2_000_000, offset_us: 900_400, reason: 1 }),
            speed(2_500_000),
        ]
        .into_iter()
        .collect();
        assert_eq!(utc_onto_the_fixes(&mut records, 0.1234567), 123_457);
        let times: Vec<i64> = records.iter().map(|r| r.t_us()).collect();
        assert_eq!(times, [1_123_457, 1_123_457, 2_123_457, 2_623_457]);
        // The device's clock is where it was: UTC − offset is unchanged.
        for r in records.iter() {
            if let Record::ClockOffset(c) = r {
                assert!(c.t_us - c.offset_us == 100_000 || c.t_us - c.offset_us == 1_099_600, "{c:?}");
            }
        }
        // A log on the device's clock has no UTC to correct.
        let mut device_clock: RecordStore = [speed(5)].into_iter().collect();
        assert_eq!(utc_onto_the_fixes(&mut device_clock, 0.1), 0);
        assert_eq!(device_clock.get(0).map(|r| r.t_us()), Some(5));
    }

    #[test]
    fn the_devices_slew_is_taken_out_and_a_fix_keeps_its_stamp() {
        use dash2sim_core::binlog::{ClockOffset, VehicleSpeed};
        let speed = |t_us| Record::VehicleSpeed(VehicleSpeed { t_us, ..VehicleSpeed::default() });
        let offset = |t_us, offset_us, reason| Record::ClockOffset(ClockOffset { t_us, offset_us, reason });
        let fix = Record::GnssFix(GnssFix { t_us: 1_350_000, mode: 3, ..GnssFix::default() });
        let source = |records: Vec<Record>| LogContents {
            header: None,
            records: records.into_iter().collect(),
            damage: vec![],
            stats: Default::default(),
            bytes: 0,
            signing: vec![],
        };
        // The first offset, a millisecond of slew, a fix, a drift of 0.5 ms, a millisecond more.
        let slewed = source(vec![
            offset(1_000_000, 900, 0),
            speed(1_100_000),
            offset(1_200_000, 1_900, 4),
            speed(1_300_000),
            fix,
            offset(1_400_000, 2_400, 1),
            offset(1_500_000, 3_400, 4),
            speed(1_600_000),
        ]);
        let slew = DeviceSlew::of(&slewed).expect("slewed");
        assert_eq!(
            (slew.latency_at(1_199_999), slew.latency_at(1_200_000), slew.latency_at(1_600_000)),
            (0, 1_000, 2_000)
        );
        let unslewed = slew.taken_out_of(&slewed);
        let times: Vec<(i64, Option<i64>)> = unslewed
            .records
            .iter()
            .map(|r| (r.t_us(), if let Record::ClockOffset(c) = r { Some(c.offset_us) } else { None }))
            .collect();
        assert_eq!(
            times,
            [
                (1_000_000, Some(900)),
                (1_100_000, None),
                (1_299_000, None),
                (1_350_000, None),
                (1_399_000, Some(1_400)),
                (1_598_000, None)
            ]
        );
        // A log its device never slewed is read as it is.
        assert!(DeviceSlew::of(&source(vec![offset(1_000_000, 900, 0), speed(1_100_000)])).is_none());
        // An anchor at a log time moves with the records about it.
        let line = |t| crate::anchors::AnchorLine {
            line: 3,
            at: AnchorForm::Time(t),
            position: dash2sim_core::geo::Geodetic { lat_deg: 60.0, lon_deg: 25.0, height_m: 0.0 },
            sigma: 0.3,
        };
        let file = AnchorFile { anchors: vec![line(1.1), line(1.6)], refused: vec![] };
        let moved: Vec<AnchorForm> = slew.taken_out_of_anchors(&file).anchors.iter().map(|a| a.at).collect();
        assert_eq!(moved, [AnchorForm::Time(1.1), AnchorForm::Time(1.6 - 0.002)]);
    }
}
