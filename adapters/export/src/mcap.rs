//! MCAP with Foxglove's JSON schemas, so a log opens in Foxglove with no plugin:
//!
//! | topic | schema | from |
//! |---|---|---|
//! | `/gnss` | `foxglove.LocationFix` | GNSS fixes |
//! | `/ego/location` | `foxglove.LocationFix` | anchored ego poses, as latitude/longitude |
//! | `/ego/pose` | `foxglove.PoseInFrame` | anchored ego poses in frame `enu` |
//! | `/tf` | `foxglove.FrameTransform` | `enu` → `ego` |
//! | `/vo/pose` | `foxglove.PoseInFrame` | VO poses in frame `vo` |
//! | `/objects` | `foxglove.SceneUpdate` | 3D tracks as cubes, one update per time |
//! | `/map` | `foxglove.SceneUpdate` | map lanes as line strips (with `--map`) |
//! | `/events` | `foxglove.Log` | events |
//! | `/speed` | `dash2sim.VehicleSpeed` | vehicle speed |
//! | `/anchor` | `dash2sim.AnchorEstimate` | the VO → ENU anchor and its quality |
//! | `/verification` | `dash2sim.Verification` | nuPlan-style metrics, score, verdict |
//! | `/imu` | `dash2sim.ImuRates` | the IMU's preintegrated intervals as mean rates: angular velocity (rad/s) and specific force (m/s²), the sensor's axes |
//! | `/imu/estimate` | `dash2sim.ImuEstimate` | the body's pitch and roll from gravity, the gyro's bias |
//!
//! Chunks are zstd-compressed; every record carries a CRC.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

use dash2sim_core::binlog::Record;
use dash2sim_core::map::MapView;
use mcap::records::MessageHeader;
use serde_json::{json, Value};

use dash2sim_core::class::name_of as class_name;
use dash2sim_linux::log::views::ego_enu;
use dash2sim_linux::log::{frame, LogContents};
use dash2sim_linux::{Error, Result};

/// JSON schemas for the messages written (the fields used, typed as Foxglove defines them).
const TIME: &str = r#"{"type":"object","properties":{"sec":{"type":"integer","minimum":0},"nsec":{"type":"integer","minimum":0,"maximum":999999999}}}"#;

