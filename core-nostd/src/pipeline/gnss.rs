//! GNSS and vehicle-speed ingest: NMEA 0183 epochs, NMEA 2000 and J1939/OBD-II frames and
//! DBC-defined signals turned into fixes and speeds, written to the log and given to the
//! anchorer.

use embedded_io::Write;

use super::clock::OffsetChange;
use super::issues::Issue;
use super::signals::{self, GnssFrame};
use super::sink::LogSink;
use super::{quantise, PipelineError, SpeedSource};
use crate::binlog::{GnssFix, Record, VehicleSpeed};
use crate::can::{Decoded, Message};
use crate::decimal::Decimal;
use crate::geo::Geodetic;

/// A course over ground counts from this speed up, m/s.
const MIN_COURSE_SPEED_MPS: f64 = 5.0;
/// A receiver's speed error, m/s: the course's σ is this over the speed.
const COURSE_SPEED_SIGMA_MPS: f64 = 0.2;
/// The course's σ is at least this, rad (1°).
const MIN_COURSE_SIGMA_RAD: f64 = 1.0 * core::f64::consts::PI / 180.0;
use crate::nmea::{Event as NmeaEvent, StreamEvent};
use crate::time::Timestamp;

/// What GNSS and speed ingest keeps between inputs.
#[derive(Debug, Default)]
pub(super) struct GnssIngest {
    /// The latest HDOP from a full fix, for position-only CAN fixes.
    hdop: Option<f64>,
    /// Receive time of the NMEA sentence before the current one (the epoch's last).
    last_sentence: Option<Timestamp>,
    /// A DBC-defined GNSS source's latest time frame: (receive time, UTC of the fix).
    signal_epoch: Option<(Timestamp, Timestamp)>,
    /// The latest vehicle speed, m/s.
    last_speed: f64,
    /// Harsh braking from the vehicle speed.
    braking: super::braking::Braking,
}

/// A GNSS fix from NMEA or NMEA 2000, in the form the pipeline uses.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Fix {
    pub(super) utc: Option<Timestamp>,
    pub(super) lat: Option<f64>,
    pub(super) lon: Option<f64>,
    pub(super) alt: Option<f64>,
    pub(super) speed: Option<f64>,
    pub(super) track_deg: Option<f64>,
    pub(super) hdop: Option<f64>,
    pub(super) gst: Option<(f64, f64)>,
    pub(super) satellites: Option<u32>,
    pub(super) mode: i64,
}

/// A finished NMEA epoch in the pipeline's form.
pub(super) fn nmea_fix(f: &crate::nmea::GnssFix) -> Fix {
    Fix {
        utc: f.time(),
        lat: f.lat,
        lon: f.lon,
        alt: f.alt_hae().or(f.alt_msl),
        speed: f.speed_mps,
        track_deg: f.track_deg,
        hdop: f.hdop,
        gst: f.sigma_lat_m.zip(f.sigma_lon_m),
        satellites: f.satellites_used,
        mode: if f.has_position() { i64::from(f.mode.gpsd()) } else { 0 },
    }
}

/// What a CAN frame gives the pipeline.
pub(super) enum Reading {
    /// A vehicle speed, m/s, and its source's code in the log.
    Speed { mps: f64, source: i64 },
    /// A fix.
    Fix(Fix),
}

/// A fix's course over ground given to the anchorer: its σ, rad, from the fix's speed (none
/// below [`MIN_COURSE_SPEED_MPS`]).
pub(super) fn course_sigma(speed: f64) -> Option<f64> {
    (speed >= MIN_COURSE_SPEED_MPS).then(|| (COURSE_SPEED_SIGMA_MPS / speed).max(MIN_COURSE_SIGMA_RAD))
}

impl GnssIngest {
    /// The latest vehicle speed, m/s (0 before the first).
    pub(super) fn last_speed(&self) -> f64 {
        self.last_speed
    }

    /// Receive time of the last NMEA sentence: an epoch still open at the end was received
    /// then.
    pub(super) fn last_sentence(&self) -> Option<Timestamp> {
        self.last_sentence
    }

