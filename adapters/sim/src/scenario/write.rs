//! Writing a generated scenario to a folder, in the formats the rest of the tool reads:
//! TUM trajectories, NMEA 0183, CSV, MOTChallenge text files and an OpenStreetMap file of
//! the road. `docs/scenario.md` lists every file and column.

use dash2sim_linux::ingest::objects::ObjectRow;
use std::fmt::Write as _;
use std::fs;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::sim3::Pose;
use serde_json::json;

use super::actors::Class;
use super::road::Segment;
use super::Scenario;
use crate::{Error, Result};
use dash2sim_linux::trajectory::{write_file, Format, Trajectory};

/// UTC time of day of the first frame, seconds (08:00:00); the date is 2026-06-01.
const START_SECONDS_OF_DAY: f64 = 8.0 * 3600.0;
/// The scenario clock's zero as Unix time, s (2026-06-01T08:00:00Z): NMEA fixes carry
/// UTC, every other file the scenario clock.
pub const START_UNIX_S: f64 = 1_780_300_800.0;

/// How `dash2sim import` reads a scenario written to `dir` into a 4D log at `output`:
/// GNSS from the NMEA capture (moved onto the scenario clock), ego truth, objects.
pub fn import_request(
    scenario: &Scenario,
    dir: &Path,
    output: PathBuf,
) -> Result<dash2sim_linux::log::import::ImportRequest> {
    Ok(dash2sim_linux::log::import::ImportRequest {
        output,
        nmea: Some(dir.join("gnss.nmea")),
        nmea_offset_s: -START_UNIX_S,
        speed_unit: dash2sim_linux::ingest::can::SpeedUnit::MetresPerSecond,
        traj: Some(dir.join("ego.tum")),
        objects: Some(dir.join("objects.csv")),
        origin: Some(origin(scenario).map_err(Error::other)?),
        ..Default::default()
    })
}

fn create(dir: &Path, name: &str, written: &mut Vec<PathBuf>) -> io::Result<BufWriter<fs::File>> {
    let path = dir.join(name);
    let file = fs::File::create(&path).map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))?;
    written.push(path);
    Ok(BufWriter::new(file))
}