fn schema(title: &str, properties: &str) -> String {
    format!(r#"{{"title":"{title}","type":"object","properties":{{{properties}}}}}"#)
}

fn vec3() -> String {
    r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"}}}"#.to_owned()
}

fn pose() -> String {
    let v = vec3();
    format!(
        r#"{{"type":"object","properties":{{"position":{v},"orientation":{{"type":"object","properties":{{"x":{{"type":"number"}},"y":{{"type":"number"}},"z":{{"type":"number"}},"w":{{"type":"number"}}}}}}}}}}"#
    )
}

fn schemas() -> Vec<(&'static str, String)> {
    let (p, v) = (pose(), vec3());
    let quaternion = r#"{"type":"object","properties":{"x":{"type":"number"},"y":{"type":"number"},"z":{"type":"number"},"w":{"type":"number"}}}"#;
    let color = r#"{"type":"object","properties":{"r":{"type":"number"},"g":{"type":"number"},"b":{"type":"number"},"a":{"type":"number"}}}"#;
    vec![
        (
            "foxglove.LocationFix",
            schema(
                "foxglove.LocationFix",
                &format!(
                    r#""timestamp":{TIME},"frame_id":{{"type":"string"}},"latitude":{{"type":"number"}},"longitude":{{"type":"number"}},"altitude":{{"type":"number"}},"position_covariance":{{"type":"array","items":{{"type":"number"}},"minItems":9,"maxItems":9}},"position_covariance_type":{{"type":"integer"}}"#
                ),
            ),
        ),
        (
            "foxglove.PoseInFrame",
            schema("foxglove.PoseInFrame", &format!(r#""timestamp":{TIME},"frame_id":{{"type":"string"}},"pose":{p}"#)),
        ),
        (
            "foxglove.FrameTransform",
            schema(
                "foxglove.FrameTransform",
                &format!(
                    r#""timestamp":{TIME},"parent_frame_id":{{"type":"string"}},"child_frame_id":{{"type":"string"}},"translation":{v},"rotation":{quaternion}"#
                ),
            ),
        ),
        (
            "foxglove.SceneUpdate",
            schema(
                "foxglove.SceneUpdate",
                &format!(
                    r#""deletions":{{"type":"array","items":{{"type":"object"}}}},"entities":{{"type":"array","items":{{"type":"object","properties":{{"timestamp":{TIME},"frame_id":{{"type":"string"}},"id":{{"type":"string"}},"lifetime":{TIME},"frame_locked":{{"type":"boolean"}},"metadata":{{"type":"array"}},"cubes":{{"type":"array","items":{{"type":"object","properties":{{"pose":{p},"size":{v},"color":{color}}}}}}},"lines":{{"type":"array","items":{{"type":"object","properties":{{"type":{{"type":"integer"}},"pose":{p},"thickness":{{"type":"number"}},"scale_invariant":{{"type":"boolean"}},"points":{{"type":"array","items":{v}}},"color":{color},"colors":{{"type":"array"}},"indices":{{"type":"array"}}}}}}}}}}}}}}"#
                ),
            ),
        ),
        (
            "foxglove.Log",
            schema(
                "foxglove.Log",
                &format!(
                    r#""timestamp":{TIME},"level":{{"type":"integer"}},"message":{{"type":"string"}},"name":{{"type":"string"}},"file":{{"type":"string"}},"line":{{"type":"integer","minimum":0}}"#
                ),
            ),
        ),
        (
            "dash2sim.VehicleSpeed",
            schema(
                "dash2sim.VehicleSpeed",
                &format!(r#""timestamp":{TIME},"speed_mps":{{"type":"number"}},"source":{{"type":"string"}}"#),
            ),
        ),
        (
            "dash2sim.AnchorEstimate",
            schema(
                "dash2sim.AnchorEstimate",
                &format!(
                    r#""timestamp":{TIME},"scale":{{"type":"number"}},"yaw_rad":{{"type":"number"}},"pitch_rad":{{"type":"number"}},"roll_rad":{{"type":"number"}},"translation":{v},"observability":{{"type":"string"}},"anchors":{{"type":"integer","minimum":0}},"rms_residual_m":{{"type":"number","minimum":0}},"gnss_latency_s":{{"type":"number"}}"#
                ),
            ),
        ),
        (
            "dash2sim.ImuRates",
            schema(
                "dash2sim.ImuRates",
                &format!(
                    r#""timestamp":{TIME},"interval_s":{{"type":"number","minimum":0}},"angular_velocity":{v},"specific_force":{v},"samples":{{"type":"integer","minimum":0}}"#
                ),
            ),
        ),
        (
            "dash2sim.ImuEstimate",
            schema(
                "dash2sim.ImuEstimate",
                &format!(
                    r#""timestamp":{TIME},"pitch_rad":{{"type":"number"}},"roll_rad":{{"type":"number"}},"gyro_bias":{v},"gyro_bias_sigma":{{"type":"number","minimum":0}},"standstills":{{"type":"integer","minimum":0}},"courses":{{"type":"integer","minimum":0}}"#
                ),
            ),
        ),
        (
            "dash2sim.Verification",
            schema(
                "dash2sim.Verification",
                &format!(
                    r#""timestamp":{TIME},"metrics":{{"type":"object","additionalProperties":{{"type":"number","minimum":0,"maximum":1}}}},"score":{{"type":"number","minimum":0,"maximum":100}},"verified":{{"type":"boolean"}},"worst_corner_outside_m":{{"type":"number"}},"decision":{{"type":"string","enum":["verified","rejected","undecided"]}},"score_interval":{{"type":"array","items":{{"type":"number","minimum":0,"maximum":100}},"minItems":2,"maxItems":2}}"#
                ),
            ),
        ),
    ]
}

fn observability_name(code: i64) -> &'static str {
    match code {
        2 => "observable",
        1 => "collinear",
        _ => "none",
    }
}

fn time(t_us: i64) -> Value {
    let t = t_us.max(0);
    json!({"sec": t / 1_000_000, "nsec": (t % 1_000_000) * 1000})
}

fn quaternion_z(yaw: f64) -> Value {
    let (s, c) = (yaw / 2.0).sin_cos();
    json!({"x": 0.0, "y": 0.0, "z": s, "w": c})
}

fn location_fix(t_us: i64, frame_id: &str, lat: f64, lon: f64, alt: f64) -> Value {
    json!({
        "timestamp": time(t_us),
        "frame_id": frame_id,
        "latitude": lat,
        "longitude": lon,
        "altitude": alt,
        "position_covariance": [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        "position_covariance_type": 0,
    })
}

fn entity(t_us: i64, id: String, lifetime_us: i64) -> serde_json::Map<String, Value> {
    let mut e = serde_json::Map::new();
    e.insert("timestamp".into(), time(t_us));
    e.insert("frame_id".into(), json!("enu"));
    e.insert("id".into(), json!(id));
    e.insert("lifetime".into(), time(lifetime_us));
    e.insert("frame_locked".into(), json!(false));
    e.insert("metadata".into(), json!([]));
    for k in ["arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"] {
        e.insert(k.into(), json!([]));
    }
    e
}

const SPEED_SOURCES: [&str; 5] = ["wheel", "J1939 CCVS1", "OBD-II", "DBC", "NMEA 2000 SOG"];

/// The messages of a log: (topic, schema, time µs, JSON), in time order per topic.
pub fn messages(log: &LogContents, map: Option<&MapView<'_>>) -> Vec<(&'static str, &'static str, i64, Value)> {
    let enu = log.header.as_ref().and_then(frame);
    let mut out = Vec::new();
    let mut scenes: BTreeMap<i64, Vec<Value>> = BTreeMap::new();
    for r in &log.records {
        match r {
            Record::GnssFix(f) => out.push((
                "/gnss",
                "foxglove.LocationFix",
                f.t_us,
                location_fix(f.t_us, "gnss", f.lat_e7 as f64 * 1e-7, f.lon_e7 as f64 * 1e-7, f.alt_mm as f64 * 1e-3),
            )),
            Record::EgoPose(p) => {
                let (v, yaw) = ego_enu(p);
                let pose = json!({"position": {"x": v.x, "y": v.y, "z": v.z}, "orientation": quaternion_z(yaw)});
                out.push(("/ego/pose", "foxglove.PoseInFrame", p.t_us, json!({"timestamp": time(p.t_us), "frame_id": "enu", "pose": pose})));
                out.push((
                    "/tf",
                    "foxglove.FrameTransform",
                    p.t_us,
                    json!({"timestamp": time(p.t_us), "parent_frame_id": "enu", "child_frame_id": "ego",
                           "translation": {"x": v.x, "y": v.y, "z": v.z}, "rotation": quaternion_z(yaw)}),
                ));
                if let Some(g) = enu.as_ref().and_then(|f| f.enu_to_geodetic(&v).ok()) {
                    out.push(("/ego/location", "foxglove.LocationFix", p.t_us, location_fix(p.t_us, "ego", g.lat_deg, g.lon_deg, g.height_m)));
                }
            }
            Record::VoPose(p) => {
                let pose = json!({"position": {"x": p.x as f64 * 1e-3, "y": p.y as f64 * 1e-3, "z": p.z as f64 * 1e-3},
                                  "orientation": quaternion_z(p.yaw_e4 as f64 * 1e-4)});
                out.push(("/vo/pose", "foxglove.PoseInFrame", p.t_us, json!({"timestamp": time(p.t_us), "frame_id": "vo", "pose": pose})));
            }
            Record::Tracks3d(batch) => {
                for t in &batch.tracks {
                    let mut e = entity(batch.t_us, format!("track-{}", t.id), 200_000);
                    e.insert(
                        "metadata".into(),
                        json!([{"key": "class", "value": class_name(t.class)}, {"key": "static", "value": (t.is_static != 0).to_string()}]),
                    );
                    let color = if t.is_static != 0 {
                        json!({"r": 1.0, "g": 0.5, "b": 0.0, "a": 0.8})
                    } else {
                        json!({"r": 0.2, "g": 0.6, "b": 1.0, "a": 0.8})
                    };
                    e.insert(
                        "cubes".into(),
                        json!([{
                            "pose": {"position": {"x": t.x_mm as f64 * 1e-3, "y": t.y_mm as f64 * 1e-3, "z": t.z_mm as f64 * 1e-3},
                                     "orientation": quaternion_z(t.yaw_e4 as f64 * 1e-4)},
                            "size": {"x": t.l_mm as f64 * 1e-3, "y": t.w_mm as f64 * 1e-3, "z": t.h_mm as f64 * 1e-3},
                            "color": color,
                        }]),
                    );
                    scenes.entry(batch.t_us).or_default().push(Value::Object(e));
                }
            }
            Record::AnchorEstimate(a) => out.push((
                "/anchor",
                "dash2sim.AnchorEstimate",
                a.t_us,
                json!({
                    "timestamp": time(a.t_us),
                    "scale": a.scale_e6 as f64 * 1e-6,
                    "yaw_rad": a.yaw_e6 as f64 * 1e-6,
                    "pitch_rad": a.pitch_e6 as f64 * 1e-6,
                    "roll_rad": a.roll_e6 as f64 * 1e-6,
                    "translation": {"x": a.tx_mm as f64 * 1e-3, "y": a.ty_mm as f64 * 1e-3, "z": a.tz_mm as f64 * 1e-3},
                    "observability": observability_name(a.observability),
                    "anchors": a.anchors.max(0),
                    "rms_residual_m": a.rms_mm.max(0) as f64 * 1e-3,
                    "gnss_latency_s": a.latency_us as f64 * 1e-6,
                }),
            )),
            Record::Verification(v) => {
                let m = |x: i64| (x as f64 * 1e-4).clamp(0.0, 1.0);
                let score = (v.score_e2 as f64 * 1e-2).clamp(0.0, 100.0);
                let mut message = json!({
                        "timestamp": time(v.t_us),
                        "metrics": {
                            "no_at_fault_collisions": m(v.collisions_e4),
                            "drivable_area_compliance": m(v.drivable_e4),
                            "driving_direction_compliance": m(v.direction_e4),
                            "ego_is_making_progress": m(v.making_progress_e4),
                            "ego_progress_along_expert_route": m(v.progress_e4),
                            "time_to_collision_within_bound": m(v.ttc_e4),
                            "speed_limit_compliance": m(v.speed_limit_e4),
                            "ego_is_comfortable": m(v.comfort_e4),
                        },
                        "score": score,
                        "verified": score > dash2sim_core::score::VERIFIED_ABOVE,
                        "worst_corner_outside_m": v.worst_corner_mm as f64 * 1e-3,
                    });
                // A finished window's decision with the log's doubt (a device's has none).
                if let (Some(decision), Some(object)) = (v.decision_name(), message.as_object_mut()) {
                    let interval = [v.score_low_e2, v.score_high_e2].map(|x| (x as f64 * 1e-2).clamp(0.0, 100.0));
                    object.insert("decision".to_owned(), json!(decision));
                    object.insert("score_interval".to_owned(), json!(interval));
                }
                out.push(("/verification", "dash2sim.Verification", v.t_us, message));
            }
            Record::VehicleSpeed(s) => out.push((
                "/speed",
                "dash2sim.VehicleSpeed",
                s.t_us,
                json!({"timestamp": time(s.t_us), "speed_mps": s.speed_mm_s as f64 * 1e-3,
                       "source": usize::try_from(s.source).ok().and_then(|i| SPEED_SOURCES.get(i)).copied().unwrap_or("other")}),
            )),
            Record::ImuDelta(d) if d.dt_us > 0 => {
                // Mean rates over the interval: what a plot of a gyro and an accelerometer shows.
                let per_s = 1e6 / d.dt_us as f64;
                let rate = |e6: i64| e6 as f64 * 1e-6 * per_s;
                let force = |mm_s: i64| mm_s as f64 * 1e-3 * per_s;
                out.push((
                    "/imu",
                    "dash2sim.ImuRates",
                    d.t_us,
                    json!({"timestamp": time(d.t_us), "interval_s": d.dt_us as f64 * 1e-6,
                           "angular_velocity": {"x": rate(d.dtheta_x_e6), "y": rate(d.dtheta_y_e6), "z": rate(d.dtheta_z_e6)},
                           "specific_force": {"x": force(d.dv_x_mm_s), "y": force(d.dv_y_mm_s), "z": force(d.dv_z_mm_s)},
                           "samples": d.samples.max(0)}),
                ));
            }
            Record::ImuEstimate(e) => out.push((
                "/imu/estimate",
                "dash2sim.ImuEstimate",
                e.t_us,
                json!({"timestamp": time(e.t_us), "pitch_rad": e.pitch_e6 as f64 * 1e-6, "roll_rad": e.roll_e6 as f64 * 1e-6,
                       "gyro_bias": {"x": e.bias_x_e7 as f64 * 1e-7, "y": e.bias_y_e7 as f64 * 1e-7, "z": e.bias_z_e7 as f64 * 1e-7},
                       "gyro_bias_sigma": (e.bias_sigma_e7 as f64 * 1e-7).max(0.0),
                       "standstills": e.standstills.max(0), "courses": e.courses.max(0)}),
            )),
            Record::Event(e) => out.push((
                "/events",
                "foxglove.Log",
                e.t_us,
                json!({"timestamp": time(e.t_us), "level": e.level.min(5), "message": String::from_utf8_lossy(&e.text),
                       "name": "dash2sim", "file": "", "line": 0}),
            )),
            _ => {}
        }
    }
    for (t, entities) in scenes {
        out.push(("/objects", "foxglove.SceneUpdate", t, json!({"deletions": [], "entities": entities})));
    }
    if let Some(map) = map {
        let t0 = log.records.first().map_or(0, Record::t_us);
        let mut e = entity(t0, "map-lanes".to_owned(), 0);
        let lines: Vec<Value> = (0..map.header().lanes)
            .filter_map(|i| map.lane(i))
            .map(|lane| {
                json!({
                    "type": 0,
                    "pose": {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}},
                    "thickness": 0.15,
                    "scale_invariant": false,
                    "points": lane.points().map(|(x, y)| json!({"x": x, "y": y, "z": 0.0})).collect::<Vec<_>>(),
                    "color": {"r": 0.8, "g": 0.8, "b": 0.8, "a": 1.0},
                    "colors": [],
                    "indices": [],
                })
            })
            .collect();
        e.insert("lines".into(), Value::Array(lines));
        out.push(("/map", "foxglove.SceneUpdate", t0, json!({"deletions": [], "entities": [Value::Object(e)]})));
    }
    out.sort_by_key(|m| m.2);
    out
}

/// One topic per record kind: the log's content once, for size comparisons.
pub const ONE_TOPIC_PER_KIND: [&str; 7] =
    ["/gnss", "/ego/pose", "/speed", "/objects", "/events", "/anchor", "/verification"];

/// Write the MCAP (all topics, or only `topics`); returns messages per topic.
pub fn write(
    log: &LogContents,
    map: Option<&MapView<'_>>,
    path: &Path,
    topics: Option<&[&str]>,
) -> Result<BTreeMap<&'static str, u64>> {
    let err = |e: mcap::McapError| Error::file(path, e);
    let file = std::fs::File::create(path).map_err(|e| Error::file(path, e))?;
    let options = mcap::WriteOptions::new().compression(Some(mcap::Compression::Zstd)).profile("");
    let mut writer = mcap::Writer::with_options(BufWriter::new(file), options).map_err(err)?;
    // A schema is written with the first channel that uses it: a log without an IMU carries
    // no IMU schema.
    let known: BTreeMap<&'static str, String> = schemas().into_iter().collect();
    let mut schema_ids: BTreeMap<&'static str, u16> = BTreeMap::new();
    let mut channels: BTreeMap<&'static str, u16> = BTreeMap::new();
    let mut counts: BTreeMap<&'static str, u64> = BTreeMap::new();
    for (topic, schema_name, t_us, message) in messages(log, map) {
        if topics.is_some_and(|keep| !keep.contains(&topic)) {
            continue;
        }
        let channel = match channels.get(topic) {
            Some(&c) => c,
            None => {
                let schema = match (schema_ids.get(schema_name), known.get(schema_name)) {
                    (Some(&id), _) => id,
                    (None, Some(text)) => {
                        let id = writer.add_schema(schema_name, "jsonschema", text.as_bytes()).map_err(err)?;
                        schema_ids.insert(schema_name, id);
                        id
                    }
                    (None, None) => 0,
                };
                let c = writer.add_channel(schema, topic, "json", &BTreeMap::new()).map_err(err)?;
                channels.insert(topic, c);
                c
            }
        };
        let count = counts.entry(topic).or_insert(0);
        let ns = u64::try_from(t_us.max(0)).unwrap_or(0) * 1000;
        let header = MessageHeader { channel_id: channel, sequence: *count as u32, log_time: ns, publish_time: ns };
        writer.write_to_known_channel(&header, message.to_string().as_bytes()).map_err(err)?;
        *count += 1;
    }
    writer.finish().map_err(err)?;
    Ok(counts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::binlog::{ImuDelta, ImuEstimate};

    #[test]
    fn the_imu_s_intervals_become_plottable_rates_and_its_estimate_a_message_of_its_own() {
        let log = LogContents {
            records: vec![
                Record::ImuDelta(ImuDelta {
                    t_us: 100_000,
                    dt_us: 100_000,
                    dtheta_z_e6: 5_000,
                    dv_z_mm_s: 981,
                    samples: 10,
                    ..ImuDelta::default()
                }),
                Record::ImuEstimate(ImuEstimate {
                    t_us: 200_000,
                    pitch_e6: 30_000,
                    bias_z_e7: -683_600,
                    ..Default::default()
                }),
            ],
            header: None,
            damage: Vec::new(),
            stats: Default::default(),
            bytes: 0,
            signing: Vec::new(),
        };
        let m = messages(&log, None);
        let (topic, schema, t, imu) = &m[0];
        assert_eq!((*topic, *schema, *t), ("/imu", "dash2sim.ImuRates", 100_000));
        assert!((imu["angular_velocity"]["z"].as_f64().unwrap_or(0.0) - 0.05).abs() < 1e-12, "{imu}");
        assert!((imu["specific_force"]["z"].as_f64().unwrap_or(0.0) - 9.81).abs() < 1e-9, "{imu}");
        let (topic, _, _, estimate) = &m[1];
        assert_eq!(*topic, "/imu/estimate");
        assert!((estimate["gyro_bias"]["z"].as_f64().unwrap_or(0.0) + 0.06836).abs() < 1e-12, "{estimate}");
        assert!(schemas().iter().any(|(name, _)| *name == "dash2sim.ImuRates"));
    }

    /// A finished window's decision and score interval reach the file (read back through
    /// the `mcap` crate's reader, CRCs checked); a device's window, which decides nothing,
    /// has neither.
    #[test]
    fn a_windows_decision_is_in_the_file_and_a_devices_window_has_none() {
        use dash2sim_core::binlog::{Verification, DECISION_UNDECIDED};
        let window = |t_us, decision, low, high| {
            Record::Verification(Verification {
                t_us,
                score_e2: 9_300,
                decision,
                score_low_e2: low,
                score_high_e2: high,
                ..Verification::default()
            })
        };
        let log = LogContents {
            records: vec![window(1_000_000, 0, 0, 0), window(2_000_000, DECISION_UNDECIDED, 4_550, 9_700)],
            header: None,
            damage: Vec::new(),
            stats: Default::default(),
            bytes: 0,
            signing: Vec::new(),
        };
        let path = std::env::temp_dir().join(format!("dash2sim-mcap-decision-{}.mcap", std::process::id()));
        let counts = write(&log, None, &path, None).expect("write");
        assert_eq!(counts.get("/verification"), Some(&2));
        let bytes = std::fs::read(&path).expect("read");
        let _ = std::fs::remove_file(&path);
        let messages: Vec<Value> = mcap::MessageStream::new(&bytes)
            .expect("an MCAP file")
            .map(|m| m.expect("a message"))
            .filter(|m| m.channel.topic == "/verification")
            .map(|m| serde_json::from_slice(&m.data).expect("JSON"))
            .collect();
        let [device, finished] = &messages[..] else { panic!("two windows: {messages:?}") };
        assert!(device.get("decision").is_none() && device.get("score_interval").is_none(), "{device}");
        assert_eq!(device["verified"], json!(true));
        assert_eq!(finished["decision"], json!("undecided"), "{finished}");
        assert_eq!(finished["score_interval"], json!([45.5, 97.0]), "{finished}");
    }
}
