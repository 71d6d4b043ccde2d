//! Recorded files → one input stream in receive-time order, in the core's replay format
//! (`dash2sim_core::pipeline::replay`): what the device would have seen, in the order it
//! would have seen it.
//!
//! | file | what it holds | device time of an input |
//! |---|---|---|
//! | `--vo F.tum` | camera poses in the VO frame, one per frame (frame k = k-th line) | the TUM stamp |
//! | `--nmea F` | the serial capture: `(seconds) $SENTENCE*CS` per line | the stamp in parentheses |
//! | `--can F.log` | candump `-l` (or any candump dialect with timestamps) | the candump stamp |
//! | `--detections F.csv` | 3D detections in the camera frame (`detections` CSV) | the `t_s` column |
//! | `--detections2d F.txt` | MOTChallenge detections (`frame,-1,left,top,w,h,score,…`) | the VO stamp of the frame |
//! | `--imu F.csv` | IMU samples (`t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z`) | the `t_s` column |

use std::collections::BTreeMap;
use std::path::Path;

use dash2sim_can::source::FrameSource;
use dash2sim_core::box2d::Box2d;
use dash2sim_core::can::CanFrame;
use dash2sim_core::imu::ImuSample;
use dash2sim_core::pipeline::replay::Recorder;
use dash2sim_core::pipeline::ImageDetection;
use dash2sim_core::sim3::Pose;
use dash2sim_core::time::Timestamp;
use dash2sim_core::track2d::Detection;
use dash2sim_core::track3d::Detection3d;

use crate::trajectory::{Format, Trajectory};
use crate::{Error, Result};

/// One input before it is written to the stream. The order of the variants is the order
/// among inputs of the same time (bus and serial before the frame they belong with).
#[derive(Clone, Debug)]
enum Input {
    Can(CanFrame),
    Serial(Vec<u8>),
    Vo(u64, u32, Pose),
    Detections3d(u64, Vec<Detection3d>),
    Detections2d(u64, Vec<ImageDetection>),
    Imu(ImuSample),
}

impl Input {
    fn rank(&self) -> u8 {
        match self {
            Input::Can(_) => 0,
            Input::Serial(_) => 1,
            Input::Imu(_) => 2,
            Input::Vo(..) => 3,
            Input::Detections3d(..) => 4,
            Input::Detections2d(..) => 5,
        }
    }
}

/// Counts of what the files held, and what was wrong in them.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct SourceCounts {
    /// VO poses.
    #[serde(rename = "vo_poses")]
    pub vo: u64,
    /// Serial lines.
    pub serial_lines: u64,
    /// CAN frames.
    pub can_frames: u64,
    /// Frames with 3D detections, and detections.
    pub detection_frames: u64,
    /// 3D detections.
    pub detections: u64,
    /// Frames with 2D detections.
    pub detection2d_frames: u64,
    /// Frames with 2D detections skipped because no other input gives their time (no VO
    /// pose, no 3D detections: the VO had lost track and nothing was seen in 3D).
    pub detection2d_frames_without_time: u64,
    /// IMU samples.
    pub imu_samples: u64,
    /// Lines of the captures that could not be read, `FILE: what` (at most ten per file,
    /// then how many more); reading went on after each.
    /// Not in the summary: `record` reports them on stderr as it reads.
    #[serde(skip)]
    pub problems: Vec<String>,
}

/// The inputs of the files, to be merged by time.
#[derive(Debug, Default)]
pub struct Inputs {
    /// (device µs, rank, sequence) → input.
    items: BTreeMap<(i64, u8, u64), Input>,
    next: u64,
    /// VO stamps by frame number.
    frame_times: BTreeMap<u64, i64>,
    /// What was read.
    pub counts: SourceCounts,
}

/// `t` seconds in microseconds, if a timestamp holds it.
fn micros(t: f64) -> Option<i64> {
    Timestamp::from_secs_f64(t).map(Timestamp::micros)
}

/// Why a time was refused.
fn out_of_range(t: f64) -> String {
    format!("time {t} is out of range")
}