/// Write every stream of `scenario` into `dir` (created if missing); returns the files written.
pub fn write_scenario(scenario: &Scenario, dir: &Path) -> io::Result<Vec<PathBuf>> {
    fs::create_dir_all(dir)?;
    let mut written = Vec::new();
    let frame = LocalFrame::new(origin(scenario)?);

    for (name, traj) in [("ego.tum", scenario.ego_trajectory()), ("vo.tum", scenario.vo.poses.clone())] {
        let path = dir.join(name);
        write_file(&traj, &path, Format::Tum)?;
        written.push(path);
    }
    let mut gnss = Trajectory::default();
    for fix in &scenario.gnss {
        gnss.stamps.push(fix.t_receive);
        gnss.poses.push(Pose { translation: Vector3::from(fix.enu), ..Pose::identity() });
    }
    let path = dir.join("gnss.tum");
    write_file(&gnss, &path, Format::Tum)?;
    written.push(path);

    // The VO as the camera process reports it: each pose with its frame number (none while
    // tracking is lost) and its VO session.
    let mut out = create(dir, "vo.csv", &mut written)?;
    write_vo_csv(&mut out, &scenario.vo)?;
    out.flush()?;

    let mut out = create(dir, "gnss.nmea", &mut written)?;
    let mut serial = create(dir, "gnss.serial.log", &mut written)?;
    for (t_receive, sentences) in receiver_output(scenario, 0.0)? {
        writeln!(out, "{}\r\n{}\r", sentences[0], sentences[1])?;
        for sentence in &sentences {
            writeln!(serial, "({t_receive:.6}) {sentence}")?;
        }
    }
    out.flush()?;
    serial.flush()?;

    let mut out = create(dir, "speed.csv", &mut written)?;
    writeln!(out, "t_s,speed_mps")?;
    for (t, v) in &scenario.speed {
        writeln!(out, "{t:.3},{v:.5}")?;
    }
    out.flush()?;

    let mut out = create(dir, "speed.can.log", &mut written)?;
    for (t, frame) in wheel_speed_frames(scenario)? {
        let time = dash2sim_core::time::Timestamp::from_micros((t * 1e6).round() as i64);
        dash2sim_can::candump::write_log_line(&mut out, time, "can0", &frame)?;
    }
    out.flush()?;

    let mut out = create(dir, "imu.csv", &mut written)?;
    super::imu::write_csv(&mut out, &scenario.imu)?;
    out.flush()?;

    let mut out = create(dir, "objects.csv", &mut written)?;
    writeln!(out, "{}", dash2sim_linux::ingest::objects::HEADER)?;
    for f in &scenario.frames {
        for o in &f.objects {
            let visible = f.visible.contains(&o.id);
            let v = [o.velocity[0], o.velocity[1]];
            let row = ObjectRow::from_box(f.ego.t, o.id, o.class.name(), &o.bbox, v, o.is_static());
            let text = dash2sim_linux::ingest::objects::line(u64::from(f.index), &row, visible);
            out.write_all(text.as_bytes())?;
        }
    }
    out.flush()?;

    let mut out = create(dir, "detections3d.csv", &mut written)?;
    writeln!(out, "{}", dash2sim_linux::ingest::detections::HEADER)?;
    let camera = &scenario.config.camera;
    for f in &scenario.frames {
        for d in &f.detections_3d {
            // Detections are generated in the ego frame; the camera reports them in its own.
            let b = dash2sim_core::box3d::Box3d {
                x: d.bbox.x - camera.mount_forward,
                z: d.bbox.z - camera.mount_height,
                ..d.bbox
            };
            let class = Class::from_id(d.class).map_or("unknown", Class::name);
            out.write_all(
                dash2sim_linux::ingest::detections::line(
                    u64::from(f.index),
                    f.ego.t,
                    class,
                    &b,
                    d.score,
                    d.position_covariance,
                )
                .as_bytes(),
            )?;
        }
    }
    out.flush()?;

    let mut out = create(dir, "gt2d.txt", &mut written)?;
    for f in &scenario.frames {
        for o in &f.objects_2d {
            let b = &o.bbox;
            let class = o.class as u16 + 1;
            writeln!(
                out,
                "{},{},{:.2},{:.2},{:.2},{:.2},1,{class},{:.3}",
                f.index, o.id, b.x, b.y, b.w, b.h, o.visibility
            )?;
        }
    }
    out.flush()?;
    let mut out = create(dir, "det2d.txt", &mut written)?;
    for f in &scenario.frames {
        for d in &f.detections_2d {
            let b = &d.bbox;
            writeln!(out, "{},-1,{:.2},{:.2},{:.2},{:.2},{:.3},-1,-1,-1", f.index, b.x, b.y, b.w, b.h, d.score)?;
        }
    }
    out.flush()?;

    let mut out = create(dir, "road.osm", &mut written)?;
    out.write_all(road_osm(scenario, &frame)?.as_bytes())?;
    out.flush()?;

    let mut out = create(dir, "scenario.json", &mut written)?;
    serde_json::to_writer_pretty(&mut out, &summary(scenario, &written))?;
    writeln!(out)?;
    out.flush()?;
    Ok(written)
}

/// A VO track as `record --vo F.csv` reads it (`frame,t_s,x,y,z,qx,qy,qz,qw,session`,
/// frames from 1).
pub fn write_vo_csv(out: &mut impl Write, vo: &super::vo::VoTrack) -> io::Result<()> {
    writeln!(out, "{}", dash2sim_linux::record::sources::VO_CSV_HEADER)?;
    for ((t, pose), sample) in vo.poses.stamps.iter().zip(&vo.poses.poses).zip(&vo.samples) {
        let q = dash2sim_core::nalgebra::UnitQuaternion::from_matrix(&pose.rotation);
        let p = pose.translation;
        writeln!(
            out,
            "{},{t:.6},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{}",
            sample.frame + 1,
            p.x,
            p.y,
            p.z,
            q.i,
            q.j,
            q.k,
            q.w,
            sample.session
        )?;
    }
    Ok(())
}

