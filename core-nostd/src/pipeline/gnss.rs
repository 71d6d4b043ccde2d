//! GNSS and vehicle-speed ingest: NMEA 0183 epochs, NMEA 2000 and J1939/OBD-II frames and
//! DBC-defined signals turned into fixes and speeds, written to the log and given to the
//! anchorer.

use embedded_io::Write;

use super::clock::OffsetChange;
use super::issues::Issue;
use super::signals::{self, GnssFrame};
use super::{quantise, PipelineError, SpeedSource, State};
use crate::anchor::gnss_sigma;
use crate::binlog::{ClockOffset, GnssFix, Record, VehicleSpeed};
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
    pub(super) hdop: Option<f64>,
    /// Receive time of the NMEA sentence before the current one (the epoch's last).
    pub(super) last_sentence: Option<Timestamp>,
    /// A DBC-defined GNSS source's latest time frame: (receive time, UTC of the fix).
    pub(super) signal_epoch: Option<(Timestamp, Timestamp)>,
    /// The latest vehicle speed, m/s.
    pub(super) last_speed: f64,
    /// Harsh braking from the vehicle speed.
    pub(super) braking: super::braking::Braking,
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

impl<W: Write, const T3: usize, const T2: usize, const BUF: usize> State<'_, W, T3, T2, BUF> {
    pub(super) fn on_nmea(&mut self, t: Timestamp, event: &StreamEvent<'_>) -> Result<(), PipelineError<W::Error>> {
        match event {
            StreamEvent::Sentence(NmeaEvent::Message { fix, .. }) => {
                if let Some(fix) = fix {
                    let rx = self.gnss.last_sentence.unwrap_or(t);
                    self.on_fix(rx, &nmea_fix(fix))?;
                }
                self.gnss.last_sentence = Some(t);
                Ok(())
            }
            StreamEvent::Sentence(_) => self.log.issue(t, Issue::NmeaBadSentence, 1),
            StreamEvent::Dropped(_) => self.log.issue(t, Issue::NmeaDropped, 1),
        }
    }

    pub(super) fn on_can(&mut self, t: Timestamp, event: crate::can::Event) -> Result<(), PipelineError<W::Error>> {
        let Decoded { message, .. } = match event {
            crate::can::Event::Decoded(d) => d,
            crate::can::Event::Error(_) | crate::can::Event::Dropped(_) => {
                return self.log.issue(t, Issue::CanBadFrame, 1);
            }
        };
        let source = self.config.speed;
        match message {
            Message::WheelSpeed(w) if source == Some(SpeedSource::Ccvs1) => match w.speed_kmh {
                Some(kmh) => self.speed(t, kmh / 3.6, 1),
                None => Ok(()),
            },
            Message::Obd(r) if source == Some(SpeedSource::Obd) => match r.vehicle_speed_kmh() {
                Some(kmh) => self.speed(t, f64::from(kmh) / 3.6, 2),
                None => Ok(()),
            },
            Message::GnssPosition(p) => {
                let utc = p
                    .date
                    .zip(p.time)
                    .map(|(d, s)| Timestamp::from_micros(i64::from(d) * 86_400_000_000 + i64::from(s) * 100));
                if p.hdop.is_some() {
                    self.gnss.hdop = p.hdop;
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
                self.on_fix(t, &fix)
            }
            Message::PositionRapid(p) => {
                let fix = Fix { lat: p.latitude, lon: p.longitude, hdop: self.gnss.hdop, mode: 2, ..Fix::default() };
                self.on_fix(t, &fix)
            }
            Message::VehiclePosition(p) => {
                let fix = Fix { lat: p.latitude, lon: p.longitude, hdop: self.gnss.hdop, mode: 2, ..Fix::default() };
                self.on_fix(t, &fix)
            }
            _ => Ok(()),
        }
    }

    pub(super) fn on_gnss_signals(&mut self, t: Timestamp, read: GnssFrame) -> Result<(), PipelineError<W::Error>> {
        match read {
            GnssFrame::Time(utc) => {
                self.gnss.signal_epoch = Some((t, utc));
                Ok(())
            }
            GnssFrame::Position { lat, lon, valid, sigma_m } => {
                let utc =
                    self.gnss.signal_epoch.take().and_then(|(rx, utc)| (t - rx <= signals::EPOCH_GAP).then_some(utc));
                let fix = Fix {
                    utc,
                    lat: Some(lat),
                    lon: Some(lon),
                    gst: sigma_m.map(|s| (s, s)),
                    mode: if valid { 2 } else { 0 },
                    ..Fix::default()
                };
                self.on_fix(t, &fix)
            }
            GnssFrame::Unreadable => self.log.issue(t, Issue::CanBadFrame, 1),
        }
    }

    pub(super) fn speed(&mut self, t: Timestamp, mps: f64, source: i64) -> Result<(), PipelineError<W::Error>> {
        if self.anchoring.anchorer.push_speed(t, mps).is_err() {
            return self.log.issue(t, Issue::SpeedRefused, 1);
        }
        self.log.stats.speeds = self.log.stats.speeds.saturating_add(1);
        self.gnss.last_speed = mps;
        self.inertial.on_speed(t, mps);
        let record = VehicleSpeed { t_us: self.log.time(t), speed_mm_s: quantise(mps, 1e-3), source };
        self.log.write(&Record::VehicleSpeed(record))?;
        let Some(from) = self.gnss.braking.push(t, mps) else { return Ok(()) };
        self.log.stats.harsh_brakings = self.log.stats.harsh_brakings.saturating_add(1);
        self.log.event(
            t,
            3,
            format_args!(
                "harsh braking: over {} m/s² from {} m/s",
                Decimal::new(super::braking::HARSH_BRAKING_MPS2, 1),
                Decimal::new(from, 1)
            ),
        )
    }

    pub(super) fn on_fix(&mut self, rx: Timestamp, fix: &Fix) -> Result<(), PipelineError<W::Error>> {
        let mut utc_trusted = false;
        if let Some(utc) = fix.utc {
            match self.log.clock.utc_sample(utc, rx) {
                OffsetChange::None => utc_trusted = true,
                OffsetChange::Ignored(by) => {
                    self.log.issue(rx, Issue::GnssTimeIgnored, 1)?;
                    self.log.event(
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
                    let (offset, reason, text) = match change {
                        OffsetChange::First(o) => (o, 0, "UTC known from the first fix: the log is in UTC from here"),
                        OffsetChange::Drift(o) => (o, 1, ""),
                        OffsetChange::Step { offset, .. } => (offset, 2, "GNSS time stepped; the clock offset follows"),
                        _ => (self.log.clock.offset().unwrap_or(0), 3, "UTC taken again after the device clock reset"),
                    };
                    let record = ClockOffset { t_us: self.log.time(rx), offset_us: offset, reason };
                    self.log.write(&Record::ClockOffset(record))?;
                    if !text.is_empty() {
                        self.log.event(rx, 2, format_args!("{text} (offset {} µs)", offset))?;
                    }
                }
            }
        }
        let position = match (fix.lat, fix.lon, fix.mode >= 2) {
            (Some(lat), Some(lon), true) => {
                Geodetic::new(lat, lon, fix.alt.unwrap_or(self.config.origin.height_m)).ok()
            }
            _ => None,
        };
        let Some(position) = position else {
            return self.log.issue(rx, Issue::GnssNoPosition, 1);
        };
        let t_us = match fix.utc {
            Some(utc) if utc_trusted => utc.micros(),
            _ => self.log.time(rx),
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
        self.log.write(&Record::GnssFix(record))?;
        if let (Some(speed), Some(track)) = (fix.speed, fix.track_deg) {
            let up = self.inertial.up();
            self.inertial.bias.push_course(rx.as_secs_f64(), track.to_radians(), speed, &up);
            if speed >= MIN_COURSE_SPEED_MPS {
                // A session not yet anchored takes its yaw from the course.
                let sigma = (COURSE_SPEED_SIGMA_MPS / speed).max(MIN_COURSE_SIGMA_RAD);
                if self.anchoring.anchorer.push_course(rx, track.to_radians(), sigma) {
                    self.log.event(rx, 2, format_args!("anchor: the VO session's yaw from the GNSS course"))?;
                }
            }
        }
        let g = &self.config.gnss;
        let sigma = gnss_sigma(fix.hdop, fix.gst, g.uere_m).unwrap_or(g.default_sigma_m);
        let enu = self.anchoring.local.geodetic_to_enu(&position);
        if self.anchoring.anchorer.push_gnss(rx, enu, sigma).is_err() {
            return self.log.issue(rx, Issue::GnssRefused, 1);
        }
        self.log.stats.fixes = self.log.stats.fixes.saturating_add(1);
        Ok(())
    }
}
