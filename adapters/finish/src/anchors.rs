//! External anchors for `dash2sim finish --anchors F.csv` (`docs/finishing.md`).
//!
//! One anchor per line, in one of two forms named by the header:
//! * `t,lat,lon,alt,sigma_m` — the ego's rear axle was at this geodetic position at log
//!   time `t` (UTC seconds, as the log's records), e.g. a place-recognition match to a
//!   geotagged street image;
//! * `x,y,z,lat,lon,alt,sigma_m` — this point of the VO frame is at this geodetic
//!   position, e.g. a street-imagery camera registered into the same reconstruction.
//!
//! Blank lines and lines starting with `#` are skipped. A bad line is refused with its
//! reason and the rest are used: a wrong field count, a field that is not a finite
//! number, a latitude or longitude out of range, σ ≤ 0, and a duplicate of an earlier line
//! (same time, or same VO point).

use std::path::Path;

use dash2sim_core::geo::Geodetic;
use dash2sim_core::nalgebra::Vector3;
use dash2sim_linux::{Error, Result};

/// Where an anchor is, before it is put in a log's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AnchorForm {
    /// The rear axle at log time `t`, s.
    Time(f64),
    /// A point of the VO frame.
    VoPoint(Vector3<f64>),
}

/// One anchor line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnchorLine {
    /// 1-based line number.
    pub line: usize,
    /// What is anchored.
    pub at: AnchorForm,
    /// Where.
    pub position: Geodetic,
    /// 1-σ, m.
    pub sigma: f64,
}

/// An anchors file: the usable lines and the refused ones (`(line, reason)`).
#[derive(Clone, Debug, Default)]
pub struct AnchorFile {
    /// Anchors in file order.
    pub anchors: Vec<AnchorLine>,
    /// Lines refused, with why.
    pub refused: Vec<(usize, String)>,
}

const TIME_HEADER: &str = "t,lat,lon,alt,sigma_m";
const POINT_HEADER: &str = "x,y,z,lat,lon,alt,sigma_m";

/// Read an anchors file. The error (a file that cannot be read or has no valid header) is
/// `FILE:LINE: reason`; refused lines are in [`AnchorFile::refused`].
pub fn read(path: &Path) -> Result<AnchorFile> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    parse(&text).map_err(|(line, why)| Error::line(path, line, why))
}

/// Parse an anchors file's text (errors as `(line, reason)`).
pub fn parse(text: &str) -> Result<AnchorFile, (usize, String)> {
    let mut lines =
        text.lines().enumerate().map(|(i, l)| (i + 1, l.trim())).filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let Some((header_line, header)) = lines.next() else {
        return Err((1, format!("empty: expected the header `{TIME_HEADER}` or `{POINT_HEADER}`")));
    };
    let header: String = header.split(',').map(str::trim).collect::<Vec<_>>().join(",");
    let by_time = match header.as_str() {
        TIME_HEADER => true,
        POINT_HEADER => false,
        _ => return Err((header_line, format!("header `{header}`: expected `{TIME_HEADER}` or `{POINT_HEADER}`"))),
    };
    let fields = if by_time { 5 } else { 7 };
    let mut file = AnchorFile::default();
    for (line, text) in lines {
        match parse_line(text, fields, by_time) {
            Ok((at, position, sigma)) => {
                let duplicate = file.anchors.iter().find(|a| a.at == at);
                if let Some(first) = duplicate {
                    file.refused.push((line, format!("duplicate of line {}", first.line)));
                } else {
                    file.anchors.push(AnchorLine { line, at, position, sigma });
                }
            }
            Err(why) => file.refused.push((line, why.to_string())),
        }
    }
    Ok(file)
}

fn parse_line(text: &str, fields: usize, by_time: bool) -> Result<(AnchorForm, Geodetic, f64)> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != fields {
        return Err(Error::invalid(format!("{} fields, expected {fields}", parts.len())));
    }
    let mut v = Vec::with_capacity(fields);
    for (k, p) in parts.iter().enumerate() {
        let x: f64 = p.parse().map_err(|_| Error::invalid(format!("field {} `{p}` is not a number", k + 1)))?;
        if !x.is_finite() {
            return Err(Error::invalid(format!("field {} `{p}` is not finite", k + 1)));
        }
        v.push(x);
    }
    let (at, rest) = if by_time {
        (AnchorForm::Time(v[0]), &v[1..])
    } else {
        (AnchorForm::VoPoint(Vector3::new(v[0], v[1], v[2])), &v[3..])
    };
    let [lat, lon, alt, sigma] = rest else { return Err(Error::invalid("internal: field count")) };
    let position = Geodetic::new(*lat, *lon, *alt).map_err(|e| Error::refused(format!("position {lat},{lon}"), e))?;
    if *sigma <= 0.0 {
        return Err(Error::invalid(format!("sigma_m {sigma} must be positive")));
    }
    Ok((at, position, *sigma))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_forms_parse_and_bad_lines_are_refused_with_their_reason() {
        let file = parse(
            "t,lat,lon,alt,sigma_m\n# comment\n1.5,37.7,-122.4,30,0.3\n2.0,nan,-122.4,30,0.3\n2.5,37.7,-122.4,30\n\
             3.0,95,-122.4,30,0.3\n1.5,37.7,-122.4,31,0.3\n4.0,37.7,-122.4,30,0\n5,37.7,x,30,1\n",
        )
        .expect("valid header");
        assert_eq!(file.anchors.len(), 1);
        assert_eq!(file.anchors[0].line, 3);
        assert_eq!(file.anchors[0].at, AnchorForm::Time(1.5));
        let reasons: Vec<(usize, &str)> = file.refused.iter().map(|(l, r)| (*l, r.as_str())).collect();
        assert_eq!(reasons.len(), 6, "{reasons:?}");
        assert!(reasons[0].0 == 4 && reasons[0].1.contains("`nan` is not finite"), "{reasons:?}");
        assert_eq!(reasons[1], (5, "4 fields, expected 5"));
        assert!(reasons[2].0 == 6 && reasons[2].1.contains("95"));
        assert_eq!(reasons[3], (7, "duplicate of line 3"));
        assert!(reasons[4].0 == 8 && reasons[4].1.contains("must be positive"));
        assert!(reasons[5].0 == 9 && reasons[5].1.contains("`x` is not a number"));

        let points = parse("x, y, z, lat, lon, alt, sigma_m\n1,2,3,37.7,-122.4,30,0.5\n").expect("header");
        assert_eq!(points.anchors[0].at, AnchorForm::VoPoint(Vector3::new(1.0, 2.0, 3.0)));
        assert_eq!(points.anchors[0].sigma, 0.5);
    }

    #[test]
    fn a_file_without_a_known_header_is_an_error_naming_the_line() {
        assert_eq!(parse("").expect_err("no header").0, 1);
        let (line, why) = parse("\n# anchors\nlat,lon\n").expect_err("unknown header");
        assert_eq!(line, 3);
        assert!(why.contains("expected `t,lat,lon,alt,sigma_m`"), "{why}");
    }
}
