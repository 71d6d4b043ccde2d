//! Merging the sentences of one fix into a [`GnssFix`], like gpsd's TPV report.
//!
//! A receiver reports one epoch as several sentences (GGA, GSA, GSV, RMC, VTG, …). The
//! assembler keeps the current state; a sentence carrying a different time of day starts
//! a new epoch and hands back the finished one. Position and velocity are per epoch;
//! date, mode, DOPs, satellites used and the geoid separation persist until replaced, as
//! they do in gpsd (which forgets the mode only when a time-only ZDA opens a cycle).

use super::messages::{Date, Message, TimeOfDay};
use crate::time::Timestamp;

/// Knots → m/s (exact by definition of the knot).
pub const KNOTS_TO_MPS: f64 = 1852.0 / 3600.0;

/// Fix dimension, as gpsd's `mode`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixMode {
    /// Nothing known yet.
    #[default]
    Unknown,
    /// No fix.
    NoFix,
    /// Horizontal fix.
    Fix2d,
    /// Horizontal and vertical fix.
    Fix3d,
}

impl FixMode {
    /// gpsd's number: 0 unknown, 1 no fix, 2, 3.
    pub fn gpsd(self) -> u8 {
        match self {
            FixMode::Unknown => 0,
            FixMode::NoFix => 1,
            FixMode::Fix2d => 2,
            FixMode::Fix3d => 3,
        }
    }
}

/// One epoch's fix: gpsd TPV fields where they exist.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct GnssFix {
    /// UTC date (from RMC or ZDA; persists).
    pub date: Option<Date>,
    /// UTC time of day of this epoch.
    pub time_of_day: Option<TimeOfDay>,
    /// Fix mode.
    pub mode: FixMode,
    /// GGA quality indicator.
    pub quality: Option<u8>,
    /// Latitude, degrees.
    pub lat: Option<f64>,
    /// Longitude, degrees.
    pub lon: Option<f64>,
    /// Altitude above mean sea level, m.
    pub alt_msl: Option<f64>,
    /// Geoid separation, m.
    pub geoid_sep: Option<f64>,
    /// Speed over ground, m/s.
    pub speed_mps: Option<f64>,
    /// Course over ground, degrees true.
    pub track_deg: Option<f64>,
    /// Magnetic variation, degrees (east positive).
    pub mag_var_deg: Option<f64>,
    /// True heading (HDT), degrees.
    pub heading_deg: Option<f64>,
    /// Satellites used.
    pub satellites_used: Option<u32>,
    /// Horizontal DOP.
    pub hdop: Option<f64>,
    /// Vertical DOP.
    pub vdop: Option<f64>,
    /// Position DOP.
    pub pdop: Option<f64>,
    /// 1-σ latitude error (GST), m.
    pub sigma_lat_m: Option<f64>,
    /// 1-σ longitude error (GST), m.
    pub sigma_lon_m: Option<f64>,
    /// 1-σ altitude error (GST), m.
    pub sigma_alt_m: Option<f64>,
}

