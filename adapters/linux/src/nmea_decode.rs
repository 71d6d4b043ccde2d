//! `dash2sim nmea decode FILE`: an NMEA 0183 capture → one fix report per epoch.
//!
//! The bytes go through the core's framer and decoder exactly as on the device. Output
//! uses gpsd's TPV field names; every rejected sentence is reported on stderr with its
//! line number, and decoding continues after it.

use std::io::Write;
use std::path::Path;

use dash2sim_core::nmea::{Event, GnssFix, Stream, StreamEvent};
use serde_json::{json, Map, Value};

/// ISO 8601 UTC with milliseconds, as gpsd prints TPV times.
pub fn iso8601(micros: i64) -> String {
    let days = micros.div_euclid(86_400_000_000);
    let ms = micros.rem_euclid(86_400_000_000) / 1000;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{:03}Z",
        ms / 3_600_000,
        ms / 60_000 % 60,
        ms / 1000 % 60,
        ms % 1000
    )
}

/// A fix as a gpsd-style TPV object.
pub fn tpv_json(fix: &GnssFix) -> Value {
    let mut o = Map::new();
    o.insert("class".into(), json!("TPV"));
    o.insert("mode".into(), json!(fix.mode.gpsd()));
    if let Some(t) = fix.time() {
        o.insert("time".into(), json!(iso8601(t.micros())));
    }
    let mut put = |k: &str, v: Option<f64>| {
        if let Some(v) = v {
            o.insert(k.into(), json!(v));
        }
    };
    if fix.has_position() {
        put("lat", fix.lat);
        put("lon", fix.lon);
    }
    put("altHAE", fix.alt_hae());
    put("altMSL", fix.alt_msl);
    put("geoidSep", fix.geoid_sep);
    put("speed", fix.speed_mps);
    put("track", fix.track_deg);
    put("magvar", fix.mag_var_deg);
    put("heading", fix.heading_deg);
    put("hdop", fix.hdop);
    put("vdop", fix.vdop);
    put("pdop", fix.pdop);
    put("epy", fix.sigma_lat_m);
    put("epx", fix.sigma_lon_m);
    put("epv", fix.sigma_alt_m);
    if let Some(q) = fix.quality {
        o.insert("quality".into(), json!(q));
    }
    if let Some(n) = fix.satellites_used {
        o.insert("uSat".into(), json!(n));
    }
    Value::Object(o)
}

fn table_row(fix: &GnssFix) -> String {
    let t = fix.time().map_or_else(|| "-".to_owned(), |t| iso8601(t.micros()));
    let f = |v: Option<f64>, p: usize| v.map_or_else(|| "-".to_owned(), |v| format!("{v:.p$}"));
    let position = |v: Option<f64>| f(v.filter(|_| fix.has_position()), 9);
    format!(
        "{t:24} mode {} lat {:>13} lon {:>14} alt {:>9} speed {:>7} track {:>8} hdop {:>5} sats {}",
        fix.mode.gpsd(),
        position(fix.lat),
        position(fix.lon),
        f(fix.alt_msl, 2),
        f(fix.speed_mps, 3),
        f(fix.track_deg, 2),
        f(fix.hdop, 2),
        fix.satellites_used.map_or_else(|| "-".to_owned(), |n| n.to_string())
    )
}

/// Decode `path`; print fixes (JSON lines or a table) and a summary. A closed stdout
/// (`| head`) ends the output quietly.
pub fn run(path: &Path, as_json: bool) -> Result<(), String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = std::io::BufWriter::new(std::io::stdout().lock());
    match decode(path, &bytes, as_json, &mut out).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        Err(e) => Err(format!("writing output: {e}")),
    }
}

fn decode(path: &Path, bytes: &[u8], as_json: bool, out: &mut impl Write) -> std::io::Result<()> {
    let mut stream: Stream = Stream::new();
    let mut fixes = 0u64;
    let mut write_fix = |fix: &GnssFix, out: &mut dyn Write| -> std::io::Result<()> {
        fixes += 1;
        writeln!(out, "{}", if as_json { tpv_json(fix).to_string() } else { table_row(fix) })
    };
    let name = path.display();
    let mut result = Ok(());
    // Feed line by line so problems can name their line.
    for (index, line) in bytes.split_inclusive(|&b| b == b'\n').enumerate() {
        let line_no = index + 1;
        stream.feed(line, |event| match event {
            StreamEvent::Sentence(Event::Message { fix: Some(fix), .. }) => {
                if result.is_ok() {
                    result = write_fix(fix, out);
                }
            }
            StreamEvent::Sentence(Event::Message { .. }) => {}
            StreamEvent::Sentence(Event::BadSentence(e)) => eprintln!("{name}:{line_no}: {e}"),
            StreamEvent::Sentence(Event::BadFields(e)) => eprintln!("{name}:{line_no}: {e}"),
            StreamEvent::Dropped(e) => eprintln!("{name}:{line_no}: {e}"),
        });
        std::mem::replace(&mut result, Ok(()))?;
    }
    if let Some(fix) = stream.decoder.finish() {
        write_fix(&fix, out)?;
    }
    let (decoder, framer) = (&stream.decoder, &stream.framer);
    let s = decoder.stats();
    let f = framer.stats();
    let summary = json!({
        "class": "SUMMARY",
        "fixes": fixes,
        "sentences": f.sentences,
        "decoded": s.decoded,
        "unknown_or_proprietary": s.unknown,
        "rejected": {
            "bad_checksum": s.bad_checksum,
            "malformed": s.malformed,
            "bad_fields": s.bad_fields,
            "too_long": f.too_long,
            "binary": f.binary,
            "interrupted": f.interrupted,
        },
        "junk_bytes": f.junk_bytes,
    });
    if as_json {
        writeln!(out, "{summary}")
    } else {
        eprintln!("{summary}");
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso_times() {
        assert_eq!(iso8601(0), "1970-01-01T00:00:00.000Z");
        assert_eq!(iso8601(1_279_471_807_250_000), "2010-07-18T16:50:07.250Z");
    }
}