impl Inputs {
    fn push(&mut self, t_us: i64, input: Input) {
        let key = (t_us, input.rank(), self.next);
        self.next += 1;
        self.items.insert(key, input);
    }

    /// VO poses: TUM (frame k is the k-th pose, from 1; one VO session), or the CSV a
    /// camera process that loses track writes ([`read_vo_csv`]: each pose with its frame
    /// number and VO session).
    pub fn vo(&mut self, path: &Path) -> Result<()> {
        let poses: Vec<VoRow> = if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("csv")) {
            read_vo_csv(path)?
        } else {
            let traj = Trajectory::read(path, Format::Tum).map_err(Error::other)?;
            (1..)
                .zip(traj.stamps)
                .zip(traj.poses)
                .map(|((frame, t), pose)| VoRow { frame, t, session: 0, pose })
                .collect()
        };
        for (k, VoRow { frame, t, session, pose }) in poses.into_iter().enumerate() {
            let t_us = micros(t).ok_or_else(|| Error::line(path, k + 1, out_of_range(t)))?;
            self.frame_times.insert(frame, t_us);
            self.push(t_us, Input::Vo(frame, session, pose));
            self.counts.vo += 1;
        }
        Ok(())
    }

    /// The serial capture: `(seconds) sentence` per line.
    pub fn serial(&mut self, path: &Path) -> Result<()> {
        let text = std::fs::read(path).map_err(|e| Error::file(path, e))?;
        for (n, line) in text.split(|&b| b == b'\n').enumerate() {
            let line = line.strip_suffix(b"\r").unwrap_or(line);
            if line.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            let at = |message: String| Error::line(path, n + 1, message);
            let stamped = line
                .strip_prefix(b"(")
                .and_then(|rest| rest.iter().position(|&b| b == b')').map(|end| (&rest[..end], &rest[end + 1..])));
            let Some((stamp, sentence)) = stamped else {
                return Err(at(
                    "expected `(seconds) $SENTENCE` — the receive time of each line is needed (a raw NMEA capture has none)"
                        .to_owned(),
                ));
            };
            let t: f64 = std::str::from_utf8(stamp)
                .ok()
                .and_then(|s| s.trim().parse().ok())
                .ok_or_else(|| at(format!("receive time {:?} is not a number", String::from_utf8_lossy(stamp))))?;
            let mut bytes = sentence.trim_ascii_start().to_vec();
            bytes.extend_from_slice(b"\r\n");
            self.push(micros(t).ok_or_else(|| at(out_of_range(t)))?, Input::Serial(bytes));
            self.counts.serial_lines += 1;
        }
        Ok(())
    }

    /// A candump capture; lines that are not frames are reported and skipped.
    pub fn can(&mut self, path: &Path) -> Result<()> {
        let file = std::fs::File::open(path).map_err(|e| Error::file(path, e))?;
        let mut reader = dash2sim_can::candump::CandumpReader::new(std::io::BufReader::new(file));
        let mut problems = 0u64;
        while let Some(record) = reader.next_frame() {
            match record {
                Ok(r) => match r.time {
                    Some(t) => {
                        self.push(t.micros(), Input::Can(r.frame));
                        self.counts.can_frames += 1;
                    }
                    None => {
                        return Err(Error::line(
                            path,
                            reader.line_number() as usize,
                            "a candump line without a timestamp",
                        ))
                    }
                },
                Err(e) => {
                    problems += 1;
                    if problems <= 10 {
                        self.counts.problems.push(format!("{}: {e}", path.display()));
                    }
                }
            }
        }
        if problems > 10 {
            self.counts.problems.push(format!("{}: … and {} more problems", path.display(), problems - 10));
        }
        Ok(())
    }

    /// 3D detections; `class_id` names the tracker's class of a name (unknown names get
    /// an id the tracker refuses, so they are counted, not dropped silently).
    pub fn detections(&mut self, path: &Path, class_id: impl Fn(&str) -> Option<u16>) -> Result<()> {
        let mut frames: BTreeMap<u64, (f64, Vec<Detection3d>)> = BTreeMap::new();
        for row in crate::ingest::detections::read(path)? {
            let entry = frames.entry(row.frame).or_insert((row.t, Vec::new()));
            entry.1.push(Detection3d {
                class: class_id(&row.class).unwrap_or(u16::MAX),
                bbox: row.bbox,
                score: row.score,
                position_covariance: row.covariance,
            });
        }
        for (frame, (t, detections)) in frames {
            self.counts.detection_frames += 1;
            self.counts.detections += detections.len() as u64;
            let t_us = micros(t).ok_or_else(|| Error::file(path, out_of_range(t)))?;
            // A frame the VO lost keeps its time for the 2D detections.
            self.frame_times.entry(frame).or_insert(t_us);
            self.push(t_us, Input::Detections3d(frame, detections));
        }
        Ok(())
    }

    /// 2D detections (MOTChallenge); each frame at its VO stamp (or, where the VO lost
    /// track, its 3D detections' time), so read those first. A frame with neither is
    /// skipped and counted.
    pub fn detections2d(&mut self, path: &Path) -> Result<()> {
        let frames = read_detections2d(path)?;
        for (frame, detections) in frames {
            let Some(&t_us) = self.frame_times.get(&frame) else {
                self.counts.detection2d_frames_without_time += 1;
                continue;
            };
            self.counts.detection2d_frames += 1;
            self.push(t_us, Input::Detections2d(frame, detections));
        }
        Ok(())
    }

    /// IMU samples ([`read_imu_csv`]).
    pub fn imu(&mut self, path: &Path) -> Result<()> {
        for (n, (t, sample)) in read_imu_csv(path)?.into_iter().enumerate() {
            let t_us = micros(t).ok_or_else(|| Error::line(path, n + 2, out_of_range(t)))?;
            self.push(t_us, Input::Imu(sample));
            self.counts.imu_samples += 1;
        }
        Ok(())
    }

    /// Nothing was read.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// The merged stream in the core's replay format.
    pub fn stream(&self) -> Result<Vec<u8>> {
        let mut recorder = Recorder::new(Vec::new()).map_err(Error::other)?;
        for (&(t_us, _, _), input) in &self.items {
            let t = Timestamp::from_micros(t_us);
            let written = match input {
                Input::Can(frame) => recorder.can(t, frame),
                Input::Serial(bytes) => recorder.serial(t, bytes),
                Input::Vo(frame, session, pose) => recorder.vo(t, *frame, *session, pose),
                Input::Detections3d(frame, d) => recorder.detections3d(t, *frame, d),
                Input::Detections2d(frame, d) => recorder.detections2d(t, *frame, d),
                Input::Imu(sample) => recorder.imu(t, sample),
            };
            written.map_err(Error::other)?;
        }
        recorder.finish().map_err(Error::other)
    }
}