/// The map tile of a drive written to `dir`: its `road.osm` in the ENU frame at `origin`,
/// with the default grid cell (what `map build` makes of it).
pub fn road_tile(dir: &Path, origin: Geodetic) -> Result<Vec<u8>> {
    let osm = dash2sim_linux::ingest::osm::read(&dir.join("road.osm")).map_err(Error::other)?;
    let content = dash2sim_linux::ingest::map_tile::from_osm(&osm, Some(origin), &mut Vec::new());
    Ok(dash2sim_linux::ingest::map_tile::encode(&content, dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M))
}

/// What the GNSS receiver sends: per fix its receive time (s) and its GGA and RMC sentences,
/// the receiver's clock `shift_s` later than the drive's (a drive replayed again).
pub fn receiver_output(scenario: &Scenario, shift_s: f64) -> io::Result<Vec<(f64, [String; 2])>> {
    let frame = LocalFrame::new(origin(scenario)?);
    scenario
        .gnss
        .iter()
        .map(|fix| {
            let position = frame
                .enu_to_geodetic(&Vector3::from(fix.enu))
                .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, format!("fix at {}: {e}", fix.t_fix)))?;
            let time = hhmmss(START_SECONDS_OF_DAY + shift_s + fix.t_fix);
            let (lat, ns) = nmea_angle(position.lat_deg, 2, ['N', 'S']);
            let (lon, ew) = nmea_angle(position.lon_deg, 3, ['E', 'W']);
            // The receiver reports its σ, as it judges it, as HDOP × 2.5 m (the pipeline's
            // default UERE).
            let hdop = fix.reported_sigma / 2.5;
            let gga = format!("GPGGA,{time},{lat},{ns},{lon},{ew},1,09,{hdop:.1},{:.1},M,0.0,M,,", position.height_m);
            let knots = fix.speed * 3600.0 / 1852.0;
            let rmc = format!("GPRMC,{time},A,{lat},{ns},{lon},{ew},{knots:.2},{:.1},010626,,,A", fix.course_deg);
            Ok((fix.t_receive, [sentence(&gga), sentence(&rmc)]))
        })
        .collect()
}

/// The vehicle bus: the wheel speed as J1939 CCVS1 frames with their times (s).
pub fn wheel_speed_frames(scenario: &Scenario) -> io::Result<Vec<(f64, dash2sim_core::can::CanFrame)>> {
    scenario
        .speed
        .iter()
        .map(|&(t, v)| {
            let frame = ccvs1_frame(v).ok_or_else(|| io::Error::other(format!("speed {v} at {t}: no CCVS1 frame")))?;
            Ok((t, frame))
        })
        .collect()
}

fn origin(scenario: &Scenario) -> io::Result<Geodetic> {
    let [lat, lon, h] = scenario.config.origin;
    Geodetic::new(lat, lon, h).map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, format!("origin: {e}")))
}

/// A J1939 CCVS1 frame (PGN 65265, priority 6, source 0) carrying a wheel-based speed.
fn ccvs1_frame(mps: f64) -> Option<dash2sim_core::can::CanFrame> {
    let raw = (mps * 3.6 * 256.0).round().clamp(0.0, 64_255.0) as u16;
    let [lo, hi] = raw.to_le_bytes();
    let id = dash2sim_core::can::frame::id_from_raw(0x18FE_F100, true)?;
    dash2sim_core::can::CanFrame::data_frame(id, &[0xFF, lo, hi, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF])
}

/// `$BODY*CS` with the XOR checksum.
fn sentence(body: &str) -> String {
    let checksum = body.bytes().fold(0u8, |c, b| c ^ b);
    format!("${body}*{checksum:02X}")
}

fn hhmmss(seconds_of_day: f64) -> String {
    let centis = (seconds_of_day * 100.0).round() as u64;
    let (h, m, s, cs) = (centis / 360_000 % 24, centis / 6000 % 60, centis / 100 % 60, centis % 100);
    format!("{h:02}{m:02}{s:02}.{cs:02}")
}

