//! MOTChallenge CSV (`frame,id,left,top,width,height,conf,...`), the file format of 2D
//! detections and tracks, read and written as motmetrics and the MOT benchmarks do.

use std::io::Write as _;
use std::path::Path;

use crate::{Error, Result};
use dash2sim_core::box2d::Box2d;

/// One row of a MOTChallenge file: `frame,id,left,top,width,height,conf,...`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotRow {
    /// Frame number (1-based in MOTChallenge).
    pub frame: i64,
    /// Track id (-1 in detection files).
    pub id: i64,
    /// The box. Like motmetrics, the MATLAB 1-based origin is moved to 0 on reading.
    pub bbox: Box2d,
    /// Confidence column (-1 when unused).
    pub confidence: f64,
}

/// Read a MOTChallenge CSV (comma or whitespace separated). Errors name file and line.
pub fn read_mot(path: &Path) -> Result<Vec<MotRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let mut rows = Vec::new();
    for (index, line) in text.lines().enumerate() {
        let at = |message: String| Error::line(path, index + 1, message);
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = line.split(|c: char| c == ',' || c.is_whitespace()).filter(|c| !c.is_empty()).collect();
        if cells.len() < 6 {
            return Err(at(format!("expected at least 6 columns, found {}", cells.len())));
        }
        let number = |i: usize| -> Result<f64> {
            cells.get(i).map_or(Ok(-1.0), |c| {
                c.parse::<f64>().map_err(|_| at(format!("column {} {c:?} is not a number", i + 1)))
            })
        };
        let integer = |i: usize| -> Result<i64> {
            let v = number(i)?;
            if v.fract() == 0.0 && v.abs() < 1e15 {
                Ok(v as i64)
            } else {
                Err(at(format!("column {} must be a whole number", i + 1)))
            }
        };
        let bbox =
            Box2d::new(number(2)? - 1.0, number(3)? - 1.0, number(4)?, number(5)?).map_err(|e| at(e.to_string()))?;
        rows.push(MotRow { frame: integer(0)?, id: integer(1)?, bbox, confidence: number(6)? });
    }
    Ok(rows)
}

/// Write MOTChallenge rows (1-based box origin again).
pub fn write_mot(path: &Path, rows: &[MotRow]) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    for r in rows {
        let b = &r.bbox;
        writeln!(
            w,
            "{},{},{:.3},{:.3},{:.3},{:.3},{:.4},-1,-1,-1",
            r.frame,
            r.id,
            b.x + 1.0,
            b.y + 1.0,
            b.w,
            b.h,
            r.confidence
        )?;
    }
    w.flush()
}