/// 2D detections (MOTChallenge: `frame,id,left,top,width,height,score,…`, pixels as
/// written), by frame number.
pub fn read_detections2d(path: &Path) -> Result<BTreeMap<u64, Vec<ImageDetection>>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let mut frames: BTreeMap<u64, Vec<ImageDetection>> = BTreeMap::new();
    for (n, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let at = |message: String| Error::line(path, n + 1, message);
        let f: Vec<f64> = line
            .split(',')
            .take(7)
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| at("expected frame,id,left,top,width,height,score numbers".to_string()))?;
        let [frame, _, x, y, w, h, score] = f[..] else {
            return Err(at("expected at least 7 columns".to_string()));
        };
        let bbox = Box2d::new(x, y, w, h).map_err(|e| at(e.to_string()))?;
        if !(frame >= 1.0 && frame.fract() == 0.0) {
            return Err(at(format!("frame {frame} is not a frame number")));
        }
        frames.entry(frame as u64).or_default().push(ImageDetection { class: 0, detection: Detection { bbox, score } });
    }
    Ok(frames)
}

/// The numbered data lines of a CSV whose first line (blank lines and `#` comments aside)
/// must be `header`; a missing or other header is an error naming the line.
fn rows_after_header<'a>(path: &Path, text: &'a str, header: &str) -> Result<Vec<(usize, &'a str)>> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty() && !l.starts_with('#'));
    match lines.next() {
        Some((_, first)) if first.trim() == header => Ok(lines.collect()),
        Some((n, first)) => Err(Error::line(path, n + 1, format!("header `{}`: expected `{header}`", first.trim()))),
        None => Err(Error::file(path, format!("empty: expected the header `{header}`"))),
    }
}

