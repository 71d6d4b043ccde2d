//! Trajectory files: TUM, KITTI and EuRoC, read as evo reads them.
//!
//! * TUM: `t tx ty tz qx qy qz qw`, space separated, `#` comments.
//! * KITTI: 12 numbers per line, the row-major 3×4 `[R|t]`; no timestamps.
//! * EuRoC ground truth CSV: `t_ns, px, py, pz, qw, qx, qy, qz, ...` (≥ 8 columns).
//!
//! Timestamps stay `f64` seconds here (unlike the SDK's µs [`Timestamp`]) because file
//! stamps carry sub-µs digits and evo's association compares them in `f64`; matching its
//! pairs exactly needs the same arithmetic. Every error names the file and line.
//!
//! A crate of its own, a leaf beside the core: the fuzz target of the parser links this
//! and not the whole Linux adapter. `dash2sim_linux::trajectory` re-exports it.
//!
//! [`Timestamp`]: dash2sim_core::time::Timestamp

use std::fmt;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use dash2sim_core::nalgebra::{Matrix3, Vector3};
use dash2sim_core::sim3::Pose;

/// The trajectory file formats understood.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// `t x y z qx qy qz qw`
    Tum,
    /// 3×4 pose matrices, one per line, no timestamps.
    Kitti,
    /// Reference: EuRoC ground-truth CSV (ns stamps, w-first quaternion); estimate: TUM.
    Euroc,
}

/// A sequence of poses with optional timestamps (seconds).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trajectory {
    /// Seconds, one per pose; empty for KITTI files.
    pub stamps: Vec<f64>,
    /// Poses, in file order.
    pub poses: Vec<Pose>,
}

/// What went wrong reading a trajectory file.
#[derive(Debug)]
pub enum TrajectoryError {
    /// The file could not be read.
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A line is malformed.
    Parse {
        /// The file (or `<input>` when parsing a string).
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        message: String,
    },
    /// No poses at all.
    Empty {
        /// The file.
        path: PathBuf,
    },
}

impl fmt::Display for TrajectoryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TrajectoryError::Io { path, source } => write!(f, "{}: {source}", path.display()),
            TrajectoryError::Parse { path, line, message } => write!(f, "{}:{line}: {message}", path.display()),
            TrajectoryError::Empty { path } => write!(f, "{}: no poses in file", path.display()),
        }
    }
}

impl std::error::Error for TrajectoryError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            TrajectoryError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl Trajectory {
    /// Number of poses.
    pub fn len(&self) -> usize {
        self.poses.len()
    }

    /// True when there are no poses.
    pub fn is_empty(&self) -> bool {
        self.poses.is_empty()
    }

    /// Positions only.
    pub fn positions(&self) -> impl Iterator<Item = &Vector3<f64>> {
        self.poses.iter().map(|p| &p.translation)
    }

    /// Read a file of the given format (`Euroc` means the EuRoC ground-truth CSV).
    pub fn read(path: &Path, format: Format) -> Result<Trajectory, TrajectoryError> {
        let text = fs::read_to_string(path).map_err(|source| TrajectoryError::Io { path: path.to_owned(), source })?;
        Trajectory::parse(&text, format, path)
    }

    /// Parse file contents; `path` is only used in error messages.
    pub fn parse(text: &str, format: Format, path: &Path) -> Result<Trajectory, TrajectoryError> {
        let (columns, separator) = match format {
            Format::Tum => (8, ' '),
            Format::Kitti => (12, ' '),
            Format::Euroc => (8, ','),
        };
        let mut traj = Trajectory::default();
        let mut values = Vec::with_capacity(17);
        for (index, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let error = |message: String| TrajectoryError::Parse { path: path.to_owned(), line: index + 1, message };
            values.clear();
            for field in line.split(separator).map(str::trim).filter(|f| !f.is_empty() || separator == ',') {
                let v: f64 = field.parse().map_err(|_| error(format!("not a number: {field:?}")))?;
                if !v.is_finite() {
                    return Err(error(format!("not a finite number: {field:?}")));
                }
                values.push(v);
            }
            let ok = match format {
                Format::Euroc => values.len() >= columns,
                _ => values.len() == columns,
            };
            if !ok {
                return Err(error(format!(
                    "expected {}{columns} values, found {}",
                    if format == Format::Euroc { "at least " } else { "" },
                    values.len()
                )));
            }
            let v = &values;
            if format != Format::Kitti {
                let stamp = if format == Format::Euroc { v[0] / 1e9 } else { v[0] };
                if let Some(&previous) = traj.stamps.last() {
                    if stamp < previous {
                        return Err(error(format!("timestamp {stamp} is earlier than the previous one ({previous})")));
                    }
                }
            }
            match format {
                Format::Tum => {
                    traj.stamps.push(v[0]);
                    traj.poses
                        .push(Pose::from_quaternion_wxyz([v[7], v[4], v[5], v[6]], Vector3::new(v[1], v[2], v[3])));
                }
                Format::Euroc => {
                    traj.stamps.push(v[0] / 1e9);
                    traj.poses
                        .push(Pose::from_quaternion_wxyz([v[4], v[5], v[6], v[7]], Vector3::new(v[1], v[2], v[3])));
                }
                Format::Kitti => {
                    #[rustfmt::skip]
                    let rotation = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
                    traj.poses.push(Pose { rotation, translation: Vector3::new(v[3], v[7], v[11]) });
                }
            }
        }
        if traj.poses.is_empty() {
            return Err(TrajectoryError::Empty { path: path.to_owned() });
        }
        Ok(traj)
    }

    /// Keep only the poses at `indices` (in that order).
    pub fn select(&self, indices: &[usize]) -> Trajectory {
        Trajectory {
            stamps: if self.stamps.is_empty() { Vec::new() } else { indices.iter().map(|&i| self.stamps[i]).collect() },
            poses: indices.iter().map(|&i| self.poses[i]).collect(),
        }
    }

