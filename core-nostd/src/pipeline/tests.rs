//! The pipeline on a small synthetic drive: a straight road east at 10 m/s, VO in a frame
//! turned by 1 rad and scaled by 0.5, a receiver sending GGA + RMC at 5 Hz (80 ms late),
//! CCVS1 wheel speed at 50 Hz, a cone ahead seen by the camera.

use core::fmt::Write as _;

use embedded_can::{ExtendedId, Id};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;

use super::*;
use crate::binlog::{Decoder, EgoPose, Event as LogEvent, Kind};
use crate::box3d::Box3d;
use crate::can::CanFrame;
use crate::geo::LocalFrame;
use crate::score::AgentKind;
use crate::sim3::rotation_z;
use crate::track2d::TrackerConfig;
use crate::track3d::{wrap_angle, Association, ClassConfig};

const ORIGIN_LAT: f64 = 60.0;
const ORIGIN_LON: f64 = 25.0;
/// UTC of device time 0 (2026-06-01T08:00:00Z), µs.
const UTC0: i64 = 1_780_300_800_000_000;
const LATENCY_US: i64 = 80_000;

fn cone_class() -> [ClassConfig; 1] {
    [ClassConfig {
        association: Association::Distance(2.0),
        min_size: [0.2; 3],
        max_size: [1.0; 3],
        max_ground_offset: 0.3,
        process_noise: [1e-3; 10],
        measurement_noise: [0.1; 7],
        initial_velocity_variance: 0.01,
    }]
}

const META: [ClassMeta; 1] = [ClassMeta { code: 6, kind: AgentKind::Object }];

fn config() -> PipelineConfig<'static> {
    let origin = Geodetic::new(ORIGIN_LAT, ORIGIN_LON, 0.0).unwrap_or_else(|_| unreachable!());
    PipelineConfig {
        anchor: AnchorConfig { mode: crate::anchor::AnchorMode::GravityAligned, ..AnchorConfig::default() },
        speed: Some(SpeedSource::Ccvs1),
        ..PipelineConfig::new(origin, &META)
    }
}

fn trackers(classes: &[ClassConfig]) -> Trackers<'_, 8, 4> {
    let tracker = Config3d { classes, min_hits: 2, max_age: 3, ground_z: 0.0, static_speed: 0.3 };
    Trackers::new(tracker, TrackerConfig::default())
}

fn us(t: i64) -> Timestamp {
    Timestamp::from_micros(t)
}

/// Where the camera is at device time `t_us` (ENU).
fn camera_at(t_us: i64) -> Vector3<f64> {
    Vector3::new(10.0 * t_us as f64 * 1e-6 + 1.8, 100.0, 1.3)
}

fn vo_pose(t_us: i64) -> Pose {
    // ENU = 0.5⁻¹… the VO frame is the world turned by −1 rad and scaled by 2.
    let to_vo = rotation_z(-1.0);
    Pose { rotation: to_vo, translation: to_vo * camera_at(t_us) * 2.0 }
}

fn sentence(body: &str) -> heapless::String<128> {
    let checksum = body.bytes().fold(0u8, |c, b| c ^ b);
    let mut s = heapless::String::new();
    let _ = write!(s, "${body}*{checksum:02X}\r\n");
    s
}

/// GGA + RMC of the fix at device time `t_us` whose UTC is `utc_us`.
fn nmea(t_us: i64, utc_us: i64) -> heapless::String<256> {
    nmea_fix(&camera_at(t_us), 90.0, utc_us)
}

/// GGA + RMC of a fix at `p` (ENU) at 10 m/s on `course_deg` (clockwise from north), whose
/// UTC is `utc_us`.
fn nmea_fix(p: &Vector3<f64>, course_deg: f64, utc_us: i64) -> heapless::String<256> {
    let frame = LocalFrame::new(Geodetic::new(ORIGIN_LAT, ORIGIN_LON, 0.0).unwrap_or_else(|_| unreachable!()));
    let g = frame.enu_to_geodetic(p).unwrap_or_else(|_| unreachable!());
    let tod = utc_us.rem_euclid(86_400_000_000) / 10_000; // centiseconds
    let (h, m, s, cs) = (tod / 360_000, tod / 6000 % 60, tod / 100 % 60, tod % 100);
    let lat_min = (g.lat_deg - 60.0) * 60.0;
    let lon_min = (g.lon_deg - 25.0) * 60.0;
    let mut gga: heapless::String<128> = heapless::String::new();
    let _ = write!(
        gga,
        "GPGGA,{h:02}{m:02}{s:02}.{cs:02},60{lat_min:09.6},N,025{lon_min:09.6},E,1,09,0.8,{:.2},M,0.0,M,,",
        g.height_m
    );
    let mut rmc: heapless::String<128> = heapless::String::new();
    let _ = write!(
        rmc,
        "GPRMC,{h:02}{m:02}{s:02}.{cs:02},A,60{lat_min:09.6},N,025{lon_min:09.6},E,19.44,{course_deg:.1},010626,,,A"
    );
    let mut out = heapless::String::new();
    let _ = out.push_str(&sentence(&gga));
    let _ = out.push_str(&sentence(&rmc));
    out
}

fn ccvs1(mps: f64) -> CanFrame {
    let raw = ((mps * 3.6 * 256.0) as u16).to_le_bytes();
    let id = Id::Extended(ExtendedId::new(0x18FE_F100).unwrap_or(ExtendedId::ZERO));
    CanFrame::data_frame(id, &[0xFF, raw[0], raw[1], 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]).unwrap_or_else(|| unreachable!())
}