    /// An NMEA stream's event at `t`: a finished epoch's fix, with the receive time of its
    /// last sentence, when it has one.
    pub(super) fn nmea<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
        event: &StreamEvent<'_>,
    ) -> Result<Option<(Timestamp, Fix)>, PipelineError<W::Error>> {
        match event {
            StreamEvent::Sentence(NmeaEvent::Message { fix, .. }) => {
                let rx = self.last_sentence.unwrap_or(t);
                self.last_sentence = Some(t);
                Ok(fix.as_ref().map(|fix| (rx, nmea_fix(fix))))
            }
            StreamEvent::Sentence(_) => log.issue(t, Issue::NmeaBadSentence, 1).map(|()| None),
            StreamEvent::Dropped(_) => log.issue(t, Issue::NmeaDropped, 1).map(|()| None),
        }
    }

    /// A decoded CAN frame at `t`: a speed of the configured `source` or a fix, when it is
    /// one.
    pub(super) fn can<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        source: Option<SpeedSource>,
        t: Timestamp,
        event: crate::can::Event,
    ) -> Result<Option<Reading>, PipelineError<W::Error>> {
        let Decoded { message, .. } = match event {
            crate::can::Event::Decoded(d) => d,
            crate::can::Event::Error(_) | crate::can::Event::Dropped(_) => {
                return log.issue(t, Issue::CanBadFrame, 1).map(|()| None);
            }
        };
        Ok(match message {
            Message::WheelSpeed(w) if source == Some(SpeedSource::Ccvs1) => {
                w.speed_kmh.map(|kmh| Reading::Speed { mps: kmh / 3.6, source: 1 })
            }
            Message::Obd(r) if source == Some(SpeedSource::Obd) => {
                r.vehicle_speed_kmh().map(|kmh| Reading::Speed { mps: f64::from(kmh) / 3.6, source: 2 })
            }
            Message::GnssPosition(p) => {
                let utc = p
                    .date
                    .zip(p.time)
                    .map(|(d, s)| Timestamp::from_micros(i64::from(d) * 86_400_000_000 + i64::from(s) * 100));
                if p.hdop.is_some() {
                    self.hdop = p.hdop;
                }
                let fix = Fix {
                    utc,
                    lat: p.latitude,
                    lon: p.longitude,
                    alt: p.altitude,
                    hdop: p.hdop,
                    satellites: p.satellites.map(u32::from),
                    mode: if p.method == 0 {
                        0
                    } else if p.altitude.is_some() {
                        3
                    } else {
                        2
                    },
                    ..Fix::default()
                };
                Some(Reading::Fix(fix))
            }
            Message::PositionRapid(p) => Some(Reading::Fix(Fix {
                lat: p.latitude,
                lon: p.longitude,
                hdop: self.hdop,
                mode: 2,
                ..Fix::default()
            })),
            Message::VehiclePosition(p) => Some(Reading::Fix(Fix {
                lat: p.latitude,
                lon: p.longitude,
                hdop: self.hdop,
                mode: 2,
                ..Fix::default()
            })),
            _ => None,
        })
    }

    /// A frame of DBC-defined GNSS signals at `t`: a fix once its position has come.
    pub(super) fn signals<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
        read: GnssFrame,
    ) -> Result<Option<Fix>, PipelineError<W::Error>> {
        match read {
            GnssFrame::Time(utc) => {
                self.signal_epoch = Some((t, utc));
                Ok(None)
            }
            GnssFrame::Position { lat, lon, valid, sigma_m } => {
                let utc = self.signal_epoch.take().and_then(|(rx, utc)| (t - rx <= signals::EPOCH_GAP).then_some(utc));
                Ok(Some(Fix {
                    utc,
                    lat: Some(lat),
                    lon: Some(lon),
                    gst: sigma_m.map(|s| (s, s)),
                    mode: if valid { 2 } else { 0 },
                    ..Fix::default()
                }))
            }
            GnssFrame::Unreadable => log.issue(t, Issue::CanBadFrame, 1).map(|()| None),
        }
    }

    /// A vehicle speed the anchorer took, `mps` from `source`: its record, and harsh braking.
    pub(super) fn speed<W: Write, const BUF: usize>(
        &mut self,
        log: &mut LogSink<W, BUF>,
        t: Timestamp,
        mps: f64,
        source: i64,
    ) -> Result<(), PipelineError<W::Error>> {
        log.stats.speeds = log.stats.speeds.saturating_add(1);
        self.last_speed = mps;
        let record = VehicleSpeed { t_us: log.time(t), speed_mm_s: quantise(mps, 1e-3), source };
        log.write(&Record::VehicleSpeed(record))?;
        let Some(from) = self.braking.push(t, mps) else { return Ok(()) };
        log.stats.harsh_brakings = log.stats.harsh_brakings.saturating_add(1);
        log.event(
            t,
            3,
            format_args!(
                "harsh braking: over {} m/s² from {} m/s",
                Decimal::new(super::braking::HARSH_BRAKING_MPS2, 1),
                Decimal::new(from, 1)
            ),
        )
    }

    /// A fix received at `rx`: its UTC into the log's clock, its record; its position
    /// (heights missing taken as `default_height_m`), none when it has none.
    pub(super) fn fix<W: Write, const BUF: usize>(
        log: &mut LogSink<W, BUF>,
        default_height_m: f64,
        rx: Timestamp,
        fix: &Fix,
    ) -> Result<Option<Geodetic>, PipelineError<W::Error>> {
        let mut utc_trusted = false;
        if let Some(utc) = fix.utc {
            match log.clock.utc_sample(utc, rx) {
                OffsetChange::None => utc_trusted = true,
                OffsetChange::Ignored(by) => {
                    log.issue(rx, Issue::GnssTimeIgnored, 1)?;
                    log.event(
                        rx,
                        3,
                        format_args!(
                            "GNSS time {} s off the clock: not used as time",
                            Decimal::signed(by as f64 * 1e-6, 3)
                        ),
                    )?;
                }
                change => {
                    utc_trusted = true;
                    log.offset_changed(rx, change)?;
                }
            }
        }
        let position = match (fix.lat, fix.lon, fix.mode >= 2) {
            (Some(lat), Some(lon), true) => Geodetic::new(lat, lon, fix.alt.unwrap_or(default_height_m)).ok(),
            _ => None,
        };
        let Some(position) = position else {
            return log.issue(rx, Issue::GnssNoPosition, 1).map(|()| None);
        };
        let t_us = match fix.utc {
            Some(utc) if utc_trusted => utc.micros(),
            _ => log.time(rx),
        };
        let record = GnssFix {
            t_us,
            lat_e7: quantise(position.lat_deg, 1e-7),
            lon_e7: quantise(position.lon_deg, 1e-7),
            alt_mm: quantise(position.height_m, 1e-3),
            speed_mm_s: fix.speed.map_or(-1, |v| quantise(v, 1e-3)),
            track_e4: fix.track_deg.map_or(-1, |d| quantise(d * (core::f64::consts::PI / 180.0), 1e-4)),
            hdop_e2: fix.hdop.map_or(-1, |h| quantise(h, 1e-2)),
            satellites: fix.satellites.map_or(-1, i64::from),
            mode: fix.mode,
        };
        log.write(&Record::GnssFix(record))?;
        Ok(Some(position))
    }
}