/// The header of an IMU CSV.
pub const IMU_CSV_HEADER: &str = "t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z";

/// An IMU CSV: `t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z` — the device time of each
/// sample (s), the angular rate (rad/s) and the specific force (m/s², 9.81 up at rest) on
/// the sensor's own axes (`--imu-mount` says how they sit on the camera). Times must go
/// forward; every value must be a finite number. Units the pipeline can tell are wrong (g,
/// °/s) or axes that gravity contradicts are refused there, counted and logged.
pub fn read_imu_csv(path: &Path) -> Result<Vec<(f64, ImuSample)>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let mut out: Vec<(f64, ImuSample)> = Vec::new();
    for (n, line) in rows_after_header(path, &text, IMU_CSV_HEADER)? {
        let at = |message: String| Error::line(path, n + 1, message);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 7 {
            return Err(at(format!("{} fields, expected 7 ({IMU_CSV_HEADER})", fields.len())));
        }
        let mut v = [0.0f64; 7];
        for (slot, field) in v.iter_mut().zip(&fields) {
            *slot = field
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| at(format!("`{field}` is not a finite number")))?;
        }
        let [t, gx, gy, gz, ax, ay, az] = v;
        if let Some((previous, _)) = out.last().filter(|(p, _)| *p >= t) {
            return Err(at(format!("time {t} s does not follow {previous} s: the samples must go forward in time")));
        }
        out.push((t, ImuSample { gyro: [gx, gy, gz], accel: [ax, ay, az] }));
    }
    Ok(out)
}

/// The header of a VO CSV.
pub const VO_CSV_HEADER: &str = "frame,t_s,x,y,z,qx,qy,qz,qw,session";

/// A VO CSV: `frame,t_s,x,y,z,qx,qy,qz,qw,session` — the frame number of each pose (frames
/// where the VO had lost track have none), its device time, the camera's pose in the VO
/// frame (TUM's order) and the VO session (0, then one more after each re-initialisation).
/// Frame numbers must increase; sessions must not go back.
pub fn read_vo_csv(path: &Path) -> Result<Vec<VoRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let mut out: Vec<VoRow> = Vec::new();
    for (n, line) in rows_after_header(path, &text, VO_CSV_HEADER)? {
        let at = |message: String| Error::line(path, n + 1, message);
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 10 {
            return Err(at(format!("{} fields, expected 10 ({VO_CSV_HEADER})", fields.len())));
        }
        let frame: u64 = fields[0].parse().map_err(|_| at(format!("frame `{}` is not a frame number", fields[0])))?;
        let mut v = [0.0f64; 8];
        for (slot, field) in v.iter_mut().zip(&fields[1..9]) {
            *slot = field
                .parse()
                .ok()
                .filter(|x: &f64| x.is_finite())
                .ok_or_else(|| at(format!("`{field}` is not a finite number")))?;
        }
        if out.last().is_some_and(|previous| previous.frame >= frame) {
            return Err(at(format!("frame {frame} does not follow the frame before it")));
        }
        let session: u32 =
            fields[9].parse().map_err(|_| at(format!("session `{}` is not a session number", fields[9])))?;
        if let Some(previous) = out.last().filter(|p| p.session > session) {
            return Err(at(format!("session {session} after session {}: sessions only count up", previous.session)));
        }
        let [t, x, y, z, qx, qy, qz, qw] = v;
        if qw * qw + qx * qx + qy * qy + qz * qz < 1e-12 {
            return Err(at("the quaternion is zero, not a rotation".to_string()));
        }
        let pose = Pose::from_quaternion_wxyz([qw, qx, qy, qz], dash2sim_core::nalgebra::Vector3::new(x, y, z));
        out.push(VoRow { frame, t, session, pose });
    }
    Ok(out)
}

