//! Decoded NMEA 0183 messages: GGA, RMC, GLL, VTG, GSA, GSV, GST, GNS, ZDA, HDT.
//!
//! Total over sentence types: anything else is [`Message::Unknown`] or
//! [`Message::Proprietary`], not an error. A present field that cannot be what its
//! position requires (a letter in a number, latitude 95°) is an error naming the field.

use super::sentence::{Fields, Sentence, Talker};

/// Time of day, UTC, in microseconds since midnight.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TimeOfDay(pub i64);

/// A calendar date (UTC).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Date {
    /// Full year.
    pub year: u16,
    /// 1..=12.
    pub month: u8,
    /// 1..=31.
    pub day: u8,
}

/// GGA: fix data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gga {
    /// UTC time of the fix.
    pub time: Option<TimeOfDay>,
    /// Latitude, degrees.
    pub lat: Option<f64>,
    /// Longitude, degrees.
    pub lon: Option<f64>,
    /// Fix quality: 0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning…
    pub quality: u8,
    /// Satellites used.
    pub satellites: Option<u32>,
    /// Horizontal dilution of precision.
    pub hdop: Option<f64>,
    /// Altitude above mean sea level, m.
    pub alt_msl: Option<f64>,
    /// Geoid separation (ellipsoid above geoid), m.
    pub geoid_sep: Option<f64>,
}

/// RMC: recommended minimum data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rmc {
    /// UTC time.
    pub time: Option<TimeOfDay>,
    /// `A` valid, `V` warning.
    pub valid: bool,
    /// Latitude, degrees.
    pub lat: Option<f64>,
    /// Longitude, degrees.
    pub lon: Option<f64>,
    /// Speed over ground, knots.
    pub speed_knots: Option<f64>,
    /// Course over ground, degrees true.
    pub track_deg: Option<f64>,
    /// UTC date.
    pub date: Option<Date>,
    /// Magnetic variation, degrees (east positive).
    pub mag_var_deg: Option<f64>,
    /// FAA mode indicator (NMEA 2.3+): A, D, E, F, M, N, R, S.
    pub mode: Option<u8>,
}

/// GLL: position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gll {
    /// Latitude, degrees.
    pub lat: Option<f64>,
    /// Longitude, degrees.
    pub lon: Option<f64>,
    /// UTC time.
    pub time: Option<TimeOfDay>,
    /// `A` valid.
    pub valid: bool,
    /// FAA mode indicator.
    pub mode: Option<u8>,
}

/// VTG: track and speed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vtg {
    /// Course over ground, degrees true.
    pub track_deg: Option<f64>,
    /// Speed over ground, knots.
    pub speed_knots: Option<f64>,
    /// Speed over ground, km/h.
    pub speed_kmh: Option<f64>,
    /// FAA mode indicator.
    pub mode: Option<u8>,
}

/// GSA: DOP and active satellites.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gsa {
    /// 1 no fix, 2 2D, 3 3D.
    pub fix_type: Option<u32>,
    /// Satellites listed as used.
    pub satellites_used: u8,
    /// Position DOP.
    pub pdop: Option<f64>,
    /// Horizontal DOP.
    pub hdop: Option<f64>,
    /// Vertical DOP.
    pub vdop: Option<f64>,
}

/// One satellite of a GSV sentence.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct SatelliteInView {
    /// PRN / satellite number.
    pub prn: u32,
    /// Elevation, degrees. (`f32`: sentences carry at most 0.1° — and a smaller
    /// message is cheaper to move on a microcontroller.)
    pub elevation_deg: Option<f32>,
    /// Azimuth, degrees.
    pub azimuth_deg: Option<f32>,
    /// Signal-to-noise ratio, dB-Hz.
    pub snr_dbhz: Option<f32>,
}

/// GSV: satellites in view (one part of a group).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gsv {
    /// Sentences in the group.
    pub total: u32,
    /// This sentence's number, 1-based.
    pub number: u32,
    /// Satellites in view.
    pub in_view: Option<u32>,
    /// Up to four satellites.
    pub satellites: [Option<SatelliteInView>; 4],
}

/// GST: pseudorange error statistics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gst {
    /// UTC time.
    pub time: Option<TimeOfDay>,
    /// RMS of the pseudorange residuals, m.
    pub rms: Option<f64>,
    /// 1-σ latitude error, m.
    pub sigma_lat_m: Option<f64>,
    /// 1-σ longitude error, m.
    pub sigma_lon_m: Option<f64>,
    /// 1-σ altitude error, m.
    pub sigma_alt_m: Option<f64>,
}

