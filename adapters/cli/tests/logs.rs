//! The `dash2sim` binary end to end — a log's life after recording: `import`, `inspect`, `finish`, `export` (TUM, GeoJSON, MCAP, nuPlan, CommonRoad, Parquet) and `plot`: output shape, exit status and error messages.

mod common;

use std::path::{Path, PathBuf};

use common::*;

#[test]
fn import_inspect_export_a_drive_and_report_damage_without_failing() {
    let dir = scratch("binlog");
    let drive = dir.join("drive");
    let out = generate_ideal(&drive, "2", "12");
    assert!(out.status.success(), "{}", stderr(&out));
    let file = |name: &str| drive.join(name).display().to_string();
    let log = dir.join("drive.d2slog").display().to_string();
    let out = dash2sim(&[
        "import",
        "-o",
        &log,
        "--nmea",
        &file("gnss.nmea"),
        "--nmea-offset",
        "-1780300800",
        "--traj",
        &file("ego.tum"),
        "--objects",
        &file("objects.csv"),
        "--origin",
        "60.2711,24.8572",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = dash2sim(&["inspect", &log, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(report["by_type"]["EgoPose"], 121, "{report}");
    assert_eq!(report["by_type"]["GnssFix"], 61, "{report}");
    assert_eq!(report["damaged"], 0);
    assert!(report["t_start"].as_f64().is_some_and(|t| t.abs() < 0.2), "{report}");
    assert!(report["records"].as_u64().is_some_and(|n| n > 121 + 61));

    let (tum, geojson, mcap) = (
        dir.join("ego.tum").display().to_string(),
        dir.join("drive.geojson").display().to_string(),
        dir.join("drive.mcap").display().to_string(),
    );
    let map = dir.join("road.map").display().to_string();
    let out = dash2sim(&["map", "build", &file("road.osm"), "-o", &map, "--origin", "60.2711,24.8572"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let out = dash2sim(&["export", &log, "--tum", &tum, "--geojson", &geojson, "--mcap", &mcap, "--map", &map]);
    assert!(out.status.success(), "{}", stderr(&out));
    // The exported TUM is the imported one, to the millimetre.
    let out = dash2sim(&["traj", "ape", &file("ego.tum"), &tum, "--json"]);
    let ape: serde_json::Value = serde_json::from_slice(&out.stdout).expect("ape json");
    assert!(ape["stats"]["max"].as_f64().is_some_and(|m| m < 1e-3), "{ape}");
    let g: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&geojson).expect("geojson")).expect("json");
    let features = g["features"].as_array().expect("features");
    assert_eq!(features[0]["geometry"]["type"], "LineString");
    assert!(features.iter().filter(|f| f["geometry"]["type"] == "Point").count() > 20, "the work zone's objects");
    // verify LOG replays the log's ego poses with its tracks as agents: the same verdict
    // as the trajectory and objects it was imported from.
    let score = |args: &[&str]| -> serde_json::Value {
        let out = dash2sim(args);
        assert!(out.status.success(), "{}", stderr(&out));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        v["metrics"].clone()
    };
    let from_log = score(&["verify", &log, "--map", &map, "--json"]);
    let from_files =
        score(&["verify", "--map", &map, "--ego", &file("ego.tum"), "--objects", &file("objects.csv"), "--json"]);
    assert_eq!(from_log, from_files);
    let mcap_bytes = std::fs::read(&mcap).expect("mcap");
    assert!(mcap_bytes.starts_with(b"\x89MCAP0\r\n") && mcap_bytes.ends_with(b"\x89MCAP0\r\n"));

    // Damage: cut the tail and flip a byte in the middle — reported, exit status 0.
    let mut bytes = std::fs::read(&log).expect("log");
    bytes.truncate(bytes.len() - 7);
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x40;
    let damaged = write(&dir, "damaged.d2slog", "");
    std::fs::write(&damaged, &bytes).expect("write");
    let out = dash2sim(&["inspect", &damaged, "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert!(r["damaged"].as_u64().is_some_and(|d| d >= 2), "{r}");
    assert!(r["records"].as_u64() < report["records"].as_u64() && r["records"].as_u64() > Some(100), "{r}");
    // Not a log at all: an error.
    let out = dash2sim(&["inspect", &file("ego.tum")]);
    assert!(!out.status.success() && stderr(&out).contains("not a dash2sim log"), "{}", stderr(&out));
    let out = dash2sim(&["import", "-o", &log]);
    assert!(!out.status.success() && stderr(&out).contains("nothing to import"), "{}", stderr(&out));
}

#[test]
fn finish_reports_bad_anchor_lines_verifies_per_window_and_refuses_a_log_without_vo() {
    let dir = scratch("finish");
    let out = demo_ideal_offline(&dir, "20");
    assert!(out.status.success(), "{}", stderr(&out));
    let anchors = dir.join("anchors.csv");
    let mut text = std::fs::read_to_string(&anchors).expect("anchors");
    let good = text.lines().filter(|l| !l.starts_with('#')).count() - 1;
    text += "12.5,nan,24.9,10,0.3\n";
    std::fs::write(&anchors, &text).expect("write");
    let (log, map, finished) = (dir.join("drive.d2slog"), dir.join("road.map"), dir.join("again.d2slog"));
    let path = |p: &Path| p.display().to_string();
    let out = dash2sim(&[
        "finish",
        &path(&log),
        "-o",
        &path(&finished),
        "--anchors",
        &path(&anchors),
        "--map",
        &path(&map),
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let bad_line = text.lines().count();
    assert!(stderr(&out).contains(&format!("anchors.csv:{bad_line}: field 2 `nan` is not finite")), "{}", stderr(&out));
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(r["anchors"]["used"], good, "{r}");
    assert_eq!(r["anchors"]["refused"][0]["line"], bad_line, "{r}");
    let windows = r["verification"]["windows"].as_array().expect("windows");
    assert!(!windows.is_empty() && windows.iter().all(|w| w["channel_sensitive"]["score"].is_number()), "{r}");
    // The finished log is a log: inspect reads it, verify scores it as finish did.
    let inspect: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["inspect", &path(&finished), "--json"]).stdout).expect("json");
    assert!(inspect["by_type"]["EgoPose"].as_u64().is_some_and(|n| n > 150), "{inspect}");
    let verify: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["verify", &path(&finished), "--map", &path(&map), "--json"]).stdout)
            .expect("json");
    let drive = &r["verification"]["drive"]["channel_insensitive"]["score"];
    assert!((verify["score"].as_f64().expect("score") - drive.as_f64().expect("score")).abs() < 1e-9, "{verify}");
    // Human output.
    let out = dash2sim(&["finish", &path(&log), "-o", &path(&finished), "--map", &path(&map)]);
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("verification  drive"));
    // A log without VO poses: nothing to re-anchor.
    let gnss_only = dir.join("gnss-only.d2slog");
    let nmea = dir.join("drive/gnss.nmea");
    assert!(dash2sim(&["import", "-o", &path(&gnss_only), "--nmea", &path(&nmea)]).status.success());
    let out = dash2sim(&["finish", &path(&gnss_only), "-o", &path(&finished)]);
    assert!(!out.status.success() && stderr(&out).contains("no trajectory to re-anchor"), "{}", stderr(&out));
    // A bad anchors header names the line.
    std::fs::write(&anchors, "lat,lon\n").expect("write");
    let out = dash2sim(&["finish", &path(&log), "-o", &path(&finished), "--anchors", &path(&anchors)]);
    assert!(!out.status.success() && stderr(&out).contains("anchors.csv:1: header"), "{}", stderr(&out));
}

#[test]
fn export_nuplan_writes_the_devkits_tables_and_layers_and_refuses_bad_input() {
    let dir = scratch("nuplan");
    let out = demo_ideal_offline(&dir, "30");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |p: &Path| p.display().to_string();
    let (log, map, nuplan) = (dir.join("finished.d2slog"), dir.join("road.map"), dir.join("nuplan"));
    let out = dash2sim(&["export", &path(&log), "--nuplan", &path(&nuplan), "--map", &path(&map)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let dbs: Vec<PathBuf> =
        std::fs::read_dir(nuplan.join("db")).expect("db").map(|e| e.expect("entry").path()).collect();
    assert_eq!(dbs.len(), 1, "{dbs:?}");
    let name = dbs[0].file_name().and_then(|n| n.to_str()).unwrap_or_default().to_owned();
    // The drive starts at 08:00:00 UTC; the finished log's UTC is the world's (`finish`
    // moved it by the receiver's latency), so its first record is not before.
    assert!(name.starts_with("2026.06.01.08.00") && name.ends_with("_dash2sim_finished.db"), "{name}");
    let db = rusqlite::Connection::open(&dbs[0]).expect("sqlite");
    let one = |sql: &str| -> i64 { db.query_row(sql, [], |r| r.get(0)).expect(sql) };
    // The clock: exactly 20 Hz, one ego pose per tick, 30 s of drive.
    let ticks = one("SELECT COUNT(*) FROM lidar_pc");
    assert_eq!(ticks, one("SELECT COUNT(*) FROM ego_pose"));
    assert!((590..=602).contains(&ticks), "{ticks}");
    assert_eq!(one("SELECT MAX(timestamp) - MIN(timestamp) FROM lidar_pc"), (ticks - 1) * 50_000);
    assert_eq!(one("SELECT COUNT(DISTINCT timestamp) FROM lidar_pc"), ticks);
    assert_eq!(one("SELECT COUNT(*) FROM lidar_pc WHERE next_token IS NULL"), 1);
    assert_eq!(one("SELECT COUNT(*) FROM scene"), 6);
    assert_eq!(one("SELECT LENGTH(token) FROM scene LIMIT 1"), 8);
    assert_eq!(one("SELECT COUNT(*) FROM lidar WHERE channel = 'MergedPointCloud'"), 1);
    // The work zone's objects, by nuPlan category, every box on a tick of the clock.
    for category in ["traffic_cone", "barrier", "czone_sign"] {
        let n = one(&format!(
            "SELECT COUNT(*) FROM track t JOIN category c ON t.category_token = c.token WHERE c.name = '{category}'"
        ));
        assert!(n > 0, "{category}");
    }
    assert_eq!(
        one(
            "SELECT COUNT(*) FROM lidar_box b LEFT JOIN lidar_pc p ON b.lidar_pc_token = p.token WHERE p.token IS NULL"
        ),
        0
    );
    // Every scene has a route of real roadblocks.
    let routes: Vec<String> = db
        .prepare("SELECT roadblock_ids FROM scene ORDER BY name")
        .expect("query")
        .query_map([], |r| r.get(0))
        .expect("rows")
        .collect::<Result<_, _>>()
        .expect("routes");
    assert!(
        routes.iter().all(|r| r.split(' ').all(|id| id.parse::<i64>().is_ok_and(|id| id >= 1_000_000))),
        "{routes:?}"
    );
    // The map: a GeoPackage with the layers nuPlan reads, in UTM 35N, lanes' ids apart from
    // roadblocks'.
    let gpkg = rusqlite::Connection::open(nuplan.join("maps/dash2sim-road/9.17.1964/map.gpkg")).expect("gpkg");
    let g = |sql: &str| -> i64 { gpkg.query_row(sql, [], |r| r.get(0)).expect(sql) };
    assert_eq!(g("PRAGMA application_id"), 0x4750_4B47);
    assert_eq!(g("SELECT COUNT(*) FROM gpkg_contents WHERE data_type = 'features'"), 14);
    assert_eq!(g("SELECT srs_id FROM gpkg_geometry_columns WHERE table_name = 'lanes_polygons'"), 32635);
    assert!(g("SELECT MAX(fid) FROM lanes_polygons") < 1_000_000);
    assert!(g("SELECT MIN(fid) FROM lane_groups_polygons") > 1_000_000);
    assert!(g("SELECT COUNT(*) FROM generic_drivable_areas") > 100);
    let maps: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(nuplan.join("maps/nuplan-maps-v1.0.json")).expect("json"))
            .expect("json");
    assert_eq!(maps["dash2sim-road"]["version"], "9.17.1964");

    // `verify --from/--to` scores one scenario's window, as the nuPlan cross-check asks it.
    let all: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["verify", &path(&log), "--map", &path(&map), "--json"]).stdout)
            .expect("json");
    let start = one("SELECT MIN(timestamp) FROM lidar_pc") as f64 * 1e-6;
    let (from, to) = (format!("{:.3}", start + 5.0), format!("{:.3}", start + 20.0));
    let window: serde_json::Value = serde_json::from_slice(
        &dash2sim(&["verify", &path(&log), "--map", &path(&map), "--json", "--from", &from, "--to", &to]).stdout,
    )
    .expect("json");
    let (n_all, n_window) = (all["poses"].as_u64().expect("poses"), window["poses"].as_u64().expect("poses"));
    assert!(n_window < n_all && (140..=160).contains(&n_window), "{n_window} of {n_all}");
    let out = dash2sim(&["verify", &path(&log), "--map", &path(&map), "--from", "0", "--to", "1"]);
    assert!(!out.status.success() && stderr(&out).contains("no ego poses between"), "{}", stderr(&out));

    // Bad input: nothing is left behind.
    let fresh = dir.join("refused");
    let out =
        dash2sim(&["export", &path(&log), "--nuplan", &path(&fresh), "--map", &path(&map), "--scenario-seconds", "10"]);
    assert!(!out.status.success() && stderr(&out).contains("nuPlan needs at least 5"), "{}", stderr(&out));
    let far = write(
        &dir,
        "far.osm",
        r#"<osm version="0.6"><node id="1" lat="0.0" lon="0.0"/><node id="2" lat="0.001" lon="0.0"/>
<way id="3"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way></osm>"#,
    );
    let out = dash2sim(&["export", &path(&log), "--nuplan", &path(&fresh), "--map", &far]);
    assert!(!out.status.success() && stderr(&out).contains("the map does not cover the drive"), "{}", stderr(&out));
    let gnss_only = dir.join("gnss-only.d2slog");
    assert!(dash2sim(&["import", "-o", &path(&gnss_only), "--nmea", &path(&dir.join("drive/gnss.nmea"))])
        .status
        .success());
    let out = dash2sim(&["export", &path(&gnss_only), "--nuplan", &path(&fresh), "--map", &path(&map)]);
    assert!(!out.status.success() && stderr(&out).contains("no ego poses"), "{}", stderr(&out));
    let out = dash2sim(&["export", &path(&log), "--nuplan", &path(&fresh)]);
    assert!(
        !out.status.success() && stderr(&out).contains("error: --map: the nuPlan export needs one"),
        "the flag that fixes it: {}",
        stderr(&out)
    );
    let left: Vec<_> = walk(&fresh).into_iter().filter(|p| p.is_file()).collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

/// Every element of an XML file: its path of tag names (`commonRoad/lanelet/successor`), its
/// attributes and its text.
type Element = (String, Vec<(String, String)>, String);

fn xml_elements(path: &Path) -> Vec<Element> {
    use quick_xml::events::Event;
    let text = std::fs::read_to_string(path).expect("xml");
    let mut reader = quick_xml::Reader::from_str(&text);
    let (mut stack, mut out): (Vec<String>, Vec<Element>) = (Vec::new(), Vec::new());
    let attributes = |e: &quick_xml::events::BytesStart<'_>| -> Vec<(String, String)> {
        e.attributes()
            .map(|a| {
                let a = a.expect("attribute");
                (a.key.as_ref().to_owned(), a.value.into_owned())
            })
            .collect()
    };
    loop {
        match reader.read_event().expect("well-formed XML") {
            Event::Start(e) => {
                stack.push(e.name().as_ref().to_owned());
                out.push((stack.join("/"), attributes(&e), String::new()));
            }
            Event::Empty(e) => {
                let name = e.name().as_ref().to_owned();
                out.push((format!("{}/{name}", stack.join("/")), attributes(&e), String::new()));
            }
            Event::Text(t) => {
                if let Some(last) = out.last_mut() {
                    last.2.push_str(t.as_ref());
                }
            }
            Event::CData(t) => {
                if let Some(last) = out.last_mut() {
                    last.2.push_str(t.as_ref());
                }
            }
            Event::End(_) => {
                stack.pop();
            }
            // Whitespace between elements lands on the last one opened: trimmed away.
            Event::Eof => return out.into_iter().map(|(p, a, t)| (p, a, t.trim().to_owned())).collect(),
            _ => {}
        }
    }
}

/// A simulator export (`flag`: `--commonroad F.xml`, `--scenarionet DIR` or `--openscenario DIR`, written to
/// `target` under `fresh`) refuses a window under 1 s, a window longer than the log, a map far
/// from the drive, a log without ego poses and a missing `--map`, each with a clear error, and
/// leaves nothing behind.
fn assert_export_refuses_bad_input(dir: &Path, log: &Path, map: &Path, flag: &str, fresh: &Path, target: &Path) {
    let path = |p: &Path| p.display().to_string();
    let (log, map, target) = (path(log), path(map), path(target));
    let out = dash2sim(&["export", &log, flag, &target, "--map", &map, "--scenario-seconds", "0.5"]);
    let e = stderr(&out);
    assert!(!out.status.success() && e.contains("--scenario-seconds: ") && e.contains("needs at least 1 s"), "{e}");
    let out = dash2sim(&["export", &log, flag, &target, "--map", &map, "--scenario-seconds", "60"]);
    assert!(!out.status.success() && stderr(&out).contains("shorter than one scenario"), "{}", stderr(&out));
    let far = write(
        dir,
        "far.osm",
        r#"<osm version="0.6"><node id="1" lat="0.0" lon="0.0"/><node id="2" lat="0.001" lon="0.0"/>
<way id="3"><nd ref="1"/><nd ref="2"/><tag k="highway" v="primary"/></way></osm>"#,
    );
    let out = dash2sim(&["export", &log, flag, &target, "--map", &far]);
    assert!(!out.status.success() && stderr(&out).contains("the map does not cover the drive"), "{}", stderr(&out));
    let gnss_only = dir.join("gnss-only.d2slog");
    assert!(dash2sim(&["import", "-o", &path(&gnss_only), "--nmea", &path(&dir.join("drive/gnss.nmea"))])
        .status
        .success());
    let out = dash2sim(&["export", &path(&gnss_only), flag, &target, "--map", &map]);
    assert!(!out.status.success() && stderr(&out).contains("no ego poses"), "{}", stderr(&out));
    let out = dash2sim(&["export", &log, flag, &target]);
    assert!(
        !out.status.success()
            && stderr(&out).contains("error: --map: the ")
            && stderr(&out).contains("export needs one"),
        "the flag that fixes it: {}",
        stderr(&out)
    );
    let left: Vec<_> = walk(fresh).into_iter().filter(|p| p.is_file()).collect();
    assert!(left.is_empty(), "left behind: {left:?}");
}

/// `dash2sim export LOG FLAG TARGET --map MAP --scenario-seconds SECONDS` (asserted to succeed),
/// then the sorted names of the files in `folder`.
fn export_windows(log: &Path, map: &Path, flag: &str, target: &Path, seconds: &str, folder: &Path) -> Vec<String> {
    let path = |p: &Path| p.display().to_string();
    let out =
        dash2sim(&["export", &path(log), flag, &path(target), "--map", &path(map), "--scenario-seconds", seconds]);
    assert!(out.status.success(), "{}", stderr(&out));
    let mut names: Vec<String> = std::fs::read_dir(folder)
        .expect("the export's folder")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn export_commonroad_writes_lanelets_obstacles_and_the_ego_and_refuses_bad_input() {
    let dir = scratch("commonroad");
    let out = demo_ideal_offline(&dir, "30");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |p: &Path| p.display().to_string();
    let (log, map) = (dir.join("finished.d2slog"), dir.join("road.map"));
    let scenario = dir.join("drive.xml");
    let out = dash2sim(&["export", &path(&log), "--commonroad", &path(&scenario), "--map", &path(&map)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let elements = xml_elements(&scenario);
    let all = |suffix: &str| -> Vec<&Element> { elements.iter().filter(|e| e.0.ends_with(suffix)).collect() };
    let attr = |e: &Element, key: &str| e.1.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone()).unwrap_or_default();
    // The lanelet network: every reference resolves, the ids are unique across kinds.
    let lanelets: Vec<String> = all("commonRoad/lanelet").into_iter().map(|e| attr(e, "id")).collect();
    assert!(lanelets.len() >= 2, "{lanelets:?}");
    for reference in ["predecessor", "successor", "adjacentLeft", "adjacentRight"] {
        for e in all(&format!("lanelet/{reference}")) {
            assert!(lanelets.contains(&attr(e, "ref")), "{reference} {}", attr(e, "ref"));
        }
    }
    // The two-way road: its two middle lanes name each other across the centre line.
    let opposite: Vec<String> = all("lanelet/adjacentLeft")
        .into_iter()
        .filter(|e| attr(e, "drivingDir") == "opposite")
        .map(|e| attr(e, "ref"))
        .collect();
    assert_eq!(opposite.len(), 2, "{opposite:?}");
    assert_ne!(opposite[0], opposite[1]);
    let mut ids: Vec<String> =
        elements.iter().filter(|e| e.0.matches('/').count() == 1).map(|e| attr(e, "id")).collect();
    ids.retain(|id| !id.is_empty());
    let unique: std::collections::BTreeSet<&String> = ids.iter().collect();
    assert_eq!(unique.len(), ids.len(), "ids collide");
    // The work zone's objects stand as construction zones; a moving track is a trajectory of
    // consecutive steps.
    assert!(all("staticObstacle/type").into_iter().any(|e| e.2 == "constructionZone"));
    let mut obstacles: Vec<Vec<i64>> = Vec::new();
    for e in &elements {
        if e.0 == "commonRoad/dynamicObstacle" {
            obstacles.push(Vec::new());
        } else if e.0.starts_with("commonRoad/dynamicObstacle/") && e.0.ends_with("time/exact") {
            obstacles.last_mut().expect("in an obstacle").push(e.2.parse().expect("step"));
        }
    }
    assert!(!obstacles.is_empty());
    for steps in &obstacles {
        assert!(steps.len() >= 2 && steps.windows(2).all(|w| w[1] == w[0] + 1), "a trajectory with a gap: {steps:?}");
    }
    // The ego: the planning problem starts where the solution does, and the solution has a
    // state per 0.1 s step of the 30 s drive.
    let solution = xml_elements(&dir.join("drive.solution.xml"));
    let states: Vec<&Element> = solution.iter().filter(|e| e.0.ends_with("ksTrajectory/ksState/x")).collect();
    assert!((299..=302).contains(&states.len()), "{}", states.len());
    let start_x: f64 =
        all("planningProblem/initialState/position/point/x").first().expect("start").2.parse().expect("x");
    assert!((start_x - states[0].2.parse::<f64>().expect("x")).abs() < 1e-6);
    assert!(elements
        .iter()
        .any(|e| e.0.ends_with("location/geoTransformation/geoReference") && e.2.contains("+zone=35")));

    // Windows: one scenario per 10 s, each with its own solution.
    std::fs::create_dir_all(dir.join("windows")).expect("dir");
    let names = export_windows(&log, &map, "--commonroad", &dir.join("windows/w.xml"), "10", &dir.join("windows"));
    assert_eq!(
        names,
        ["w-001.solution.xml", "w-001.xml", "w-002.solution.xml", "w-002.xml", "w-003.solution.xml", "w-003.xml"]
    );

    // Bad input: a clear error and nothing left behind.
    let fresh = dir.join("refused");
    std::fs::create_dir_all(&fresh).expect("dir");
    assert_export_refuses_bad_input(&dir, &log, &map, "--commonroad", &fresh, &fresh.join("s.xml"));
}

#[test]
fn export_openscenario_writes_a_road_and_scenarios_of_the_log_and_refuses_bad_input() {
    let dir = scratch("openscenario");
    let out = demo_ideal_offline(&dir, "30");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |p: &Path| p.display().to_string();
    let (log, map) = (dir.join("finished.d2slog"), dir.join("road.map"));
    let folder = dir.join("osc");
    let out = dash2sim(&["export", &path(&log), "--openscenario", &path(&folder), "--map", &path(&map)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let attr = |e: &Element, key: &str| e.1.iter().find(|(k, _)| k == key).map(|(_, v)| v.clone()).unwrap_or_default();
    let number =
        |e: &Element, key: &str| -> f64 { attr(e, key).parse().unwrap_or_else(|_| panic!("{key} of {}", e.0)) };

    // The road: geo-referenced in the log's UTM zone; each road's length is its plan view's,
    // whose elements follow one another in s; lanes drive along the reference line.
    let road = xml_elements(&folder.join("road.xodr"));
    assert!(road.iter().any(|e| e.0 == "OpenDRIVE/header/geoReference" && e.2.contains("+zone=35")));
    let roads: Vec<&Element> = road.iter().filter(|e| e.0 == "OpenDRIVE/road").collect();
    assert!(roads.len() >= 2, "{}", roads.len());
    let mut geometries = road.iter().filter(|e| e.0 == "OpenDRIVE/road" || e.0 == "OpenDRIVE/road/planView/geometry");
    let mut current: Option<(f64, f64)> = None; // (the road's length, s reached)
    let check = |c: Option<(f64, f64)>| {
        if let Some((length, reached)) = c {
            assert!((length - reached).abs() < 1e-4, "a road of {length} m whose plan view reaches {reached} m");
        }
    };
    for e in geometries.by_ref() {
        if e.0 == "OpenDRIVE/road" {
            check(current);
            current = Some((number(e, "length"), 0.0));
        } else if let Some((_, reached)) = current.as_mut() {
            // Lengths and s are written to the micrometre: their sums drift by as much per element.
            assert!((number(e, "s") - *reached).abs() < 1e-4, "a gap in s at {}", number(e, "s"));
            *reached += number(e, "length");
        }
    }
    check(current);
    assert!(road.iter().any(|e| e.0.ends_with("right/lane") && attr(e, "id") == "-2" && attr(e, "type") == "driving"));

    // The scenario: the ego and the work zone's objects; every entity an action names exists;
    // the ego's trajectory has a vertex per 0.1 s of the 30 s drive, 0.1 s apart, from 0.
    let scenario = xml_elements(&folder.join("scenario.xosc"));
    assert!(scenario.iter().any(|e| e.0 == "OpenSCENARIO/RoadNetwork/LogicFile" && attr(e, "filepath") == "road.xodr"));
    let entities: Vec<String> =
        scenario.iter().filter(|e| e.0 == "OpenSCENARIO/Entities/ScenarioObject").map(|e| attr(e, "name")).collect();
    assert_eq!(entities.first().map(String::as_str), Some("Ego"));
    assert!(scenario.iter().any(|e| e.0.ends_with("ScenarioObject/MiscObject")), "no work-zone object");
    for e in scenario.iter().filter(|e| e.0.ends_with("/EntityRef") || e.0.ends_with("Init/Actions/Private")) {
        assert!(entities.contains(&attr(e, "entityRef")), "{} names {}", e.0, attr(e, "entityRef"));
    }
    let mut times: Vec<f64> = Vec::new();
    let mut in_ego = false;
    for e in &scenario {
        if e.0.ends_with("Story/Act/ManeuverGroup") {
            in_ego = attr(e, "name") == "Ego";
        } else if in_ego && e.0.ends_with("Polyline/Vertex") {
            times.push(number(e, "time"));
        }
    }
    assert!((299..=302).contains(&times.len()), "{}", times.len());
    assert_eq!(times[0], 0.0);
    assert!(times.windows(2).all(|w| (w[1] - w[0] - 0.1).abs() < 1e-9));
    let start = scenario.iter().find(|e| attr(e, "name") == "log_start_s").expect("log_start_s");
    assert!(number(start, "value") > 1.0e9);

    // Windows: the road and one scenario per 10 s.
    let windows = dir.join("windows");
    let names = export_windows(&log, &map, "--openscenario", &windows, "10", &windows);
    assert_eq!(names, ["road.xodr", "scenario-001.xosc", "scenario-002.xosc", "scenario-003.xosc"]);

    // `map export` writes the road the export writes.
    let alone = dir.join("alone.xodr");
    let out = dash2sim(&["map", "export", &path(&map), "--opendrive", &path(&alone)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("lane centres within"), "{said}");
    assert_eq!(std::fs::read(&alone).expect("alone"), std::fs::read(folder.join("road.xodr")).expect("road"));

    // Bad input: a clear error and nothing left behind.
    let fresh = dir.join("refused");
    std::fs::create_dir_all(&fresh).expect("dir");
    assert_export_refuses_bad_input(&dir, &log, &map, "--openscenario", &fresh, &fresh.join("osc"));
    let out = dash2sim(&["map", "export", &path(&dir.join("far.osm")), "--opendrive", &path(&fresh.join("a.xodr"))]);
    assert!(out.status.success(), "a road alone needs no drive: {}", stderr(&out));
    let empty = write(&dir, "empty.osm", r#"<osm version="0.6"><node id="1" lat="0.0" lon="0.0"/></osm>"#);
    let out = dash2sim(&["map", "export", &empty, "--opendrive", &path(&fresh.join("b.xodr"))]);
    assert!(!out.status.success() && stderr(&out).contains("no lanes"), "{}", stderr(&out));
    assert!(!fresh.join("b.xodr").exists() && !fresh.join("b.partial").exists());
}

/// A pickle's structure as serde-pickle reads it: numpy arrays (an unresolved global) are
/// `None`.
fn unpickle(path: &Path) -> serde_pickle::Value {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_pickle::value_from_slice(&bytes, serde_pickle::DeOptions::new().replace_unresolved_globals())
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// `value[key]` of a pickled dict with string keys.
fn field<'v>(value: &'v serde_pickle::Value, key: &str) -> &'v serde_pickle::Value {
    let serde_pickle::Value::Dict(map) = value else { panic!("not a dict: {value:?}") };
    map.get(&serde_pickle::HashableValue::String(key.to_string())).unwrap_or_else(|| panic!("no {key}"))
}

fn keys(value: &serde_pickle::Value) -> Vec<String> {
    let serde_pickle::Value::Dict(map) = value else { panic!("not a dict") };
    map.keys()
        .map(|k| match k {
            serde_pickle::HashableValue::String(s) => s.clone(),
            other => panic!("a key that is not a string: {other:?}"),
        })
        .collect()
}

#[test]
fn export_scenarionet_writes_a_dataset_with_the_ego_objects_and_lanes_and_refuses_bad_input() {
    use serde_pickle::Value;
    let dir = scratch("scenarionet");
    let out = demo_ideal_offline(&dir, "30");
    assert!(out.status.success(), "{}", stderr(&out));
    let (log, map) = (dir.join("finished.d2slog"), dir.join("road.map"));
    let dataset = dir.join("dataset");
    // Three windows of 10 s and ScenarioNet's two index files, nothing else.
    let names = export_windows(&log, &map, "--scenarionet", &dataset, "10", &dataset);
    let scenarios: Vec<String> = names.iter().filter(|n| n.starts_with("sd_dash2sim_")).cloned().collect();
    assert_eq!(scenarios.len(), 3, "{names:?}");
    assert_eq!(names.len(), 5, "{names:?}");
    let mapping = unpickle(&dataset.join("dataset_mapping.pkl"));
    let mut mapped = keys(&mapping);
    mapped.sort();
    assert_eq!(mapped, scenarios);
    let summary = unpickle(&dataset.join("dataset_summary.pkl"));
    for name in &scenarios {
        let scenario = unpickle(&dataset.join(name));
        let mut top = keys(&scenario);
        top.sort();
        assert_eq!(top, ["dynamic_map_states", "id", "length", "map_features", "metadata", "tracks", "version"]);
        assert_eq!(field(&scenario, "length"), &Value::I64(100));
        let metadata = field(&scenario, "metadata");
        assert_eq!(field(metadata, "sdc_id"), &Value::String("ego".into()));
        assert_eq!(field(metadata, "dataset"), &Value::String("dash2sim".into()));
        assert_eq!(field(metadata, "utm_epsg"), &Value::I64(32635));
        assert_eq!(field(&summary, name), metadata, "the summary holds each scenario's metadata");
        // The ego and the tracked objects, each with the state arrays MetaDrive reads and
        // its own id in its metadata.
        let tracks = field(&scenario, "tracks");
        let ids = keys(tracks);
        assert!(ids.contains(&"ego".to_string()) && ids.len() >= 2, "{ids:?}");
        for id in &ids {
            let track = field(tracks, id);
            let mut state = keys(field(track, "state"));
            state.sort();
            assert_eq!(state, ["heading", "height", "length", "position", "valid", "velocity", "width"]);
            assert_eq!(field(field(track, "metadata"), "object_id"), &Value::String(id.clone()));
        }
        let object_summary = field(metadata, "object_summary");
        let mut summarised = keys(object_summary);
        summarised.sort();
        let mut sorted = ids.clone();
        sorted.sort();
        assert_eq!(summarised, sorted);
        // Lanes whose neighbours, entries, exits and boundaries all name features of the map.
        let features = field(&scenario, "map_features");
        let feature_ids = keys(features);
        let kind = |id: &str| match field(field(features, id), "type") {
            Value::String(s) => s.clone(),
            other => panic!("{other:?}"),
        };
        let lanes: Vec<&String> = feature_ids.iter().filter(|id| kind(id) == "LANE_SURFACE_STREET").collect();
        assert!(lanes.len() >= 2, "{feature_ids:?}");
        assert!(feature_ids.iter().any(|id| kind(id) == "ROAD_EDGE_BOUNDARY"));
        for lane in lanes {
            let lane = field(features, lane);
            for (list, key) in [
                ("entry_lanes", None),
                ("exit_lanes", None),
                ("left_neighbor", Some("feature_id")),
                ("right_neighbor", Some("feature_id")),
                ("left_boundaries", Some("boundary_feature_id")),
                ("right_boundaries", Some("boundary_feature_id")),
            ] {
                let Value::List(items) = field(lane, list) else { panic!("{list} is not a list") };
                for item in items {
                    let target = match key {
                        None => item,
                        Some(k) => field(item, k),
                    };
                    let Value::String(target) = target else { panic!("{list}: {target:?}") };
                    assert!(feature_ids.contains(target), "{list} names {target}, not a feature");
                }
            }
        }
    }

    // Bad input: a clear error and nothing left behind.
    let fresh = dir.join("refused");
    assert_export_refuses_bad_input(&dir, &log, &map, "--scenarionet", &fresh, &fresh);
}

#[test]
fn plot_draws_the_map_the_three_trajectories_and_the_objects_and_refuses_a_log_without_poses() {
    let dir = scratch("plot");
    let out = demo_ideal_offline(&dir, "30");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |p: &Path| p.display().to_string();
    // The demo drew its drive.
    let png = std::fs::read(dir.join("plot.png")).expect("the demo's plot.png");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let (w, h) = (
        u32::from_be_bytes([png[16], png[17], png[18], png[19]]),
        u32::from_be_bytes([png[20], png[21], png[22], png[23]]),
    );
    assert_eq!((w, h), (1200, 1400));

    let svg_path = dir.join("again.svg");
    let (log, finished, map) = (dir.join("drive.d2slog"), dir.join("finished.d2slog"), dir.join("road.map"));
    let out =
        dash2sim(&["plot", &path(&log), "--map", &path(&map), "--finished", &path(&finished), "-o", &path(&svg_path)]);
    assert!(out.status.success(), "{}", stderr(&out));
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(said.contains("online and") && said.contains("cone"), "{said}");
    let svg = std::fs::read_to_string(&svg_path).expect("svg");
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"));
    // The layers a person looks for, each named in a legend; the panels; scale bar, north.
    let texts: Vec<String> = svg
        .split("<text")
        .skip(1)
        .filter_map(|t| Some(t.split_once('>')?.1.split_once("</text>")?.0.trim().to_owned()))
        .collect();
    for label in [
        "map lanes (drivable area)",
        "GNSS fixes (raw)",
        "online anchored ego",
        "finished ego",
        "cone",
        "drum",
        "barricade",
        "car",
        "vehicle speed (wheel / CAN)",
        "time to collision",
        "score / 100",
        "speed",
        "N",
    ] {
        assert!(texts.iter().any(|t| t == label), "no {label:?} among {texts:?}");
    }
    assert!(
        texts.iter().any(|t| t.strip_suffix(" m").is_some_and(|n| n.parse::<u32>().is_ok_and(|n| n >= 10))),
        "no scale bar among {texts:?}"
    );
    // Grey lane areas, red fixes, orange and blue lines are all there.
    for colour in ["#CDCDCD", "#D62728", "#FF7F0E", "#1F77B4"] {
        assert!(svg.contains(colour), "no {colour} in the SVG");
    }
    // Without a map or a finished log, those layers are absent, not empty.
    let bare = dir.join("bare.svg");
    assert!(dash2sim(&["plot", &path(&log), "-o", &path(&bare)]).status.success());
    let bare = std::fs::read_to_string(&bare).expect("svg");
    assert!(!bare.contains("map lanes") && !bare.contains("finished ego") && bare.contains("online anchored ego"));

    // Bad input: a log without ego poses, an unknown picture format.
    let gnss_only = dir.join("gnss-only.d2slog");
    assert!(dash2sim(&["import", "-o", &path(&gnss_only), "--nmea", &path(&dir.join("drive/gnss.nmea"))])
        .status
        .success());
    let out = dash2sim(&["plot", &path(&gnss_only), "-o", &path(&dir.join("x.svg"))]);
    assert!(!out.status.success() && stderr(&out).contains("no ego poses to plot"), "{}", stderr(&out));
    let out = dash2sim(&["plot", &path(&log), "-o", &path(&dir.join("x.gif"))]);
    assert!(!out.status.success() && stderr(&out).contains("must end in .svg or .png"), "{}", stderr(&out));
}

#[test]
fn export_parquet_writes_a_table_per_record_kind_in_si_units_and_utc() {
    use arrow_array::cast::AsArray;
    use arrow_array::types::{Float64Type, TimestampMicrosecondType};
    use arrow_array::Array;
    let dir = scratch("parquet");
    let demo = dir.join("demo");
    let out = dash2sim(&[
        "demo",
        "--profile",
        "ideal",
        "--offline",
        "-q",
        "--duration",
        "20",
        "-o",
        &demo.display().to_string(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let log = demo.join("finished.d2slog").display().to_string();
    let out_dir = dir.join("pq");
    let out = dash2sim(&["export", &log, "--parquet", &out_dir.display().to_string(), "--log-id", "seed-1"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let inspect: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["inspect", &log, "--json"]).stdout).expect("json");
    let by_type = &inspect["by_type"];
    for (table, kind) in [
        ("ego", "EgoPose"),
        ("gnss", "GnssFix"),
        ("speed", "VehicleSpeed"),
        ("anchors", "AnchorEstimate"),
        ("verification", "Verification"),
        ("imu", "ImuDelta"),
        ("imu_estimates", "ImuEstimate"),
        ("events", "Event"),
    ] {
        let (rows, _) = parquet_table(&out_dir.join(format!("{table}.parquet")));
        assert_eq!(rows as u64, by_type[kind].as_u64().unwrap_or(0), "{table}");
    }
    let (states, _) = parquet_table(&out_dir.join("tracks3d.parquet"));
    assert!(states as u64 >= by_type["Tracks3d"].as_u64().unwrap_or(0) && states > 0);
    // The ego in metres and UTC: the TUM export's first pose.
    let tum_path = dir.join("ego.tum");
    assert!(dash2sim(&["export", &log, "--tum", &tum_path.display().to_string()]).status.success());
    let tum = std::fs::read_to_string(&tum_path).expect("tum");
    let first: Vec<f64> = tum
        .lines()
        .find(|l| !l.starts_with('#'))
        .expect("a pose")
        .split(' ')
        .map(|x| x.parse().expect("number"))
        .collect();
    let (_, batches) = parquet_table(&out_dir.join("ego.parquet"));
    let b = &batches[0];
    let t = b.column_by_name("t").expect("t").as_primitive::<TimestampMicrosecondType>().value(0);
    let x = b.column_by_name("x_m").expect("x").as_primitive::<Float64Type>().value(0);
    assert!((t as f64 * 1e-6 - first[0]).abs() < 1e-6 && (x - first[1]).abs() < 1e-9, "{t} {x} vs {first:?}");
    assert_eq!(b.column_by_name("log_id").expect("id").as_string::<i32>().value(0), "seed-1");
    // What the finished log states of its doubt: each pose's σ, each track's covariance,
    // each window's decision and the score's interval around its score.
    let sigma = b.column_by_name("sigma_m").expect("sigma_m").as_primitive::<Float64Type>();
    assert!(sigma.null_count() == 0 && sigma.values().iter().all(|s| *s > 0.0), "{sigma:?}");
    let (_, tracks) = parquet_table(&out_dir.join("tracks3d.parquet"));
    let xx = tracks[0].column_by_name("cov_xx_m2").expect("cov_xx_m2").as_primitive::<Float64Type>();
    assert!(xx.null_count() == 0 && xx.values().iter().all(|v| *v >= 0.0), "{xx:?}");
    let windows = |dir: &Path| {
        let (rows, batches) = parquet_table(&dir.join("verification.parquet"));
        let b = &batches[0];
        let decision = b.column_by_name("decision").expect("decision").as_string::<i32>().clone();
        let number = |name| b.column_by_name(name).expect(name).as_primitive::<Float64Type>().clone();
        (rows, decision, number("score"), number("score_low"), number("score_high"))
    };
    let (rows, decision, score, low, high) = windows(&out_dir);
    assert!(rows > 0 && decision.null_count() == 0, "every finished window decided: {decision:?}");
    for k in 0..rows {
        assert!(["verified", "rejected", "undecided"].contains(&decision.value(k)));
        assert!(low.value(k) <= score.value(k) + 0.005 && score.value(k) <= high.value(k) + 0.005, "window {k}");
    }
    // The device decides its windows too, with its ego's doubt.
    let device_dir = dir.join("device-pq");
    let device_log = demo.join("drive.d2slog").display().to_string();
    assert!(dash2sim(&["export", &device_log, "--parquet", &device_dir.display().to_string()]).status.success());
    let (rows, decision, score, low, high) = windows(&device_dir);
    assert!(rows > 0 && decision.null_count() == 0, "every device window decided: {decision:?}");
    for k in 0..rows {
        assert!(low.value(k) <= score.value(k) + 0.005 && score.value(k) <= high.value(k) + 0.005, "window {k}");
    }
    // A folder that cannot be made is named.
    let blocker = write(&dir, "file", "");
    let out = dash2sim(&["export", &log, "--parquet", &format!("{blocker}/pq")]);
    assert!(!out.status.success() && stderr(&out).contains(&blocker), "{}", stderr(&out));
}