/// Degrees as NMEA's `dddmm.mmmmmm` with `width` degree digits, and the hemisphere letter.
fn nmea_angle(deg: f64, width: usize, hemispheres: [char; 2]) -> (String, char) {
    let hemisphere = if deg < 0.0 { hemispheres[1] } else { hemispheres[0] };
    let micro_minutes = (deg.abs() * 60.0 * 1e6).round() as u64;
    let (whole, minutes) = (micro_minutes / 60_000_000, micro_minutes % 60_000_000);
    (format!("{whole:0width$}{:02}.{:06}", minutes / 1_000_000, minutes % 1_000_000), hemisphere)
}

/// The road as one OpenStreetMap way (nodes every 10 m along the reference line).
fn road_osm(scenario: &Scenario, frame: &LocalFrame) -> io::Result<String> {
    let road = &scenario.road;
    let mut xml = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<osm version=\"0.6\" generator=\"dash2sim scenario\">\n",
    );
    let count = (road.length() / 10.0).ceil() as u64;
    for k in 0..=count {
        let s = (k as f64 * 10.0).min(road.length());
        let (x, y) = road.point(s, 0.0);
        let g = frame
            .enu_to_geodetic(&Vector3::new(x, y, 0.0))
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, format!("road at s = {s}: {e}")))?;
        let _ =
            writeln!(xml, "  <node id=\"{}\" version=\"1\" lat=\"{:.8}\" lon=\"{:.8}\"/>", k + 1, g.lat_deg, g.lon_deg);
    }
    xml.push_str("  <way id=\"1\" version=\"1\">\n");
    for k in 0..=count {
        let _ = writeln!(xml, "    <nd ref=\"{}\"/>", k + 1);
    }
    let lanes = road.lanes_forward + road.lanes_backward;
    let width = f64::from(lanes) * road.lane_width;
    for (k, v) in [
        ("highway", "trunk".to_owned()),
        ("lanes", lanes.to_string()),
        ("lanes:forward", road.lanes_forward.to_string()),
        ("lanes:backward", road.lanes_backward.to_string()),
        ("width", format!("{width}")),
        ("maxspeed", format!("{:.0}", road.speed_limit * 3.6)),
        ("name", "dash2sim scenario road".to_owned()),
    ] {
        let _ = writeln!(xml, "    <tag k=\"{k}\" v=\"{v}\"/>");
    }
    xml.push_str("  </way>\n</osm>\n");
    Ok(xml)
}

/// The ENU origin as `--origin` takes it (`map build`, `record`, `import`): `LAT,LON,H`.
pub fn origin_option([lat, lon, height]: [f64; 3]) -> String {
    format!("{lat},{lon},{height}")
}