/// GNS: multi-constellation fix data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Gns {
    /// UTC time.
    pub time: Option<TimeOfDay>,
    /// Latitude, degrees.
    pub lat: Option<f64>,
    /// Longitude, degrees.
    pub lon: Option<f64>,
    /// First mode character (GPS): N no fix, A autonomous, D differential, R/F RTK, E DR.
    pub mode: Option<u8>,
    /// True when any constellation's mode character is not `N`.
    pub any_fix: bool,
    /// Satellites used.
    pub satellites: Option<u32>,
    /// HDOP.
    pub hdop: Option<f64>,
    /// Altitude above MSL, m.
    pub alt_msl: Option<f64>,
    /// Geoid separation, m.
    pub geoid_sep: Option<f64>,
}

/// ZDA: date and time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Zda {
    /// UTC time.
    pub time: Option<TimeOfDay>,
    /// UTC date.
    pub date: Option<Date>,
}

/// HDT: true heading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hdt {
    /// Heading, degrees true.
    pub heading_deg: Option<f64>,
}

/// A decoded sentence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Message<'a> {
    /// Fix data.
    Gga(Gga),
    /// Recommended minimum.
    Rmc(Rmc),
    /// Position.
    Gll(Gll),
    /// Track and speed.
    Vtg(Vtg),
    /// DOP and active satellites.
    Gsa(Gsa),
    /// Satellites in view.
    Gsv(Gsv),
    /// Error statistics.
    Gst(Gst),
    /// Multi-constellation fix.
    Gns(Gns),
    /// Date and time.
    Zda(Zda),
    /// True heading.
    Hdt(Hdt),
    /// A proprietary sentence (manufacturer code and fields, undecoded).
    Proprietary(&'a [u8]),
    /// A standard sentence type this crate does not decode (e.g. `TXT`, `DPT`).
    Unknown(&'a [u8]),
}

/// Why a sentence's fields could not be decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MessageError {
    /// Field `index` (1-based) is not of the expected form.
    BadField {
        /// 1-based field index.
        index: u8,
    },
    /// Field `index` is out of its range (latitude beyond 90°, minutes ≥ 60, month 13…).
    OutOfRange {
        /// 1-based field index.
        index: u8,
    },
}

impl core::fmt::Display for MessageError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            MessageError::BadField { index } => write!(f, "field {index} is malformed"),
            MessageError::OutOfRange { index } => write!(f, "field {index} is out of range"),
        }
    }
}

impl core::error::Error for MessageError {}

/// A field reader that knows its position, for error messages.
struct Reader<'a> {
    fields: Fields<'a>,
    index: u8,
}

impl<'a> Reader<'a> {
    fn new(s: &Sentence<'a>) -> Self {
        Reader { fields: s.cursor(), index: 0 }
    }

    fn bad(&self) -> MessageError {
        MessageError::BadField { index: self.index }
    }

    fn range(&self) -> MessageError {
        MessageError::OutOfRange { index: self.index }
    }