    /// Write as TUM (`t x y z qx qy qz qw`); poses without stamps get their index.
    pub fn write_tum(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        for (k, pose) in self.poses.iter().enumerate() {
            let t = self.stamps.get(k).copied().unwrap_or(k as f64);
            let q = dash2sim_core::nalgebra::UnitQuaternion::from_matrix(&pose.rotation);
            let p = pose.translation;
            writeln!(out, "{t:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}", p.x, p.y, p.z, q.i, q.j, q.k, q.w)?;
        }
        Ok(())
    }

    /// Write as KITTI (row-major 3×4 per line).
    pub fn write_kitti(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        for pose in &self.poses {
            let (r, t) = (&pose.rotation, &pose.translation);
            let mut line = String::new();
            for row in 0..3 {
                for col in 0..3 {
                    line.push_str(&format!("{:e} ", r[(row, col)]));
                }
                line.push_str(&format!("{:e}{}", t[row], if row < 2 { " " } else { "" }));
            }
            writeln!(out, "{line}")?;
        }
        Ok(())
    }

    /// Write as an EuRoC ground-truth style CSV: `t_ns, p_x, p_y, p_z, q_w, q_x, q_y, q_z`.
    pub fn write_euroc(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        writeln!(
            out,
            "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []"
        )?;
        for (k, pose) in self.poses.iter().enumerate() {
            let t = self.stamps.get(k).copied().unwrap_or(k as f64);
            let q = dash2sim_core::nalgebra::UnitQuaternion::from_matrix(&pose.rotation);
            let p = pose.translation;
            let ns = (t * 1e9).round() as i64;
            writeln!(out, "{ns},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9},{:.9}", p.x, p.y, p.z, q.w, q.i, q.j, q.k)?;
        }
        Ok(())
    }
}

/// Write a trajectory to `path` in `format`.
pub fn write_file(traj: &Trajectory, path: &Path, format: Format) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(fs::File::create(path)?);
    match format {
        Format::Kitti => traj.write_kitti(&mut out)?,
        Format::Tum => traj.write_tum(&mut out)?,
        Format::Euroc => traj.write_euroc(&mut out)?,
    }
    out.flush()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str, format: Format) -> Result<Trajectory, TrajectoryError> {
        Trajectory::parse(text, format, Path::new("t.txt"))
    }

    #[test]
    fn tum_round_trip() {
        let text = "# header\n1.0 1 2 3 0 0 0.7071067811865476 0.7071067811865476\n2.5 4 5 6 0 0 0 1\n";
        let t = parse(text, Format::Tum).expect("valid");
        assert_eq!(t.stamps, vec![1.0, 2.5]);
        assert!((t.poses[0].rotation[(1, 0)] - 1.0).abs() < 1e-12);
        let mut out = Vec::new();
        t.write_tum(&mut out).expect("write");
        let back = parse(std::str::from_utf8(&out).expect("utf8"), Format::Tum).expect("valid");
        assert_eq!(back.stamps, t.stamps);
        for (a, b) in back.poses.iter().zip(&t.poses) {
            assert!((a.to_matrix() - b.to_matrix()).norm() < 1e-8);
        }
    }

    #[test]
    fn kitti_round_trip() {
        let text = "1 0 0 1.5 0 1 0 -2 0 0 1 3\n";
        let t = parse(text, Format::Kitti).expect("valid");
        assert_eq!(t.poses[0].translation, Vector3::new(1.5, -2.0, 3.0));
        let mut out = Vec::new();
        t.write_kitti(&mut out).expect("write");
        assert_eq!(parse(std::str::from_utf8(&out).expect("utf8"), Format::Kitti).expect("valid"), t);
    }

    #[test]
    fn euroc_round_trip() {
        let text = "0.5 1 2 3 0 0.6 0 0.8\n1.25 4 5 6 0 0 0 1\n";
        let t = parse(text, Format::Tum).expect("valid");
        let mut out = Vec::new();
        t.write_euroc(&mut out).expect("write");
        let back = parse(std::str::from_utf8(&out).expect("utf8"), Format::Euroc).expect("valid");
        assert_eq!(back.stamps, t.stamps);
        for (a, b) in back.poses.iter().zip(&t.poses) {
            assert!((a.to_matrix() - b.to_matrix()).norm() < 1e-8);
        }
    }

    #[test]
    fn euroc_stamps_are_nanoseconds_and_quaternion_is_w_first() {
        let text = "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z,v\n1403715523912143104,1,2,3,1,0,0,0,9\n";
        let t = parse(text, Format::Euroc).expect("valid");
        assert!((t.stamps[0] - 1_403_715_523.912_143).abs() < 1e-6);
        assert_eq!(t.poses[0].rotation, Matrix3::identity());
    }

    #[test]
    fn errors_name_the_line() {
        let err = parse("1 2 3\n", Format::Tum).expect_err("short line");
        assert_eq!(err.to_string(), "t.txt:1: expected 8 values, found 3");
        let err = parse("# c\n1 2 3 4 5 6 7 x\n", Format::Tum).expect_err("bad number");
        assert_eq!(err.to_string(), "t.txt:2: not a number: \"x\"");
        let err = parse("1 2 3 4 5 6 7 NaN\n", Format::Tum).expect_err("nan");
        assert!(err.to_string().contains("not a finite number"));
        assert!(matches!(parse("# only a comment\n", Format::Kitti), Err(TrajectoryError::Empty { .. })));
        let err = parse("2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", Format::Tum).expect_err("out of order");
        assert_eq!(err.to_string(), "t.txt:2: timestamp 1 is earlier than the previous one (2)");
    }
}