fn standard(id: u16, data: &[u8]) -> CanFrame {
    let id = Id::Standard(embedded_can::StandardId::new(id).unwrap_or(embedded_can::StandardId::ZERO));
    CanFrame::data_frame(id, data).unwrap_or_else(|| unreachable!())
}

/// A CANmod gnss_pos frame.
pub(super) fn canmod_position(lat: f64, lon: f64, valid: bool, accuracy_m: u64) -> CanFrame {
    let lat_raw = libm::round((lat + 90.0) * 1e6) as u64;
    let lon_raw = libm::round((lon + 180.0) * 1e6) as u64;
    let bits = u64::from(valid) | (lat_raw << 1) | (lon_raw << 29) | (accuracy_m << 58);
    standard(3, &bits.to_le_bytes())
}

/// A CANmod gnss_time frame for UTC `utc_us` (6 bytes, as the module sends it).
pub(super) fn canmod_time(utc_us: i64) -> CanFrame {
    let raw = ((utc_us / 1000) - 1_577_840_400_000) as u64;
    let bytes = ((raw << 8) | 1).to_le_bytes();
    standard(2, &bytes[..6])
}

/// A cone 30 m ahead of the start, on the road's edge, in the camera frame at `t_us`.
fn cone(t_us: i64) -> Detection3d {
    let ahead = 30.0 - camera_at(t_us).x;
    Detection3d::new(0, Box3d { x: ahead, y: -3.0, z: -1.3 + 0.35, yaw: 0.0, l: 0.36, w: 0.36, h: 0.7 }, 0.9)
}

/// What a log holds.
#[derive(Default)]
struct Decoded {
    counts: [u64; Kind::ALL.len()],
    damaged: u64,
    events: heapless::Vec<heapless::String<255>, 64>,
    /// The reasons of the clock offsets, the latency's slew (reason 4) left out.
    clock_reasons: heapless::Vec<i64, 16>,
    /// The latency slewed into the log's clock, µs, and in how many steps; whether every
    /// step was at most a millisecond, one way, at least 0.1 s after the one before.
    slewed_us: i64,
    slew_steps: u32,
    slew_steps_even: bool,
    last_ego: Option<EgoPose>,
    /// The VO sessions, in the order they first appear.
    sessions: heapless::Vec<i64, 8>,
    /// Horizontal error of every ego pose of session 1 before its anchor was observable (the
    /// carried ones), against [`camera_at`]'s drive, m.
    carried_error_m: heapless::Vec<f64, 128>,
}

fn decode(log: &[u8]) -> Decoded {
    let mut out = Decoded { slew_steps_even: true, ..Decoded::default() };
    let (mut offset, mut last_step) = (None::<i64>, None::<i64>);
    let mut decoder: Decoder = Decoder::default();
    let mut carrying = false;
    let mut on = |e: LogEvent| match e {
        LogEvent::Record(r) => {
            if let Some(i) = Kind::ALL.iter().position(|k| *k == r.kind()) {
                out.counts[i] += 1;
            }
            match r {
                Record::Event(e) => {
                    if e.text.starts_with(b"VO session 1 began") {
                        carrying = true;
                    }
                    if e.text.starts_with(b"ego anchored again") {
                        carrying = false;
                    }
                    let _ = out.events.push(
                        heapless::String::try_from(core::str::from_utf8(&e.text).unwrap_or("?")).unwrap_or_default(),
                    );
                }
                Record::ClockOffset(c) if c.reason == 4 => {
                    let step = c.offset_us - offset.unwrap_or(c.offset_us);
                    let apart = last_step.is_none_or(|t| c.t_us - t >= 100_000 + step);
                    let one_way = out.slewed_us == 0 || (out.slewed_us > 0) == (step > 0);
                    out.slew_steps_even &= step != 0 && step.abs() <= 1_000 && one_way && apart;
                    out.slewed_us += step;
                    out.slew_steps += 1;
                    (offset, last_step) = (Some(c.offset_us), Some(c.t_us));
                }
                Record::ClockOffset(c) => {
                    let _ = out.clock_reasons.push(c.reason);
                    offset = Some(c.offset_us);
                }
                Record::EgoPose(p) => {
                    if carrying {
                        // The rear axle at device time t: 10 t m east, 100 m north.
                        let t = (p.t_us - UTC0 + LATENCY_US - out.slewed_us) as f64 * 1e-6;
                        let error = (p.x_mm as f64 * 1e-3 - 10.0 * t).hypot(p.y_mm as f64 * 1e-3 - 100.0);
                        let _ = out.carried_error_m.push(error);
                    }
                    out.last_ego = Some(p);
                }
                Record::VoPose(p) if !out.sessions.contains(&p.session) => {
                    let _ = out.sessions.push(p.session);
                }
                _ => {}
            }
        }
        LogEvent::Damaged { .. } | LogEvent::NotALog(_) => out.damaged += 1,
        _ => {}
    };
    for chunk in log.chunks(97) {
        decoder.push(chunk, &mut on);
    }
    decoder.finish(&mut on);
    out
}

fn count(d: &Decoded, kind: Kind) -> u64 {
    Kind::ALL.iter().position(|k| *k == kind).map_or(0, |i| d.counts[i])
}