    fn raw(&mut self) -> &'a [u8] {
        self.index = self.index.saturating_add(1);
        self.fields.next_raw()
    }

    fn skip(&mut self, n: u8) {
        for _ in 0..n {
            self.raw();
        }
    }

    fn f64(&mut self) -> Result<Option<f64>, MessageError> {
        self.index = self.index.saturating_add(1);
        self.fields.f64().map_err(|e| MessageError::BadField { index: e.index })
    }

    fn u32(&mut self) -> Result<Option<u32>, MessageError> {
        self.index = self.index.saturating_add(1);
        self.fields.u32().map_err(|e| MessageError::BadField { index: e.index })
    }

    fn char(&mut self) -> Option<u8> {
        self.index = self.index.saturating_add(1);
        self.fields.char()
    }

    /// `ddmm.mmm,N` or `dddmm.mmm,E` (two fields) as gpsd computes it.
    fn coordinate(&mut self, limit: f64) -> Result<Option<f64>, MessageError> {
        let value = self.f64()?;
        let hemisphere = self.char();
        let Some(v) = value else { return Ok(None) };
        let degrees = libm::trunc(v / 100.0);
        let minutes = v - degrees * 100.0;
        if !(0.0..60.0).contains(&minutes) || degrees > limit {
            self.index = self.index.saturating_sub(1);
            return Err(self.range());
        }
        let deg = degrees + minutes / 60.0;
        if deg > limit {
            return Err(self.range());
        }
        // A value without its hemisphere is a truncated sentence, not a northern one.
        match hemisphere {
            Some(b'N' | b'E') => Ok(Some(deg)),
            Some(b'S' | b'W') => Ok(Some(-deg)),
            _ => Err(self.bad()),
        }
    }

    /// `hhmmss[.sss]`.
    fn time(&mut self) -> Result<Option<TimeOfDay>, MessageError> {
        let raw = self.raw();
        if raw.is_empty() {
            return Ok(None);
        }
        let (whole, frac) = match raw.iter().position(|&b| b == b'.') {
            Some(i) => (&raw[..i], &raw[i + 1..]),
            None => (raw, &[][..]),
        };
        if whole.len() != 6 || !whole.iter().chain(frac).all(u8::is_ascii_digit) {
            return Err(self.bad());
        }
        let two = |i: usize| i64::from(whole[i] - b'0') * 10 + i64::from(whole[i + 1] - b'0');
        let (h, m, s) = (two(0), two(2), two(4));
        // 60 allows a leap second.
        if h > 23 || m > 59 || s > 60 {
            return Err(self.range());
        }
        let mut micros = 0i64;
        let mut scale = 100_000i64;
        for &d in frac.iter().take(6) {
            micros += i64::from(d - b'0') * scale;
            scale /= 10;
        }
        Ok(Some(TimeOfDay(((h * 60 + m) * 60 + s) * 1_000_000 + micros)))
    }

    /// `ddmmyy` with a two-digit year (1980–2079).
    fn date_ddmmyy(&mut self) -> Result<Option<Date>, MessageError> {
        let raw = self.raw();
        if raw.is_empty() {
            return Ok(None);
        }
        if raw.len() != 6 || !raw.iter().all(u8::is_ascii_digit) {
            return Err(self.bad());
        }
        let two = |i: usize| (raw[i] - b'0') * 10 + (raw[i + 1] - b'0');
        let (day, month, yy) = (two(0), two(2), two(4));
        if !(1..=31).contains(&day) || !(1..=12).contains(&month) {
            return Err(self.range());
        }
        let year = if yy < 80 { 2000 + u16::from(yy) } else { 1900 + u16::from(yy) };
        Ok(Some(Date { year, month, day }))
    }
}

fn is_valid_flag(c: Option<u8>) -> bool {
    c == Some(b'A')
}

