//! `dash2sim nmea decode FILE`: an NMEA 0183 capture → one fix report per epoch.
//!
//! The bytes go through the core's framer and decoder exactly as on the device. Fixes come
//! out with gpsd's TPV field names; every rejected sentence is reported with its line
//! number, and decoding continues after it.

use dash2sim_core::nmea::{Event, GnssFix, Stream, StreamEvent};
use serde_json::{json, Map, Value};

use crate::utc::iso8601;

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

/// Decode a capture as the device would: `on_fix` gets each epoch's fix (stopping at its
/// first error, which is returned), `on_problem` each rejected sentence or dropped bytes with
/// its line number (decoding goes on after it). The summary, gpsd-style (`class`
/// `SUMMARY`): fixes, sentences, what was rejected and why.
pub fn decode(
    bytes: &[u8],
    mut on_fix: impl FnMut(&GnssFix) -> std::io::Result<()>,
    mut on_problem: impl FnMut(usize, &dyn std::fmt::Display),
) -> std::io::Result<Value> {
    let mut stream: Stream = Stream::new();
    let mut fixes = 0u64;
    let mut result = Ok(());
    // Feed line by line so problems can name their line.
    for (index, line) in bytes.split_inclusive(|&b| b == b'\n').enumerate() {
        let line_no = index + 1;
        stream.feed(line, |event| match event {
            StreamEvent::Sentence(Event::Message { fix: Some(fix), .. }) => {
                if result.is_ok() {
                    fixes += 1;
                    result = on_fix(fix);
                }
            }
            StreamEvent::Sentence(Event::Message { .. }) => {}
            StreamEvent::Sentence(Event::BadSentence(e)) => on_problem(line_no, &e),
            StreamEvent::Sentence(Event::BadFields(e)) => on_problem(line_no, &e),
            StreamEvent::Dropped(e) => on_problem(line_no, &e),
        });
        std::mem::replace(&mut result, Ok(()))?;
    }
    if let Some(fix) = stream.decoder.finish() {
        fixes += 1;
        on_fix(&fix)?;
    }
    let (decoder, framer) = (&stream.decoder, &stream.framer);
    let s = decoder.stats();
    let f = framer.stats();
    Ok(json!({
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
    }))
}