/// Drive for `seconds`, calling `tamper(t_us, pipeline)` before each 20 ms step.
fn drive(
    buffer: &mut [u8],
    seconds: i64,
    tamper: impl FnMut(i64, &mut Pipeline<'_, &mut [u8], 8, 4, 4096>),
) -> (usize, PipelineStats, Issues) {
    drive_vo(buffer, seconds, tamper, |t| Some((0, vo_pose(t))))
}

/// [`drive`] with the VO (session and pose, or none: tracking lost) of each frame time.
fn drive_vo(
    buffer: &mut [u8],
    seconds: i64,
    mut tamper: impl FnMut(i64, &mut Pipeline<'_, &mut [u8], 8, 4, 4096>),
    vo: impl Fn(i64) -> Option<(u32, Pose)>,
) -> (usize, PipelineStats, Issues) {
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let total = buffer.len();
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(buffer, config(), &mut trackers);
    let mut frame = 0;
    for step in 0..seconds * 50 {
        let t = step * 20_000;
        tamper(t, &mut p);
        let _ = p.push_can(us(t), &ccvs1(10.0));
        if step % 10 == 0 {
            let bytes = nmea(t, UTC0 + t);
            let _ = p.push_serial(us(t + LATENCY_US), bytes.as_bytes());
        }
        if step % 5 == 0 {
            frame += 1;
            if let Some((session, pose)) = vo(t) {
                let _ = p.push_vo(us(t), frame, session, &pose);
            }
            let _ = p.push_detections(us(t), frame, &[cone(t)]);
        }
    }
    let (rest, stats, issues) = p.finish().unwrap_or_else(|_| unreachable!());
    (total - rest.len(), stats, issues)
}

/// The VO of a camera turned on the car by `mount` (camera → VO = VO ← ENU · body → ENU ·
/// camera → body; the car heads east, so body = ENU).
fn vo_pose_mounted(t_us: i64, mount: &CameraMount) -> Pose {
    let to_vo = rotation_z(-1.0);
    Pose { rotation: to_vo * mount.rotation(), translation: to_vo * camera_at(t_us) * 2.0 }
}

#[test]
fn a_new_vo_session_is_anchored_on_its_own() {
    let mut buffer = [0u8; 262_144];
    // After 15 s the VO loses track for a second and starts again elsewhere: another
    // origin, heading and scale.
    let restarted = |t: i64| {
        let to_vo = rotation_z(2.2);
        Pose { rotation: to_vo, translation: to_vo * (camera_at(t) - Vector3::new(150.0, 90.0, 0.0)) * 0.3 }
    };
    let vo = |t: i64| match t {
        ..15_000_000 => Some((0, vo_pose(t))),
        15_000_000..16_000_000 => None,
        _ => Some((1, restarted(t))),
    };
    let (len, stats, issues) = drive_vo(&mut buffer, 40, |_, _| {}, vo);
    let log = decode(&buffer[..len]);
    // The lost second: ten frames without VO, their detections logged raw.
    assert_eq!(issues.get(Issue::FramesMissing), 10);
    assert_eq!(issues.get(Issue::DetectionsWithoutPose), 10);
    assert_eq!(issues.total(), 20, "{issues:?}");
    assert!(log.events.iter().any(|e| e.starts_with("VO session 1 began 1.1 s after")), "{:?}", log.events);
    // Anchored in each session: before the new one began, and again in it.
    let began = log.events.iter().position(|e| e.starts_with("VO session 1 began")).unwrap_or(usize::MAX);
    let observable: heapless::Vec<usize, 16> =
        log.events.iter().enumerate().filter(|(_, e)| e.starts_with("anchor: Observable")).map(|(k, _)| k).collect();
    assert!(observable.iter().any(|&k| k < began) && observable.iter().any(|&k| k > began), "{:?}", log.events);
    // Until then the ego was carried by the last anchored pose and the wheels.
    assert!(stats.carried_frames > 5, "{stats:?}");
    assert!(log.events.iter().any(|e| e.starts_with("ego anchored again in VO session 1, ")));
    let carried = log.carried_error_m.iter().fold(0.0f64, |m, e| m.max(*e));
    assert!(carried > 0.0 && carried < 0.5, "carried ego off by {carried} m");
    // Without the new session the old similarity would put the car hundreds of metres off.
    let ego = log.last_ego.unwrap_or_default();
    assert!((ego.x_mm as f64 * 1e-3 - 399.0).abs() < 2.1 && (ego.y_mm - 100_000).abs() < 500, "{ego:?}");
    assert!(stats.anchored_frames > 250, "{stats:?}");
    assert_eq!(log.sessions, [0, 1], "the VO poses carry their session");

    // A session number going back is taken as a new session, and said.
    let back =
        |t: i64| Some((if t < 15_000_000 { 3 } else { 1 }, if t < 15_000_000 { vo_pose(t) } else { restarted(t) }));
    let (len, _, issues) = drive_vo(&mut buffer, 30, |_, _| {}, back);
    assert_eq!(issues.get(Issue::VoSessionBackwards), 1);
    let log = decode(&buffer[..len]);
    let ego = log.last_ego.unwrap_or_default();
    assert!((ego.x_mm as f64 * 1e-3 - 299.0).abs() < 2.1, "{ego:?}");
}

#[test]
fn the_camera_mount_is_calibrated_online_and_detections_placed_through_it() {
    let truth = CameraMount { roll_pitch_yaw: [0.0, -0.035, 0.045], ..CameraMount::default() };
    // The cone as the turned camera sees it.
    let seen = |t: i64| {
        let d = cone(t);
        let b = &d.bbox;
        let body = CameraMount::default().rotation() * Vector3::new(b.x, b.y, b.z);
        let camera = truth.rotation().transpose() * body;
        Detection3d { bbox: Box3d { x: camera.x, y: camera.y, z: camera.z, ..*b }, ..d }
    };
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let mut buffer = [0u8; 262_144];
    let total = buffer.len();
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(&mut buffer[..], config(), &mut trackers);
    for step in 0..20 * 50 {
        let t = step * 20_000;
        let _ = p.push_can(us(t), &ccvs1(10.0));
        if step % 10 == 0 {
            let _ = p.push_serial(us(t + LATENCY_US), nmea(t, UTC0 + t).as_bytes());
        }
        if step % 5 == 0 {
            let frame = step as u64 / 5 + 1;
            let _ = p.push_vo(us(t), frame, 0, &vo_pose_mounted(t, &truth));
            let _ = p.push_detections(us(t), frame, &[seen(t)]);
        }
    }
    let m = *p.mount();
    let [_, pitch, yaw] = m.mount.roll_pitch_yaw;
    assert!(m.calibrated && (pitch + 0.035).abs() < 1e-4 && (yaw - 0.045).abs() < 1e-4, "{m:?}");
    // The cone 30 m ahead is 1 m off the ground through the nominal pitch: refused. Through
    // the calibrated one it is tracked.
    assert_eq!(p.issues().get(Issue::DetectionsRefused), 0, "{:?}", p.issues());
    let (rest, stats, _) = p.finish().unwrap_or_else(|_| unreachable!());
    let len = total - rest.len();
    assert!(stats.track_states > 100, "{stats:?}");
    let log = decode(&buffer[..len]);
    assert!(count(&log, Kind::MountEstimate) >= 10, "written about once a second");
    assert!(log.events.iter().any(|e| e.starts_with("camera mount calibrated from")), "{:?}", log.events);
}

#[test]
fn a_clean_drive_is_anchored_tracked_and_timed_in_utc() {
    let mut buffer = [0u8; 65_536];
    let (len, stats, issues) = drive(&mut buffer, 20, |_, _| {});
    let log = decode(&buffer[..len]);
    assert_eq!(log.damaged, 0);
    assert_eq!(issues.total(), 0, "{issues:?} {:?} {:?}", log.events, nmea(0, UTC0));
    assert!(stats.anchored_frames > 150, "{stats:?}");
    assert_eq!(count(&log, Kind::EgoPose), stats.anchored_frames);
    assert_eq!(count(&log, Kind::VoPose), 200);
    assert_eq!(count(&log, Kind::GnssFix), 100);
    assert_eq!(count(&log, Kind::VehicleSpeed), 1000);
    assert!(count(&log, Kind::Tracks3d) > 100);
    assert!(count(&log, Kind::Detection3d) > 0, "detections before the anchor are logged raw");
    assert_eq!(log.clock_reasons.first(), Some(&0));
    // The last ego pose: the rear axle at 10 m/s × 19.9 s, heading east, in UTC. At a
    // constant speed the receiver's latency is unobservable (docs/anchoring.md): the anchor
    // may sit along the road by up to v × the largest latency hypothesis (0.2 s).
    let ego = log.last_ego.unwrap_or_default();
    assert!((ego.x_mm as f64 * 1e-3 - 199.0).abs() < 2.1, "{ego:?}");
    assert!((ego.y_mm - 100_000).abs() < 500 && ego.yaw_e4.abs() < 100, "{ego:?}");
    // Its UTC: the fixes' arrivals, early by the receiver's latency, which the drive does
    // not show — so none is slewed in.
    assert_eq!(log.slew_steps, 0);
    assert!((ego.t_us - (UTC0 + 19_900_000 - LATENCY_US)).abs() < 1_000, "{ego:?}");
}

#[test]
fn a_latency_the_drive_shows_is_slewed_into_the_logs_utc() {
    // The car's speed swings between 3.7 and 16.3 m/s every 8 s: where the fixes lag the
    // VO shows.
    let omega = core::f64::consts::TAU / 8.0;
    let x = |t_us: i64| {
        let t = t_us as f64 * 1e-6;
        10.0 * t + 8.0 * (1.0 - libm::cos(omega * t)) + 1.8
    };
    let camera = |t_us: i64| Vector3::new(x(t_us), 100.0, 1.3);
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let mut buffer = [0u8; 262_144];
    let total = buffer.len();
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(&mut buffer[..], config(), &mut trackers);
    for step in 0..40 * 50 {
        let t = step * 20_000;
        let speed = 10.0 + 8.0 * omega * libm::sin(omega * t as f64 * 1e-6);
        let _ = p.push_can(us(t), &ccvs1(speed));
        if step % 10 == 0 {
            let _ = p.push_serial(us(t + LATENCY_US), nmea_fix(&camera(t), 90.0, UTC0 + t).as_bytes());
        }
        if step % 5 == 0 {
            let to_vo = rotation_z(-1.0);
            let pose = Pose { rotation: to_vo, translation: to_vo * camera(t) * 2.0 };
            let _ = p.push_vo(us(t), step as u64 / 5 + 1, 0, &pose);
        }
    }
    let (rest, _, _) = p.finish().unwrap_or_else(|_| unreachable!());
    let len = total - rest.len();
    let log = decode(&buffer[..len]);
    assert!(log.events.iter().any(|e| e.starts_with("GNSS receiver latency 0.0")), "{:?}", log.events);
    // The 80 ms slewed in a millisecond per 0.1 s, without going back and forth.
    assert!((log.slewed_us - LATENCY_US).abs() <= 10_000 && log.slew_steps_even, "{} µs", log.slewed_us);
    assert!(i64::from(log.slew_steps) <= log.slewed_us / 1_000 + 1, "{} steps", log.slew_steps);
    // The last pose, at device time 39.9 s, stamped in the world's UTC.
    let ego = log.last_ego.unwrap_or_default();
    assert!((ego.t_us - (UTC0 + 39_900_000)).abs() <= 10_000, "{ego:?}");
}

#[test]
fn bad_inputs_are_counted_written_as_events_and_lose_nothing_else() {
    let mut buffer = [0u8; 262_144];
    let nan = Pose { rotation: Matrix3::identity(), translation: Vector3::new(f64::NAN, 0.0, 0.0) };
    let (len, stats, issues) = drive(&mut buffer, 20, |t, p| {
        match t {
            // Detections before the first VO pose.
            0 => {
                let _ = p.push_detections(us(0), 0, &[cone(0)]);
            }
            // NaN VO, and a VO pose out of order.
            2_000_000 => {
                let _ = p.push_vo(us(t + 1), 1_000, 0, &nan);
                let _ = p.push_vo(us(t - 500_000), 1, 0, &vo_pose(t));
            }
            // 10 000 CAN frames in one burst: bad fast packets of PGN 129029.
            4_000_000 => {
                let id = Id::Extended(ExtendedId::new(0x09F8_0501).unwrap_or(ExtendedId::ZERO));
                let junk = CanFrame::data_frame(id, &[0x21, 1, 2, 3, 4, 5, 6, 7]).unwrap_or_else(|| unreachable!());
                for _ in 0..10_000 {
                    let _ = p.push_can(us(t), &junk);
                }
            }
            // A GNSS time stepped back by a second, for good.
            6_000_000 => {
                for k in 0..5 {
                    let tk = t + 200_000 * k;
                    let _ = p.push_serial(us(tk + LATENCY_US + 10_000), nmea(tk, UTC0 + tk - 1_000_000).as_bytes());
                }
            }
            // A sentence with a bad checksum, binary garbage.
            8_000_000 => {
                let _ = p.push_serial(us(t), b"$GPGGA,1,2,3*00\r\n\x00\xff\xfe garbage\r\n");
            }
            _ => {}
        }
    });
    let log = decode(&buffer[..len]);
    assert_eq!(log.damaged, 0, "the log always decodes");
    assert!(issues.get(Issue::DetectionsWithoutPose) >= 1);
    assert_eq!(issues.get(Issue::VoNotFinite), 1);
    assert_eq!(issues.get(Issue::VoOutOfOrder), 1);
    assert!(issues.get(Issue::CanBadFrame) >= 10_000, "{issues:?}");
    assert!(issues.get(Issue::NmeaBadSentence) + issues.get(Issue::NmeaDropped) >= 1);
    assert!(log.clock_reasons.contains(&2), "the lasting step is followed: {:?}", log.clock_reasons);
    assert!(issues.get(Issue::GnssTimeIgnored) >= 2);
    // Every reason is in the log as an event; the burst did not flood it.
    for issue in [Issue::DetectionsWithoutPose, Issue::VoNotFinite, Issue::CanBadFrame, Issue::GnssTimeIgnored] {
        assert!(log.events.iter().any(|e| e.starts_with(issue.text())), "{issue:?}: {:?}", log.events);
    }
    assert!(log.events.len() < 60, "{} events", log.events.len());
    // Everything good still went in.
    assert_eq!(count(&log, Kind::VoPose), 200);
    assert!(stats.anchored_frames > 150, "{stats:?}");
}

#[test]
fn a_device_clock_reset_keeps_the_log_going_in_utc() {
    let mut buffer = [0u8; 131_072];
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(&mut buffer[..], config(), &mut trackers);
    // 10 s, then the device clock restarts at 0 while the car drives on (2 s lost).
    let reset_at = 10_000_000;
    let lost = 2_000_000;
    let mut frame = 0;
    for step in 0..20 * 50 {
        let t = step * 20_000;
        let device = if t < reset_at { t } else { t - reset_at - lost + 1 };
        if t >= reset_at && t < reset_at + lost {
            continue;
        }
        let _ = p.push_can(us(device), &ccvs1(10.0));
        if step % 10 == 0 {
            let _ = p.push_serial(us(device + LATENCY_US), nmea(t, UTC0 + t).as_bytes());
        }
        if step % 5 == 0 {
            frame += 1;
            let _ = p.push_vo(us(device), frame, 0, &vo_pose(t));
        }
    }
    assert_eq!(p.issues().get(Issue::ClockReset), 1);
    let (rest, stats, _) = p.finish().unwrap_or_else(|_| unreachable!());
    let len = 131_072 - rest.len();
    let log = decode(&buffer[..len]);
    assert_eq!(log.damaged, 0);
    assert!(log.clock_reasons.contains(&3), "UTC taken again after the reset: {:?}", log.clock_reasons);
    let ego = log.last_ego.unwrap_or_default();
    let utc = UTC0 + 19_900_000 - LATENCY_US + log.slewed_us;
    assert!((ego.t_us - utc).abs() < 1_000, "the last pose in UTC: {ego:?}");
    assert!(stats.anchored_frames > 130, "{stats:?}");
}

/// One input of any kind, with any time and content.
#[derive(Clone, Debug)]
enum AnyInput {
    Serial(i64, std::vec::Vec<u8>),
    Can(i64, u32, std::vec::Vec<u8>),
    Vo(i64, u64, [f64; 3], f64),
    Detections(i64, u64, std::vec::Vec<[f64; 8]>),
}

extern crate std;

fn any_input() -> impl Strategy<Value = AnyInput> {
    let t = -2_000_000i64..60_000_000;
    let value = prop_oneof![-1e3f64..1e3, Just(f64::NAN), Just(f64::INFINITY), Just(1e300)];
    prop_oneof![
        (t.clone(), prop::collection::vec(any::<u8>(), 0..200)).prop_map(|(t, b)| AnyInput::Serial(t, b)),
        (t.clone(), any::<u32>(), prop::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(t, id, d)| AnyInput::Can(t, id, d)),
        (t.clone(), 0u64..50, prop::array::uniform3(value.clone()), value.clone())
            .prop_map(|(t, f, p, yaw)| AnyInput::Vo(t, f, p, yaw)),
        (t, 0u64..50, prop::collection::vec(prop::array::uniform8(value), 0..12))
            .prop_map(|(t, f, d)| AnyInput::Detections(t, f, d)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn any_interleaving_of_any_inputs_never_panics_and_always_decodes(
        inputs in prop::collection::vec(any_input(), 0..300),
    ) {
        let mut buffer = std::vec![0u8; 1 << 20];
        let classes = cone_class();
        let mut trackers = trackers(&classes);
        let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> =
            Pipeline::new(&mut buffer[..], config(), &mut trackers);
        for input in &inputs {
            let _ = match input {
                AnyInput::Serial(t, b) => p.push_serial(us(*t), b),
                AnyInput::Can(t, id, d) => {
                    let id = crate::can::frame::id_from_raw(id & 0x1FFF_FFFF, id & 0x8000_0000 != 0);
                    match id.and_then(|id| CanFrame::data_frame(id, d)) {
                        Some(f) => p.push_can(us(*t), &f),
                        None => Ok(()),
                    }
                }
                AnyInput::Vo(t, f, [x, y, z], yaw) => {
                    let pose = Pose { rotation: rotation_z(*yaw), translation: Vector3::new(*x, *y, *z) };
                    p.push_vo(us(*t), *f, 0, &pose)
                }
                AnyInput::Detections(t, f, boxes) => {
                    let dets: std::vec::Vec<Detection3d> = boxes
                        .iter()
                        .map(|b| Detection3d {
                            position_covariance: Some([b[7].abs(), 0.0, b[7].abs()]),
                            ..Detection3d::new(0, Box3d { x: b[0], y: b[1], z: b[2], yaw: b[3], l: b[4], w: b[5], h: b[6] }, 0.5)
                        })
                        .collect();
                    p.push_detections(us(*t), *f, &dets)
                }
            };
        }
        let (rest, _, _) = p.finish().unwrap_or_else(|_| unreachable!());
        let len = (1 << 20) - rest.len();
        let log = decode(&buffer[..len]);
        prop_assert_eq!(log.damaged, 0);
    }
}

#[test]
fn a_camera_restart_and_skipped_frames_are_events_and_tracking_goes_on_across_a_rotation() {
    let mut first = [0u8; 131_072];
    let mut second = [0u8; 131_072];
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(&mut first[..], config(), &mut trackers);
    let mut frame = 0;
    let mut second_sink = Some(&mut second[..]);
    let mut tracks_before = 0;
    let mut first_len = 0;
    for step in 0..20 * 50 {
        let t = step * 20_000;
        let _ = p.push_can(us(t), &ccvs1(10.0));
        if step % 10 == 0 {
            let _ = p.push_serial(us(t + LATENCY_US), nmea(t, UTC0 + t).as_bytes());
        }
        if step % 5 == 0 {
            frame += 1;
            if t == 8_000_000 {
                frame += 3; // three frames lost
            }
            if t == 10_000_000 {
                frame = 1; // the camera process restarted
                tracks_before = p.stats().track_states;
            }
            let _ = p.push_vo(us(t), frame, 0, &vo_pose(t));
            let _ = p.push_detections(us(t), frame, &[cone(t)]);
        }
        if t == 12_000_000 {
            if let Some(sink) = second_sink.take() {
                let old = p.rotate(sink).unwrap_or_else(|_| unreachable!());
                first_len = 131_072 - old.len();
            }
        }
    }
    assert_eq!(p.issues().get(Issue::CameraRestarted), 1);
    assert_eq!(p.issues().get(Issue::FramesMissing), 3);
    assert!(p.stats().track_states > tracks_before + 20, "tracking went on after the restart");
    let (rest, _, _) = p.finish().unwrap_or_else(|_| unreachable!());
    let len = 131_072 - rest.len();
    let later = decode(&second[..len]);
    let earlier = decode(&first[..first_len]);
    assert_eq!((earlier.damaged, later.damaged), (0, 0));
    assert!(earlier.events.iter().any(|e| e.starts_with(Issue::CameraRestarted.text())), "{:?}", earlier.events);
    assert_eq!(later.clock_reasons.first(), Some(&1), "the new file starts with the clock offset");
    assert!(later.events.iter().any(|e| e.starts_with("log continued on a new file (rotation 1)")));
    assert!(count(&later, Kind::EgoPose) > 60 && count(&later, Kind::Tracks3d) > 0);
}

#[test]
fn frame_numbers_at_the_end_of_the_range_are_taken_without_a_panic() {
    // Found by the `pipeline_inputs` fuzz target: the largest frame number, then a restart
    // whose frame offset saturates, left the new frame equal to the last one.
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let mut buffer = [0u8; 65_536];
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(&mut buffer[..], config(), &mut trackers);
    for (k, frame) in [u64::MAX - 1, u64::MAX, 0, 1, u64::MAX].into_iter().enumerate() {
        let t = 100_000 * k as i64;
        assert!(p.push_vo(us(t), frame, 0, &vo_pose(t)).is_ok(), "frame {frame}");
    }
    assert_eq!(p.stats().vo_poses, 5);
    assert!(p.issues().get(Issue::CameraRestarted) >= 1);
}

#[test]
fn gnss_from_dbc_signals_anchors_the_drive_and_puts_the_log_in_utc() {
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let mut buffer = [0u8; 65_536];
    let total = buffer.len();
    let config = PipelineConfig { gnss_signals: GnssSignals::canmod_gps(), ..config() };
    let frame = LocalFrame::new(Geodetic::new(ORIGIN_LAT, ORIGIN_LON, 0.0).unwrap_or_else(|_| unreachable!()));
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(&mut buffer[..], config, &mut trackers);
    for step in 0..20 * 50 {
        let t = step * 20_000;
        let _ = p.push_can(us(t), &ccvs1(10.0));
        if step % 10 == 0 {
            // The epoch's burst: time, then position 0.5 ms later. No fix in the first
            // second; at 4 s no time frame, at 6 s one that came 0.6 s early (not this
            // fix's: taken, it would move the clock by 0.6 s).
            let g = frame.enu_to_geodetic(&camera_at(t)).unwrap_or_else(|_| unreachable!());
            let rx = t + LATENCY_US;
            match t {
                4_000_000 => {}
                6_000_000 => {
                    let _ = p.push_can(us(rx - 600_000), &canmod_time(UTC0 + t));
                }
                _ => {
                    let _ = p.push_can(us(rx), &canmod_time(UTC0 + t));
                }
            }
            let _ = p.push_can(us(rx + 500), &canmod_position(g.lat_deg, g.lon_deg, t >= 1_000_000, 2));
        }
        if step % 5 == 0 {
            let _ = p.push_vo(us(t), step as u64 / 5 + 1, 0, &vo_pose(t));
        }
    }
    let _ = p.push_can(us(20_000_000), &standard(3, &[0; 4]));
    let (rest, stats, issues) = p.finish().unwrap_or_else(|_| unreachable!());
    let len = total - rest.len();
    let log = decode(&buffer[..len]);
    assert_eq!(issues.get(Issue::GnssNoPosition), 5, "the first second has no fix: {issues:?}");
    assert_eq!(issues.get(Issue::CanBadFrame), 1, "the short position frame");
    assert_eq!(count(&log, Kind::GnssFix), 95);
    assert_eq!(stats.fixes, 95);
    assert_eq!(log.clock_reasons.as_slice(), &[0], "UTC from the time frames, and only from this fix's");
    assert_eq!(issues.get(Issue::GnssTimeIgnored), 0);
    assert!(stats.anchored_frames > 150, "{stats:?}");
    let ego = log.last_ego.unwrap_or_default();
    assert!((ego.x_mm as f64 * 1e-3 - 199.0).abs() < 2.1, "{ego:?}");
    assert!((ego.t_us - (UTC0 + 19_900_000 - LATENCY_US)).abs() < 1_000, "{ego:?}");
}

#[test]
fn the_anchor_record_carries_the_estimated_gnss_latency() {
    let anchorer: Anchorer = Anchorer::new(AnchorConfig::default());
    let quality = |latency_s| crate::anchor::Quality { latency_s, ..*anchorer.quality() };
    let estimate = Sim3::identity();
    assert_eq!(anchor_record(5, &estimate, &quality(Some(0.0625))).latency_us, 62_500);
    // Not estimated yet: written as 0, which costs nothing in the payload.
    assert_eq!(anchor_record(5, &estimate, &quality(None)).latency_us, 0);
}

/// The straight drive with an IMU at 100 Hz on the camera's (levelled) axes reading `accel`
/// and a biased gyro, VO pushed too; the relative motion as `motion`.
fn drive_imu(
    buffer: &mut [u8],
    motion: RelativeMotion,
    accel: [f64; 3],
) -> (usize, PipelineStats, Issues, Vector3<f64>) {
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let total = buffer.len();
    let config = PipelineConfig { relative_motion: motion, ..config() };
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(buffer, config, &mut trackers);
    let gyro = [0.004, -0.003, 0.02];
    let mut frame = 0;
    for step in 0..30 * 100 {
        let t = step * 10_000;
        let _ = p.push_imu(us(t), &crate::imu::ImuSample { gyro, accel });
        if step % 2 == 0 {
            let _ = p.push_can(us(t), &ccvs1(10.0));
        }
        if step % 20 == 0 {
            let _ = p.push_serial(us(t + LATENCY_US), nmea(t, UTC0 + t).as_bytes());
        }
        if step % 10 == 0 {
            frame += 1;
            let _ = p.push_vo(us(t), frame, 0, &vo_pose(t));
        }
    }
    let (bias, _) = p.gyro_bias();
    let (rest, stats, issues) = p.finish().unwrap_or_else(|_| unreachable!());
    (total - rest.len(), stats, issues, bias)
}

#[test]
fn gyro_and_wheels_are_anchored_on_a_straight_road_where_the_camera_gives_no_vo() {
    let mut buffer = [0u8; 400_000];
    let (used, stats, issues, bias) = drive_imu(&mut buffer, RelativeMotion::ImuWheels, [0.0, 0.0, 9.81]);
    let log = decode(&buffer[..used]);
    assert!(stats.anchored_frames > 300, "{stats:?}");
    assert_eq!(issues.get(Issue::VoNotUsed), 300, "every VO pose is counted as not used");
    assert_eq!(stats.imu_samples, 3000);
    // The rear axle at the end: 10 m/s east for 30 s along y = 100 m.
    let ego = log.last_ego.unwrap_or_default();
    let (x, y) = (ego.x_mm as f64 * 1e-3, ego.y_mm as f64 * 1e-3);
    assert!((x - 299.9).abs() < 1.0 && (y - 100.0).abs() < 1.0, "{x} {y}");
    // The vertical bias from the course, the horizontal ones from gravity.
    assert!((bias - Vector3::new(0.004, -0.003, 0.02)).norm() < 2e-3, "{bias:?}");
    // 3000 samples span 29.99 s: 299 whole intervals of 0.1 s.
    assert_eq!(count(&log, Kind::ImuDelta), 299, "one preintegrated interval per 0.1 s");
    assert!(count(&log, Kind::ImuEstimate) >= 28);
}

#[test]
fn an_imu_in_g_is_refused_with_an_error_event_and_nothing_else_is_lost() {
    let mut buffer = [0u8; 400_000];
    let (used, stats, issues, _) = drive_imu(&mut buffer, RelativeMotion::Vo, [0.0, 0.0, 1.0]);
    let log = decode(&buffer[..used]);
    // The first second decides; every sample after it is refused and counted.
    assert_eq!(issues.get(Issue::ImuUnits), 2900, "{issues:?}");
    assert!(log.events.iter().any(|e| e.contains("given in g")), "{:?}", log.events);
    assert!(stats.anchored_frames > 100, "the VO drive goes on: {stats:?}");
}

/// A car that starts turning left (0.1 rad/s) at 16 s, inside a 2 s VO gap (15.5–17.5 s),
/// with a gyro (`imu`) or without: the ego's heading error (rad) at its poses from the gap's
/// end to 20 s, the largest, and how many poses there were.
fn turn_in_a_vo_gap(imu: bool) -> (f64, usize) {
    const OMEGA: f64 = 0.1;
    const TURN_AT: f64 = 16.0;
    let heading = |t: f64| OMEGA * (t - TURN_AT).max(0.0);
    let rear = |t: f64| {
        if t < TURN_AT {
            Vector3::new(10.0 * t, 100.0, 0.0)
        } else {
            let a = OMEGA * (t - TURN_AT);
            Vector3::new(10.0 * TURN_AT + 10.0 / OMEGA * libm::sin(a), 100.0 + 10.0 / OMEGA * (1.0 - libm::cos(a)), 0.0)
        }
    };
    let camera = |t: f64| rear(t) + rotation_z(heading(t)) * Vector3::new(1.8, 0.0, 1.3);
    let vo = |t: f64| -> Option<(u32, Pose)> {
        let world = Pose { rotation: rotation_z(heading(t)), translation: camera(t) };
        if t < 15.5 {
            let to_vo = rotation_z(-1.0);
            Some((0, Pose { rotation: to_vo * world.rotation, translation: to_vo * world.translation * 2.0 }))
        } else if t < 17.5 {
            None
        } else {
            let to_vo = rotation_z(2.2);
            let offset = Vector3::new(150.0, 90.0, 0.0);
            Some((
                1,
                Pose { rotation: to_vo * world.rotation, translation: to_vo * (world.translation - offset) * 0.3 },
            ))
        }
    };
    let mut buffer = [0u8; 400_000];
    let classes = cone_class();
    let mut trackers = trackers(&classes);
    let total = buffer.len();
    let mut p: Pipeline<'_, &mut [u8], 8, 4, 4096> = Pipeline::new(&mut buffer[..], config(), &mut trackers);
    let mut frame = 0;
    for step in 0..22 * 100 {
        let t_us = step * 10_000;
        let t = t_us as f64 * 1e-6;
        if imu {
            // Body axes: the turn about z (and a small bias), the centripetal force to the left.
            let rate = if t >= TURN_AT { OMEGA } else { 0.0 };
            let sample = crate::imu::ImuSample { gyro: [0.0, 0.0, rate + 0.002], accel: [0.0, 10.0 * rate, 9.81] };
            let _ = p.push_imu(us(t_us), &sample);
        }
        if step % 2 == 0 {
            let _ = p.push_can(us(t_us), &ccvs1(10.0));
        }
        if step % 20 == 0 {
            let course = 90.0 - heading(t).to_degrees();
            let _ = p.push_serial(us(t_us + LATENCY_US), nmea_fix(&camera(t), course, UTC0 + t_us).as_bytes());
        }
        if step % 10 == 0 {
            frame += 1;
            if let Some((session, pose)) = vo(t) {
                let _ = p.push_vo(us(t_us), frame, session, &pose);
            }
        }
    }
    let (rest, _, _) = p.finish().unwrap_or_else(|_| unreachable!());
    let used = total - rest.len();
    let (mut worst, mut poses) = (0.0f64, 0);
    let mut decoder: Decoder = Decoder::default();
    let mut on = |e: LogEvent| {
        if let LogEvent::Record(Record::EgoPose(pose)) = e {
            let t = (pose.t_us - UTC0 + LATENCY_US) as f64 * 1e-6;
            if (17.5..20.0).contains(&t) {
                worst = worst.max(libm::fabs(wrap_angle(pose.yaw_e4 as f64 * 1e-4 - heading(t))));
                poses += 1;
            }
        }
    };
    decoder.push(&buffer[..used], &mut on);
    decoder.finish(&mut on);
    (worst, poses)
}

#[test]
fn the_gyro_carries_the_heading_across_a_vo_gap() {
    // The car began to turn in the gap: the turn rate before it says nothing of that, the
    // gyro measured it.
    let (with_gyro, poses) = turn_in_a_vo_gap(true);
    let (without, poses_without) = turn_in_a_vo_gap(false);
    // The ego has a pose at nearly every frame from the gap's end on (22 of 25 in 2.5 s: the
    // carry waits for 2 m of wheels to scale the new session), carried, then anchored in it.
    assert!(poses >= 20 && poses_without >= 20, "{poses} {poses_without}");
    assert!(with_gyro < 0.5f64.to_radians(), "heading off by {}° with the gyro", with_gyro.to_degrees());
    assert!(without > 3f64.to_radians(), "heading off by {}° without", without.to_degrees());
}
