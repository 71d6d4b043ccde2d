//! The 3D detections CSV (`frame,t_s,class,x,y,z,yaw,l,w,h,score,cov_xx,cov_xy,cov_yy`):
//! what a monocular 3D detector reports per camera frame, in the camera frame (x forward,
//! y left, z up, metres from the camera) with the covariance of the horizontal centre
//! (m²; empty or all zero when the detector gives none). `dash2sim scenario generate`
//! writes it and `dash2sim record --detections` reads it.

use std::path::Path;

use crate::{Error, Result};
use dash2sim_core::box3d::Box3d;

/// The header line.
pub const HEADER: &str = "frame,t_s,class,x,y,z,yaw,l,w,h,score,cov_xx,cov_xy,cov_yy";

/// One CSV line (with its newline).
pub fn line(frame: u64, t: f64, class: &str, b: &Box3d, score: f64, covariance: Option<[f64; 3]>) -> String {
    let cov = covariance.map_or_else(|| ",,".to_owned(), |[xx, xy, yy]| format!("{xx:.6},{xy:.6},{yy:.6}"));
    format!(
        "{frame},{t:.6},{class},{:.4},{:.4},{:.4},{:.5},{:.3},{:.3},{:.3},{score:.3},{cov}\n",
        b.x, b.y, b.z, b.yaw, b.l, b.w, b.h
    )
}

/// One detection.
#[derive(Clone, Debug, PartialEq)]
pub struct DetectionRow {
    /// Camera frame number.
    pub frame: u64,
    /// Capture time, s (device clock).
    pub t: f64,
    /// Class name.
    pub class: String,
    /// The box in the camera frame.
    pub bbox: Box3d,
    /// Score in [0, 1].
    pub score: f64,
    /// Horizontal centre covariance (xx, xy, yy), m².
    pub covariance: Option<[f64; 3]>,
}

/// Read every row; a bad line is an error naming the file and line.
pub fn read(path: &Path) -> Result<Vec<DetectionRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let mut rows = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || (n == 0 && line.starts_with("frame")) {
            continue;
        }
        let at = |what: &str| Error::line(path, n + 1, what);
        let f: Vec<&str> = line.split(',').map(str::trim).collect();
        if f.len() != 11 && f.len() != 14 {
            return Err(at(&format!("expected 11 or 14 columns ({HEADER}), found {}", f.len())));
        }
        let number = |k: usize, name: &str| -> Result<f64> {
            f[k].parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| at(&format!("{name} is not a finite number")))
        };
        let frame = f[0].parse::<u64>().map_err(|_| at("frame is not a non-negative integer"))?;
        let covariance = if f.len() == 14 && f[11..].iter().any(|v| !v.is_empty()) {
            let c = [number(11, "cov_xx")?, number(12, "cov_xy")?, number(13, "cov_yy")?];
            (c != [0.0; 3]).then_some(c)
        } else {
            None
        };
        rows.push(DetectionRow {
            frame,
            t: number(1, "t_s")?,
            class: f[2].to_owned(),
            bbox: Box3d {
                x: number(3, "x")?,
                y: number(4, "y")?,
                z: number(5, "z")?,
                yaw: number(6, "yaw")?,
                l: number(7, "l")?,
                w: number(8, "w")?,
                h: number(9, "h")?,
            },
            score: number(10, "score")?,
            covariance,
        });
    }
    Ok(rows)
}