/// Days since 1970-01-01 of a proleptic Gregorian date (Hinnant's `days_from_civil`).
pub fn days_since_unix_epoch(d: Date) -> i64 {
    let (y, m, day) = (i64::from(d.year), i64::from(d.month), i64::from(d.day));
    let y = if m <= 2 { y - 1 } else { y };
    let era = if y >= 0 { y } else { y - 399 } / 400;
    let yoe = y - era * 400;
    let mp = (m + 9) % 12;
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

impl GnssFix {
    /// UTC time as microseconds since the Unix epoch, when date and time are known.
    pub fn time(&self) -> Option<Timestamp> {
        let (date, tod) = (self.date?, self.time_of_day?);
        Some(Timestamp::from_micros(days_since_unix_epoch(date) * 86_400_000_000 + tod.0))
    }

    /// Height above the ellipsoid, m (MSL altitude plus geoid separation).
    pub fn alt_hae(&self) -> Option<f64> {
        Some(self.alt_msl? + self.geoid_sep?)
    }

    /// True when the fix has at least a horizontal position.
    pub fn has_position(&self) -> bool {
        self.mode >= FixMode::Fix2d && self.lat.is_some() && self.lon.is_some()
    }

    /// A fix with height (GGA, GNS): position, altitude and its dimension. As gpsd, a
    /// vertical fix needs an altitude and at least 4 satellites; a "fix" from no
    /// satellites is no fix.
    #[allow(clippy::too_many_arguments)]
    fn take_fix(
        &mut self,
        valid: bool,
        lat: Option<f64>,
        lon: Option<f64>,
        alt_msl: Option<f64>,
        geoid_sep: Option<f64>,
        satellites: Option<u32>,
        hdop: Option<f64>,
    ) {
        if valid && satellites != Some(0) {
            self.lat = lat.or(self.lat);
            self.lon = lon.or(self.lon);
            self.alt_msl = alt_msl.or(self.alt_msl);
            self.geoid_sep = geoid_sep.or(self.geoid_sep);
            let three_d = alt_msl.is_some() && satellites.is_none_or(|n| n >= 4);
            self.mode = if three_d { FixMode::Fix3d } else { FixMode::Fix2d };
        } else {
            self.mode = FixMode::NoFix;
        }
        self.satellites_used = satellites.or(self.satellites_used);
        self.hdop = hdop.or(self.hdop);
    }

    /// A horizontal-only position (RMC, GLL): at least a 2D fix when valid, else no fix.
    fn take_horizontal(&mut self, valid: bool, lat: Option<f64>, lon: Option<f64>) {
        if valid {
            self.lat = lat.or(self.lat);
            self.lon = lon.or(self.lon);
            if self.mode < FixMode::Fix2d {
                self.mode = FixMode::Fix2d;
            }
        } else {
            self.mode = FixMode::NoFix;
        }
    }

    fn clear_epoch(&mut self) {
        *self = GnssFix {
            date: self.date,
            mode: self.mode,
            satellites_used: self.satellites_used,
            hdop: self.hdop,
            vdop: self.vdop,
            pdop: self.pdop,
            mag_var_deg: self.mag_var_deg,
            geoid_sep: self.geoid_sep,
            ..GnssFix::default()
        };
    }
}

/// Merges messages into per-epoch fixes.
#[derive(Clone, Debug, Default)]
pub struct EpochAssembler {
    current: GnssFix,
    /// The last finished epoch; lent out by [`EpochAssembler::push`] instead of copied.
    finished: GnssFix,
    /// True once the current epoch holds anything.
    dirty: bool,
    /// The receiver reported a speed in this epoch (else it may be derived).
    speed_reported: bool,
    /// Time and position of the previous epoch, for deriving speed.
    previous: Option<(Timestamp, f64, f64)>,
}

impl EpochAssembler {
    /// An empty assembler.
    pub fn new() -> Self {
        Self::default()
    }

    /// The state of the epoch being assembled (what gpsd would report now).
    pub fn current(&self) -> &GnssFix {
        &self.current
    }

    /// Start a new epoch if `time` differs from the current one; true when that finished
    /// one (now in `self.finished`).
    fn at(&mut self, time: Option<TimeOfDay>) -> bool {
        let Some(time) = time else { return false };
        match self.current.time_of_day {
            Some(t) if t == time => false,
            previous => {
                let finished = self.dirty && previous.is_some();
                if finished {
                    self.finished = self.current;
                }
                if let (Some(t), Some(lat), Some(lon), true) =
                    (self.current.time(), self.current.lat, self.current.lon, self.current.has_position())
                {
                    self.previous = Some((t, lat, lon));
                }
                self.current.clear_epoch();
                self.current.time_of_day = Some(time);
                self.dirty = false;
                self.speed_reported = false;
                finished
            }
        }
    }

    /// When the receiver reports no speed, derive it (as gpsd does) from the distance to
    /// the previous epoch's position over the time between them.
    fn derive_speed(&mut self) {
        if self.speed_reported || !self.current.has_position() {
            return;
        }
        let (Some((t0, lat0, lon0)), Some(t), Some(lat), Some(lon)) =
            (self.previous, self.current.time(), self.current.lat, self.current.lon)
        else {
            return;
        };
        let dt = (t - t0).as_secs_f64();
        if dt > 0.0 {
            if let Some((distance, _)) = crate::geo::distance_and_bearing(lat0, lon0, lat, lon) {
                self.current.speed_mps = Some(distance / dt);
            }
        }
    }

    /// Merge one message; returns the previous epoch's fix when this one starts a new epoch.
    /// The fix is lent, not copied: at ~300 bytes, copying it out for every sentence cost
    /// more than the rest of the epoch logic.
    pub fn push(&mut self, message: &Message<'_>) -> Option<&GnssFix> {
        let finished = self.merge(message);
        if matches!(message, Message::Gga(_) | Message::Rmc(_) | Message::Gll(_) | Message::Gns(_) | Message::Vtg(_)) {
            self.derive_speed();
        }
        finished.then_some(&self.finished)
    }

    fn merge(&mut self, message: &Message<'_>) -> bool {
        let fix = &mut self.current;
        let finished = match message {
            Message::Gga(g) => {
                let done = self.at(g.time);
                self.current.quality = Some(g.quality);
                self.current.take_fix(g.quality != 0, g.lat, g.lon, g.alt_msl, g.geoid_sep, g.satellites, g.hdop);
                done
            }
            Message::Rmc(m) => {
                // A warning ('V') RMC does not vouch for its time either (gpsd keeps the
                // last valid time).
                let done = m.valid && self.at(m.time);
                let fix = &mut self.current;
                fix.date = m.date.or(fix.date);
                fix.take_horizontal(m.valid, m.lat, m.lon);
                if m.valid {
                    if let Some(k) = m.speed_knots {
                        fix.speed_mps = Some(k * KNOTS_TO_MPS);
                        self.speed_reported = true;
                    }
                    fix.track_deg = m.track_deg.or(fix.track_deg);
                    fix.mag_var_deg = m.mag_var_deg.or(fix.mag_var_deg);
                }
                done
            }
            Message::Gll(g) => {
                let done = self.at(g.time);
                self.current.take_horizontal(g.valid && g.mode != Some(b'N'), g.lat, g.lon);
                done
            }
            Message::Gns(g) => {
                let done = self.at(g.time);
                self.current.take_fix(g.any_fix, g.lat, g.lon, g.alt_msl, g.geoid_sep, g.satellites, g.hdop);
                done
            }
            Message::Vtg(v) => {
                fix.track_deg = v.track_deg.or(fix.track_deg);
                if let Some(speed) = v.speed_knots.map(|k| k * KNOTS_TO_MPS).or(v.speed_kmh.map(|k| k / 3.6)) {
                    fix.speed_mps = Some(speed);
                    self.speed_reported = true;
                }
                false
            }
            Message::Gsa(a) => {
                // As gpsd: GSA's dimension does not downgrade a 3D fix this epoch's GGA
                // established (receivers report the GSA of one constellation as "2").
                match a.fix_type {
                    Some(1) => fix.mode = FixMode::NoFix,
                    Some(2) if fix.mode != FixMode::Fix3d || fix.alt_msl.is_none() => fix.mode = FixMode::Fix2d,
                    Some(3) => fix.mode = FixMode::Fix3d,
                    _ => {}
                }
                fix.pdop = a.pdop.or(fix.pdop);
                fix.hdop = a.hdop.or(fix.hdop);
                fix.vdop = a.vdop.or(fix.vdop);
                false
            }
            Message::Gst(g) => {
                // Error statistics describe the fix; their time does not open a cycle
                // (receivers send GST after, and sometimes ahead of, the fix sentences).
                fix.sigma_lat_m = g.sigma_lat_m;
                fix.sigma_lon_m = g.sigma_lon_m;
                fix.sigma_alt_m = g.sigma_alt_m;
                false
            }
            Message::Zda(z) => {
                let done = self.at(z.time);
                if self.current.time_of_day == z.time && !self.dirty {
                    // A cycle opened by a time-only sentence knows nothing of the fix yet.
                    self.current.mode = FixMode::Unknown;
                }
                self.current.date = z.date.or(self.current.date);
                done
            }
            Message::Hdt(h) => {
                fix.heading_deg = h.heading_deg.or(fix.heading_deg);
                false
            }
            Message::Gsv(_) | Message::Proprietary(_) | Message::Unknown(_) => return false,
        };
        self.dirty = true;
        finished
    }

    /// The last epoch, at the end of the input.
    pub fn finish(&mut self) -> Option<GnssFix> {
        let done = (self.dirty && self.current.time_of_day.is_some()).then_some(self.current);
        self.dirty = false;
        done
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::nmea::messages::parse;
    use crate::nmea::sentence::Sentence;

    fn push(a: &mut EpochAssembler, line: &[u8]) -> Option<GnssFix> {
        a.push(&parse(&Sentence::parse(line, false).expect("sentence")).expect("message")).copied()
    }

    #[test]
    fn merges_an_epoch_and_hands_it_back_when_the_next_starts() {
        let mut a = EpochAssembler::new();
        assert_eq!(push(&mut a, b"$GPGGA,165007.000,4143.6058,N,08338.0778,W,1,06,1.5,204.3,M,-33.7,M,,0000"), None);
        push(&mut a, b"$GPGSA,A,3,31,16,29,23,20,32,,,,,,,2.8,1.5,2.4");
        push(&mut a, b"$GPRMC,165007.000,A,4143.6058,N,08338.0778,W,0.55,36.58,180710,,,A");
        let now = a.current();
        assert_eq!(now.mode, FixMode::Fix3d);
        assert!((now.speed_mps.expect("speed") - 0.283).abs() < 5e-4);
        assert!((now.alt_hae().expect("hae") - 170.6).abs() < 1e-9);
        let t = now.time().expect("time");
        // 2010-07-18T16:50:07Z
        assert_eq!(t.micros(), 1_279_471_807_000_000);
        let done =
            push(&mut a, b"$GPGGA,165008.000,4143.6059,N,08338.0786,W,1,06,1.5,204.1,M,-33.7,M,,0000").expect("epoch");
        assert_eq!(done.time(), Some(t));
        // No speed reported yet in the new epoch: derived from the move over 1 s.
        let (moved, _) = crate::geo::distance_and_bearing(41.726763333, -83.634630000, 41.726765000, -83.634643333)
            .expect("converges");
        assert!((a.current().speed_mps.expect("derived") - moved).abs() < 1e-3);
        assert_eq!(a.current().date, done.date, "the date persists");
        assert_eq!(a.finish().map(|f| f.alt_msl), Some(Some(204.1)));
    }

    #[test]
    fn invalid_status_means_no_fix() {
        let mut a = EpochAssembler::new();
        push(&mut a, b"$GPRMC,120000,V,,,,,,,010120,,");
        assert_eq!(a.current().mode, FixMode::NoFix);
        assert!(!a.current().has_position());
    }

    #[test]
    fn civil_days() {
        assert_eq!(days_since_unix_epoch(Date { year: 1970, month: 1, day: 1 }), 0);
        assert_eq!(days_since_unix_epoch(Date { year: 2000, month: 3, day: 1 }), 11_017);
        assert_eq!(days_since_unix_epoch(Date { year: 2024, month: 2, day: 29 }), 19_782);
    }
}
