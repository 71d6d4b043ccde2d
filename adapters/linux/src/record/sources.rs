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

use std::collections::BTreeMap;
use std::path::Path;

use dash2sim_can::source::FrameSource;
use dash2sim_core::box2d::Box2d;
use dash2sim_core::can::CanFrame;
use dash2sim_core::pipeline::replay::Recorder;
use dash2sim_core::pipeline::ImageDetection;
use dash2sim_core::sim3::Pose;
use dash2sim_core::time::Timestamp;
use dash2sim_core::track2d::Detection;
use dash2sim_core::track3d::Detection3d;

use crate::trajectory::{Format, Trajectory};

/// One input before it is written to the stream. The order of the variants is the order
/// among inputs of the same time (bus and serial before the frame they belong with).
#[derive(Clone, Debug)]
enum Input {
    Can(CanFrame),
    Serial(Vec<u8>),
    Vo(u64, Pose),
    Detections3d(u64, Vec<Detection3d>),
    Detections2d(u64, Vec<ImageDetection>),
}

impl Input {
    fn rank(&self) -> u8 {
        match self {
            Input::Can(_) => 0,
            Input::Serial(_) => 1,
            Input::Vo(..) => 2,
            Input::Detections3d(..) => 3,
            Input::Detections2d(..) => 4,
        }
    }
}

/// Counts of what the files held.
#[derive(Clone, Copy, Debug, Default)]
pub struct SourceCounts {
    /// VO poses.
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

fn micros(t: f64, what: &str) -> Result<i64, String> {
    Timestamp::from_secs_f64(t).map(Timestamp::micros).ok_or_else(|| format!("{what}: time {t} is out of range"))
}

impl Inputs {
    fn push(&mut self, t_us: i64, input: Input) {
        let key = (t_us, input.rank(), self.next);
        self.next += 1;
        self.items.insert(key, input);
    }

    /// VO poses: frame k is the k-th pose (from 1).
    pub fn vo(&mut self, path: &Path) -> Result<(), String> {
        let traj = Trajectory::read(path, Format::Tum).map_err(|e| e.to_string())?;
        for (k, (t, pose)) in traj.stamps.iter().zip(&traj.poses).enumerate() {
            let t_us = micros(*t, &format!("{}:{}", path.display(), k + 1))?;
            let frame = k as u64 + 1;
            self.frame_times.insert(frame, t_us);
            self.push(t_us, Input::Vo(frame, *pose));
            self.counts.vo += 1;
        }
        Ok(())
    }

    /// The serial capture: `(seconds) sentence` per line.
    pub fn serial(&mut self, path: &Path) -> Result<(), String> {
        let text = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        for (n, line) in text.split(|&b| b == b'\n').enumerate() {
            let line = line.strip_suffix(b"\r").unwrap_or(line);
            if line.iter().all(u8::is_ascii_whitespace) {
                continue;
            }
            let at = || format!("{}:{}", path.display(), n + 1);
            let stamped = line
                .strip_prefix(b"(")
                .and_then(|rest| rest.iter().position(|&b| b == b')').map(|end| (&rest[..end], &rest[end + 1..])));
            let Some((stamp, sentence)) = stamped else {
                return Err(format!(
                    "{}: expected `(seconds) $SENTENCE` — the receive time of each line is needed (a raw NMEA capture has none)",
                    at()
                ));
            };
            let t: f64 = std::str::from_utf8(stamp).ok().and_then(|s| s.trim().parse().ok()).ok_or_else(|| {
                format!("{}: receive time {:?} is not a number", at(), String::from_utf8_lossy(stamp))
            })?;
            let mut bytes = sentence.trim_ascii_start().to_vec();
            bytes.extend_from_slice(b"\r\n");
            self.push(micros(t, &at())?, Input::Serial(bytes));
            self.counts.serial_lines += 1;
        }
        Ok(())
    }

    /// A candump capture; lines that are not frames are reported and skipped.
    pub fn can(&mut self, path: &Path) -> Result<(), String> {
        let file = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
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
                        return Err(format!(
                            "{}:{}: a candump line without a timestamp",
                            path.display(),
                            reader.line_number()
                        ))
                    }
                },
                Err(e) => {
                    problems += 1;
                    if problems <= 10 {
                        eprintln!("{}: {e}", path.display());
                    }
                }
            }
        }
        if problems > 10 {
            eprintln!("{}: … and {} more problems", path.display(), problems - 10);
        }
        Ok(())
    }

    /// 3D detections; `class_id` names the tracker's class of a name (unknown names get
    /// an id the tracker refuses, so they are counted, not dropped silently).
    pub fn detections(&mut self, path: &Path, class_id: impl Fn(&str) -> Option<u16>) -> Result<(), String> {
        let mut frames: BTreeMap<u64, (f64, Vec<Detection3d>)> = BTreeMap::new();
        for row in crate::detections::read(path)? {
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
            self.push(micros(t, &path.display().to_string())?, Input::Detections3d(frame, detections));
        }
        Ok(())
    }

    /// 2D detections (MOTChallenge); each frame at its VO stamp, so read `--vo` first.
    pub fn detections2d(&mut self, path: &Path) -> Result<(), String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut frames: BTreeMap<u64, Vec<ImageDetection>> = BTreeMap::new();
        for (n, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let at = || format!("{}:{}", path.display(), n + 1);
            let f: Vec<f64> = line
                .split(',')
                .take(7)
                .map(|v| v.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| format!("{}: expected frame,id,left,top,width,height,score numbers", at()))?;
            let [frame, _, x, y, w, h, score] = f[..] else {
                return Err(format!("{}: expected at least 7 columns", at()));
            };
            let bbox = Box2d::new(x, y, w, h).map_err(|e| format!("{}: {e}", at()))?;
            if !(frame >= 1.0 && frame.fract() == 0.0) {
                return Err(format!("{}: frame {frame} is not a frame number", at()));
            }
            frames
                .entry(frame as u64)
                .or_default()
                .push(ImageDetection { class: 0, detection: Detection { bbox, score } });
        }
        for (frame, detections) in frames {
            let Some(&t_us) = self.frame_times.get(&frame) else {
                return Err(format!(
                    "{}: frame {frame} has no VO pose (give --vo with one pose per frame)",
                    path.display()
                ));
            };
            self.counts.detection2d_frames += 1;
            self.push(t_us, Input::Detections2d(frame, detections));
        }
        Ok(())
    }

    /// Nothing was read.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// The merged stream in the core's replay format.
    pub fn stream(&self) -> Result<Vec<u8>, String> {
        let mut recorder = Recorder::new(Vec::new()).map_err(|e| e.to_string())?;
        for (&(t_us, _, _), input) in &self.items {
            let t = Timestamp::from_micros(t_us);
            let written = match input {
                Input::Can(frame) => recorder.can(t, frame),
                Input::Serial(bytes) => recorder.serial(t, bytes),
                Input::Vo(frame, pose) => recorder.vo(t, *frame, pose),
                Input::Detections3d(frame, d) => recorder.detections3d(t, *frame, d),
                Input::Detections2d(frame, d) => recorder.detections2d(t, *frame, d),
            };
            written.map_err(|e| e.to_string())?;
        }
        recorder.finish().map_err(|e| e.to_string())
    }
}