/// Decode a checked sentence.
pub fn parse<'a>(s: &Sentence<'a>) -> Result<Message<'a>, MessageError> {
    if s.talker == Talker::Proprietary {
        return Ok(Message::Proprietary(s.kind));
    }
    let mut r = Reader::new(s);
    Ok(match s.kind {
        b"GGA" => {
            let time = r.time()?;
            let lat = r.coordinate(90.0)?;
            let lon = r.coordinate(180.0)?;
            let quality = r.u32()?.unwrap_or(0).min(255) as u8;
            let satellites = r.u32()?;
            let hdop = r.f64()?;
            let alt_msl = r.f64()?;
            r.skip(1);
            let geoid_sep = r.f64()?;
            Message::Gga(Gga { time, lat, lon, quality, satellites, hdop, alt_msl, geoid_sep })
        }
        b"RMC" => {
            let time = r.time()?;
            let valid = is_valid_flag(r.char());
            let lat = r.coordinate(90.0)?;
            let lon = r.coordinate(180.0)?;
            let speed_knots = r.f64()?;
            let track_deg = r.f64()?;
            // A malformed date (some receivers write `2208-1` before they know it) costs
            // the date only; the position and velocity of the sentence are still good.
            let date = r.date_ddmmyy().unwrap_or(None);
            let var = r.f64()?;
            let var_dir = r.char();
            let mag_var_deg = var.map(|v| if var_dir == Some(b'W') { -v } else { v });
            let mode = r.char();
            Message::Rmc(Rmc { time, valid, lat, lon, speed_knots, track_deg, date, mag_var_deg, mode })
        }
        b"GLL" => {
            let lat = r.coordinate(90.0)?;
            let lon = r.coordinate(180.0)?;
            let time = r.time()?;
            let valid = is_valid_flag(r.char());
            let mode = r.char();
            Message::Gll(Gll { lat, lon, time, valid, mode })
        }
        b"VTG" => {
            let track_deg = r.f64()?;
            // NMEA 2.3+ marks each value with a unit letter; older receivers do not.
            let mut probe = s.cursor();
            probe.skip(1);
            let tagged = probe.next_raw() == b"T";
            if tagged {
                r.skip(3);
                let speed_knots = r.f64()?;
                r.skip(1);
                let speed_kmh = r.f64()?;
                r.skip(1);
                let mode = r.char();
                Message::Vtg(Vtg { track_deg, speed_knots, speed_kmh, mode })
            } else {
                r.skip(1);
                let speed_knots = r.f64()?;
                let speed_kmh = r.f64()?;
                Message::Vtg(Vtg { track_deg, speed_knots, speed_kmh, mode: None })
            }
        }
        b"GSA" => {
            r.skip(1);
            let fix_type = r.u32()?;
            let mut used = 0u8;
            for _ in 0..12 {
                if r.u32()?.is_some() {
                    used += 1;
                }
            }
            let pdop = r.f64()?;
            let hdop = r.f64()?;
            let vdop = r.f64()?;
            Message::Gsa(Gsa { fix_type, satellites_used: used, pdop, hdop, vdop })
        }
        b"GSV" => {
            let total = r.u32()?.unwrap_or(0);
            let number = r.u32()?.unwrap_or(0);
            let in_view = r.u32()?;
            let mut satellites = [None; 4];
            for slot in satellites.iter_mut() {
                let prn = r.u32()?;
                let elevation_deg = r.f64()?.map(|v| v as f32);
                let azimuth_deg = r.f64()?.map(|v| v as f32);
                let snr_dbhz = r.f64()?.map(|v| v as f32);
                *slot = prn.map(|prn| SatelliteInView { prn, elevation_deg, azimuth_deg, snr_dbhz });
            }
            Message::Gsv(Gsv { total, number, in_view, satellites })
        }
        b"GST" => {
            let time = r.time()?;
            let rms = r.f64()?;
            r.skip(3);
            let sigma_lat_m = r.f64()?;
            let sigma_lon_m = r.f64()?;
            let sigma_alt_m = r.f64()?;
            Message::Gst(Gst { time, rms, sigma_lat_m, sigma_lon_m, sigma_alt_m })
        }
        b"GNS" => {
            let time = r.time()?;
            let lat = r.coordinate(90.0)?;
            let lon = r.coordinate(180.0)?;
            let modes = r.raw();
            let satellites = r.u32()?;
            let hdop = r.f64()?;
            let alt_msl = r.f64()?;
            let geoid_sep = r.f64()?;
            Message::Gns(Gns {
                time,
                lat,
                lon,
                mode: modes.first().copied(),
                any_fix: modes.iter().any(|&m| m != b'N'),
                satellites,
                hdop,
                alt_msl,
                geoid_sep,
            })
        }
        b"ZDA" => {
            let time = r.time()?;
            let day = r.u32()?;
            let month = r.u32()?;
            let year = r.u32()?;
            let date = match (day, month, year) {
                (Some(d), Some(m), Some(y)) => {
                    if !(1..=31).contains(&d) || !(1..=12).contains(&m) || !(1980..=2200).contains(&y) {
                        return Err(r.range());
                    }
                    Some(Date { year: y as u16, month: m as u8, day: d as u8 })
                }
                _ => None,
            };
            Message::Zda(Zda { time, date })
        }
        b"HDT" => Message::Hdt(Hdt { heading_deg: r.f64()? }),
        other => Message::Unknown(other),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn decode(line: &[u8]) -> Result<Message<'_>, MessageError> {
        parse(&Sentence::parse(line, false).expect("sentence"))
    }

    #[test]
    fn gga_from_a_garmin() {
        let Ok(Message::Gga(g)) =
            decode(b"$GPGGA,165007.000,4143.6058,N,08338.0778,W,1,06,1.5,204.3,M,-33.7,M,,0000*67")
        else {
            panic!("not GGA");
        };
        assert_eq!(g.time, Some(TimeOfDay(((16 * 60 + 50) * 60 + 7) * 1_000_000)));
        assert!((g.lat.expect("lat") - 41.726763333).abs() < 1e-9);
        assert!((g.lon.expect("lon") + 83.634630000).abs() < 1e-9);
        assert_eq!(
            (g.quality, g.satellites, g.hdop, g.alt_msl, g.geoid_sep),
            (1, Some(6), Some(1.5), Some(204.3), Some(-33.7))
        );
    }

    #[test]
    fn rmc_date_speed_and_variation() {
        let Ok(Message::Rmc(m)) = decode(b"$GPRMC,165007.000,A,4143.6058,N,08338.0778,W,0.55,36.58,180710,7.0,W,A")
        else {
            panic!("not RMC");
        };
        assert!(m.valid);
        assert_eq!(m.date, Some(Date { year: 2010, month: 7, day: 18 }));
        assert_eq!(
            (m.speed_knots, m.track_deg, m.mag_var_deg, m.mode),
            (Some(0.55), Some(36.58), Some(-7.0), Some(b'A'))
        );
    }

    #[test]
    fn old_and_new_vtg() {
        let Ok(Message::Vtg(new)) = decode(b"$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A") else { panic!() };
        let Ok(Message::Vtg(old)) = decode(b"$GPVTG,054.7,034.4,005.5,010.2") else { panic!() };
        assert_eq!((new.track_deg, new.speed_knots, new.speed_kmh), (Some(54.7), Some(5.5), Some(10.2)));
        assert_eq!((old.track_deg, old.speed_knots, old.speed_kmh), (Some(54.7), Some(5.5), Some(10.2)));
    }

    #[test]
    fn out_of_range_and_malformed_fields_name_the_field() {
        assert_eq!(
            decode(b"$GPGGA,120000,9500.000,N,00000.000,E,1,5,1.0,1,M,0,M,,"),
            Err(MessageError::OutOfRange { index: 2 })
        );
        assert_eq!(
            decode(b"$GPGGA,120000,4500.000,N,00000.000,E,1,x,1.0,1,M,0,M,,"),
            Err(MessageError::BadField { index: 7 })
        );
        assert_eq!(decode(b"$GPRMC,250000,A,,,,,,,,,"), Err(MessageError::OutOfRange { index: 1 }));
        assert_eq!(decode(b"$GPZDA,120000,01,13,2020,,"), Err(MessageError::OutOfRange { index: 4 }));
        // Truncated after the latitude value: its hemisphere (field 4) is missing.
        assert_eq!(decode(b"$GPRMC,120001.00,A,4807.03"), Err(MessageError::BadField { index: 4 }));
    }

    #[test]
    fn unknown_and_proprietary_are_not_errors() {
        assert_eq!(decode(b"$GPTXT,01,01,02,hello"), Ok(Message::Unknown(b"TXT")));
        assert_eq!(decode(b"$PUBX,00,1"), Ok(Message::Proprietary(b"UBX")));
    }

    #[test]
    fn messages_stay_small() {
        // Moved by value through the decoder on every sentence.
        assert!(size_of::<Message<'_>>() <= 168, "{}", size_of::<Message<'_>>());
    }

    #[test]
    fn gsa_gsv_gst_gns_zda_hdt() {
        let Ok(Message::Gsa(a)) = decode(b"$GPGSA,A,3,31,16,29,23,20,32,,,,,,,2.8,1.5,2.4") else { panic!() };
        assert_eq!(
            (a.fix_type, a.satellites_used, a.pdop, a.hdop, a.vdop),
            (Some(3), 6, Some(2.8), Some(1.5), Some(2.4))
        );
        let Ok(Message::Gsv(v)) = decode(b"$GPGSV,3,3,10,03,08,171,,14,06,129,") else { panic!() };
        assert_eq!((v.total, v.number, v.in_view), (3, 3, Some(10)));
        assert_eq!(v.satellites[1].map(|s| s.prn), Some(14));
        assert_eq!(v.satellites[2], None);
        let Ok(Message::Gst(t)) = decode(b"$GPGST,172814.0,0.006,0.023,0.020,273.6,0.023,0.020,0.031") else {
            panic!()
        };
        assert_eq!((t.sigma_lat_m, t.sigma_lon_m, t.sigma_alt_m), (Some(0.023), Some(0.020), Some(0.031)));
        let Ok(Message::Gns(n)) = decode(b"$GNGNS,014035.00,4332.69262,S,17235.48549,E,RR,13,0.9,25.63,11.24,,") else {
            panic!()
        };
        assert_eq!((n.mode, n.any_fix, n.satellites), (Some(b'R'), true, Some(13)));
        assert!(n.lat.expect("lat") < 0.0);
        let Ok(Message::Zda(z)) = decode(b"$GPZDA,160012.71,11,03,2004,-1,00") else { panic!() };
        assert_eq!(z.date, Some(Date { year: 2004, month: 3, day: 11 }));
        let Ok(Message::Hdt(h)) = decode(b"$HEHDT,274.07,T") else { panic!() };
        assert_eq!(h.heading_deg, Some(274.07));
    }
}