fn summary(scenario: &Scenario, files: &[PathBuf]) -> serde_json::Value {
    let c = &scenario.config;
    let segments: Vec<_> = scenario
        .road
        .segments
        .iter()
        .map(|s| match s {
            Segment::Straight(l) => json!({"straight_m": l}),
            Segment::Arc(l, k) => json!({"arc_m": l, "curvature_per_m": k}),
        })
        .collect();
    let zones: Vec<_> = scenario
        .zones
        .iter()
        .map(|z| {
            json!({"taper_start_s": z.taper_start, "taper_length_m": z.taper_length,
                   "closure_length_m": z.closure_length, "end_taper_length_m": z.end_taper_length})
        })
        .collect();
    let count = |f: fn(&super::Frame) -> usize| scenario.frames.iter().map(f).sum::<usize>();
    json!({
        "seed": c.seed,
        "duration_s": c.duration_s,
        "frame_rate_hz": c.frame_rate_hz,
        "gnss_rate_hz": c.gnss_rate_hz,
        "speed_rate_hz": c.speed_rate_hz,
        "origin": {"lat": c.origin[0], "lon": c.origin[1], "height_m": c.origin[2], "as_option": origin_option(c.origin)},
        "start_utc": "2026-06-01T08:00:00Z",
        "start_unix_s": START_UNIX_S,
        "classes": Class::ALL.iter().map(|k| k.name()).collect::<Vec<_>>(),
        "profile": c.profile.name(),
        "receiver": c.receiver.name(),
        "driver": c.driver.name(),
        // What the truth's verdict must be: the metric a bad driver fails, none for a careful one.
        "expectation": match c.driver.expectation() {
            super::Expectation::Verifies => json!({"verified": true, "fails": null}),
            super::Expectation::Fails(metric) => json!({"verified": false, "fails": metric}),
        },
        "camera": {"focal_px": c.camera.focal_px, "width": c.camera.width, "height": c.camera.height,
                   "mount_height_m": c.camera.mount_height, "mount_forward_m": c.camera.mount_forward,
                   "true_mount_error": {"yaw_deg": c.camera.mount_error.yaw.to_degrees(),
                                        "pitch_deg": c.camera.mount_error.pitch.to_degrees(),
                                        "offset_m": c.camera.mount_error.offset}},
        "road": {"start_heading_rad": scenario.road.start.heading, "segments": segments,
                 "lane_width_m": scenario.road.lane_width, "lanes_forward": scenario.road.lanes_forward,
                 "lanes_backward": scenario.road.lanes_backward, "speed_limit_mps": scenario.road.speed_limit},
        "work_zone": zones.first(),
        "work_zones": zones,
        "vo": {"scale": c.vo.scale, "scale_drift_per_min": c.vo.scale_drift_per_min,
               "yaw_drift_deg_per_min": c.vo.yaw_drift_deg_per_min,
               "scale_walk_per_sqrt_min": c.vo.scale_walk_per_sqrt_min,
               "yaw_walk_deg_per_sqrt_min": c.vo.yaw_walk_deg_per_sqrt_min, "tilt_deg": c.vo.tilt_deg,
               "increment_noise": c.vo.translation_noise, "rotation_noise_deg": c.vo.rotation_noise_deg,
               "reinit": c.vo.reinit.map(|r| json!({"every_s": r.every_s, "gap_s": r.gap_s, "scale_factor": r.scale_factor})),
               "sessions": scenario.vo.reinits() + 1},
        "gnss": {"sigma_range_m": c.gnss.sigma_range, "correlation_s": c.gnss.correlation_s,
                 "latency_s": c.gnss.latency_s, "multipath_rate": c.gnss.multipath_rate,
                 "reported_sigma_factor": c.gnss.reported_sigma_factor, "reported_jitter": c.gnss.reported_jitter,
                 "outages_per_min": c.gnss.outages_per_min},
        "wheel": {"scale": c.wheel.scale, "sigma_mps": c.wheel.sigma, "latency_s": c.wheel.latency_s},
        "detector": {"covariance_factor": c.detector.covariance_factor, "confusion": c.detector.confusion,
                     "occlusion": c.detector.occlusion, "false_positives_per_frame": c.detector.false_positives},
        "street_anchors": c.anchors,
        "imu": super::imu::summary(&c.imu),
        "counts": {
            "frames": scenario.frames.len(),
            "objects": scenario.frames.first().map_or(0, |f| f.objects.len()),
            "visible_object_frames": count(|f| f.visible.len()),
            "detections_3d": count(|f| f.detections_3d.len()),
            "detections_2d": count(|f| f.detections_2d.len()),
            "gnss_fixes": scenario.gnss.len(),
            "gnss_multipath_fixes": scenario.gnss.iter().filter(|g| g.multipath).count(),
            "speed_samples": scenario.speed.len(),
            "imu_samples": scenario.imu.len(),
        },
        "files": files.iter().filter_map(|p| p.file_name()).map(|n| n.to_string_lossy().into_owned()).collect::<Vec<_>>(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nmea_fields_are_formatted_as_receivers_do() {
        assert_eq!(nmea_angle(60.5, 2, ['N', 'S']), ("6030.000000".to_owned(), 'N'));
        assert_eq!(nmea_angle(-4.25, 3, ['E', 'W']), ("00415.000000".to_owned(), 'W'));
        assert_eq!(hhmmss(8.0 * 3600.0 + 61.25), "080101.25");
        // The checksum of a well-known sentence.
        assert_eq!(sentence("GPGLL,4916.45,N,12311.12,W,225444,A"), "$GPGLL,4916.45,N,12311.12,W,225444,A*31");
    }
}