/// One pose of a VO file.
#[derive(Clone, Copy, Debug)]
pub struct VoRow {
    /// The camera's frame number.
    pub frame: u64,
    /// Device time, s.
    pub t: f64,
    /// VO session.
    pub session: u32,
    /// Camera → VO frame.
    pub pose: Pose,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A CSV file with `header` and `body` in the temporary folder.
    fn csv(name: &str, header: &str, body: &str) -> std::path::PathBuf {
        let path = std::env::temp_dir().join(format!("dash2sim-csv-{}-{name}.csv", std::process::id()));
        std::fs::write(&path, format!("{header}\n{body}")).expect("write");
        path
    }

    fn vo_csv(name: &str, body: &str) -> std::path::PathBuf {
        csv(&format!("vo-{name}"), VO_CSV_HEADER, body)
    }

    #[test]
    fn a_bad_imu_csv_names_the_line_and_what_is_wrong() {
        for (name, body, expected) in [
            ("back", "0.02,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.8\n", ":3: time 0.01 s does not follow 0.02 s"),
            ("nan", "0.0,NaN,0,0,0,0,9.8\n", ":2: `NaN` is not a finite number"),
            ("short", "0.0,0,0,0\n", ":2: 4 fields, expected 7"),
        ] {
            let path = csv(&format!("imu-{name}"), IMU_CSV_HEADER, body);
            let e = read_imu_csv(&path).expect_err(name);
            assert!(e.to_string().contains(expected), "{name}: {e}");
            let _ = std::fs::remove_file(path);
        }
        let path = csv("imu-good", IMU_CSV_HEADER, "0.00,0.1,0,0,0,0,9.8\n0.01,0,0,0,0.5,0,9.8\n");
        let samples = read_imu_csv(&path).expect("read");
        assert_eq!(samples.len(), 2);
        assert_eq!(samples[1].1.accel, [0.5, 0.0, 9.8]);
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_vo_csv_keeps_each_pose_s_frame_number_across_a_gap() {
        let path = vo_csv("gap", "1,0.0,0,0,0,0,0,0,1,0\n2,0.1,1,0,0,0,0,0,1,0\n7,0.6,0,0,0,0,0,0,1,1\n");
        let mut inputs = Inputs::default();
        inputs.vo(&path).expect("read");
        assert_eq!(inputs.frame_times.keys().copied().collect::<Vec<_>>(), vec![1, 2, 7]);
        assert_eq!(inputs.frame_times[&7], 600_000);
        let _ = std::fs::remove_file(path);
    }

    #[test]
    fn a_bad_vo_csv_names_the_line_and_what_is_wrong() {
        for (name, body, expected) in [
            ("order", "3,0.2,0,0,0,0,0,0,1,0\n2,0.3,0,0,0,0,0,0,1,0\n", ":3: frame 2 does not follow"),
            ("zero", "1,0.0,0,0,0,0,0,0,0,0\n", ":2: the quaternion is zero"),
            ("nan", "1,0.0,nan,0,0,0,0,0,1,0\n", ":2: `nan` is not a finite number"),
            ("short", "1,0.0,0,0,0\n", ":2: 5 fields, expected 10"),
            ("frame", "x,0.0,0,0,0,0,0,0,1,0\n", ":2: frame `x` is not a frame number"),
        ] {
            let path = vo_csv(name, body);
            let e = read_vo_csv(&path).expect_err(name);
            assert!(matches!(e, Error::Line { .. }), "{name}: {e:?}");
            assert!(e.to_string().contains(expected), "{name}: {e}");
            let _ = std::fs::remove_file(path);
        }
        let path = std::env::temp_dir().join(format!("dash2sim-vo-{}-header.csv", std::process::id()));
        std::fs::write(&path, "t,x,y\n").expect("write");
        assert!(read_vo_csv(&path).expect_err("header").to_string().contains(":1: header `t,x,y`"));
        let _ = std::fs::remove_file(path);
    }
}
