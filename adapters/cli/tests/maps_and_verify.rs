//! The `dash2sim` binary end to end — generated drives (`scenario generate|eval`), map tiles (`map build|info|check`) and `verify`: output shape, exit status and error messages.

mod common;

use common::*;

#[test]
fn scenario_files_round_trip_through_the_other_commands() {
    let dir = scratch("scenario");
    let out = generate_ideal(&dir, "3", "12");
    assert!(out.status.success(), "{}", stderr(&out));
    let path = |name: &str| dir.join(name).display().to_string();
    for name in ["ego.tum", "vo.tum", "gnss.tum", "gnss.nmea", "speed.csv", "objects.csv", "detections3d.csv"] {
        assert!(dir.join(name).is_file(), "{name} missing");
    }
    // Every GNSS fix (5 Hz for 12 s, both ends) decodes as NMEA with nothing rejected.
    let out = dash2sim(&["nmea", "decode", &path("gnss.nmea"), "--json"]);
    let text = String::from_utf8_lossy(&out.stdout);
    let summary: serde_json::Value = text.lines().last().and_then(|l| serde_json::from_str(l).ok()).expect("summary");
    assert_eq!(summary["fixes"], 61, "{summary}");
    assert!(summary["rejected"].as_object().expect("counts").values().all(|v| v == 0), "{summary}");
    assert!(stderr(&out).is_empty(), "{}", stderr(&out));
    // The GNSS track is metres (not kilometres) off the ego truth.
    let out = dash2sim(&["traj", "ape", &path("ego.tum"), &path("gnss.tum"), "--max-diff", "0.1", "--json"]);
    let ape: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    let rmse = ape["stats"]["rmse"].as_f64().expect("rmse");
    assert!((2.0..40.0).contains(&rmse) && ape["matched"] == 61, "{ape}");
    // The 2D ground truth is a valid MOTChallenge file: against itself it scores perfectly.
    let out = dash2sim(&["mot", "eval", &path("gt2d.txt"), &path("gt2d.txt"), "--json"]);
    let m: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!((m["mota"].as_f64(), m["num_switches"].as_f64()), (Some(1.0), Some(0.0)), "{m}");
    // The 2D detections feed track2d.
    let tracks = path("tracks2d.txt");
    assert!(dash2sim(&["track2d", &path("det2d.txt"), "-o", &tracks]).status.success());
    let m: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["mot", "eval", &path("gt2d.txt"), &tracks, "--json"]).stdout).expect("json");
    assert!(m["num_matches"].as_f64().is_some_and(|n| n > 50.0), "{m}");
    // One node every 10 m of road and one way.
    let osm = std::fs::read_to_string(dir.join("road.osm")).expect("osm");
    assert_eq!(osm.matches("<node ").count(), 116, "1150 m of road");
    assert!(osm.contains("<tag k=\"lanes:forward\" v=\"2\"/>"));
    let info: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("scenario.json")).expect("json")).expect("json");
    assert_eq!((info["seed"].as_u64(), info["counts"]["frames"].as_u64()), (Some(3), Some(121)));
}

#[test]
fn scenario_eval_reports_the_figures_and_bad_durations_are_refused() {
    // The tracker's own figures, on the ideal profile's detections.
    let out = dash2sim(&["scenario", "eval", "--profile", "ideal", "--seed", "2", "--duration", "30", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(r["profile"], "ideal");
    let get = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
    assert!(get("rmse_filtered_m") < get("rmse_detections_m") && get("static_accuracy") > 0.9, "{r}");
    assert!(r["metrics"]["idf1"].as_f64().is_some_and(|v| v > 0.5), "{r}");
    for bad in ["0", "nan", "1000"] {
        let out = dash2sim(&["scenario", "eval", "--duration", bad]);
        assert!(!out.status.success() && stderr(&out).contains("--duration"), "{bad}: {}", stderr(&out));
    }
}

#[test]
fn map_build_and_info_describe_the_tile_and_refuse_a_corrupted_one() {
    let dir = scratch("map");
    let osm = write(
        &dir,
        "small.osm",
        r#"<osm version="0.6">
  <node id="1" lat="60.0000" lon="24.0000"/>
  <node id="2" lat="60.0010" lon="24.0000"/>
  <node id="3" lat="60.0010" lon="24.0020"/>
  <way id="5"><nd ref="1"/><nd ref="2"/><nd ref="3"/><tag k="highway" v="primary"/><tag k="lanes" v="2"/><tag k="maxspeed" v="50"/></way>
  <way id="6"><nd ref="2"/><nd ref="404"/><tag k="highway" v="residential"/><tag k="width" v="abc"/></way>
  <way id="7"><nd ref="1"/><nd ref="3"/><tag k="highway" v="footway"/></way>
</osm>"#,
    );
    let map = dir.join("small.map").display().to_string();
    let out = dash2sim(&["map", "build", &osm, "-o", &map, "--origin", "60,24"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("way 6 references missing node 404") && err.contains("way 6: width"), "{err}");
    let out = dash2sim(&["map", "info", &map, "--json"]);
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(info["osm"], serde_json::json!({"nodes": 3, "ways": 3, "highway_ways": 3, "relations": 0}));
    assert_eq!((info["origin"]["lat"].as_f64(), info["lanes"].as_u64()), (Some(60.0), Some(2)));
    // Two lanes along 111 m north then 111 m east.
    let km = info["lane_km"].as_f64().expect("km");
    assert!((km - 2.0 * 0.2225).abs() < 0.01, "{km}");
    assert_eq!(info["bytes"].as_u64(), std::fs::metadata(&map).ok().map(|m| m.len()));
    // One flipped byte: a clear error, not a crash.
    let mut bytes = std::fs::read(&map).expect("tile");
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    let bad = write(&dir, "bad.map", "");
    std::fs::write(&bad, &bytes).expect("write");
    let out = dash2sim(&["map", "info", &bad]);
    assert!(!out.status.success() && stderr(&out).contains("CRC-32C mismatch"), "{}", stderr(&out));
    let out = dash2sim(&["map", "build", &osm, "-o", &map, "--origin", "91,0"]);
    assert!(!out.status.success() && stderr(&out).contains("--origin"), "{}", stderr(&out));
}

#[test]
fn verify_scores_a_generated_drive_and_names_bad_inputs() {
    let dir = scratch("verify");
    let drive = dir.join("drive");
    let out = generate_ideal(&drive, "1", "10");
    assert!(out.status.success(), "{}", stderr(&out));
    let map = dir.join("road.map").display().to_string();
    let road = drive.join("road.osm").display().to_string();
    let out = dash2sim(&["map", "build", &road, "-o", &map, "--origin", "60.2711,24.8572"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (ego, objects) = (drive.join("ego.tum").display().to_string(), drive.join("objects.csv").display().to_string());
    let poses = dir.join("poses.csv").display().to_string();
    for sensitive in [false, true] {
        let mut args = vec!["verify", "--map", &map, "--ego", &ego, "--objects", &objects, "--json", "--poses", &poses];
        if sensitive {
            args.push("--channel-sensitive");
        }
        let out = dash2sim(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        // The first 10 s: lane keeping at 22 m/s behind traffic, before the work zone.
        assert_eq!(report["verified"], true, "{report}");
        assert!(report["score"].as_f64().is_some_and(|s| s > 90.0), "{report}");
        let metrics = report["metrics"].as_object().expect("metrics");
        assert_eq!(metrics.len(), 8);
        assert_eq!(report["poses"], 101);
        assert_eq!(report["channel_sensitive"], sensitive);
    }
    let csv = std::fs::read_to_string(&poses).expect("per-pose CSV");
    assert_eq!(csv.lines().count(), 102, "header and one row per pose");
    assert!(csv.lines().nth(1).is_some_and(|l| l.split(',').count() == 16));
    // A TTC always names the agent it is to.
    let header: Vec<&str> = csv.lines().next().expect("header").split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let (ttc, agent) = (column("ttc_s"), column("ttc_agent"));
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().any(|r| !r[ttc].is_empty()), "some pose has an agent ahead within the horizon");
    assert!(rows.iter().all(|r| r[ttc].is_empty() == r[agent].is_empty()), "{csv}");
    // A verified drive meets nothing.
    assert!(rows.iter().all(|r| r[column("collision_agent")].is_empty()), "{csv}");

    // Bad inputs: a clear error naming the file and line, never a crash.
    let bad_ego = write(&dir, "bad.tum", "0.0 1 2 0 0 0 0 1\n0.1 1 2 zero 0 0 0 1\n");
    let out = dash2sim(&["verify", "--map", &map, "--ego", &bad_ego]);
    assert!(!out.status.success() && stderr(&out).contains("bad.tum:2"), "{}", stderr(&out));
    let bad_objects = write(&dir, "bad.csv", "frame,t_s,id,class,x,y,z,yaw,l,w,h,vx,vy,static,visible\n0,0.0,1,cone,1,2,0,0,0.4,0.4,1,0,0,1,1\n1,0.1,1,cone,x,2,0,0,0.4,0.4,1,0,0,1,1\n");
    let out = dash2sim(&["verify", "--map", &map, "--ego", &ego, "--objects", &bad_objects]);
    assert!(!out.status.success() && stderr(&out).contains("bad.csv:3: x is not a finite number"), "{}", stderr(&out));
    let out = dash2sim(&["verify", "--map", &ego, "--ego", &ego]);
    assert!(!out.status.success() && stderr(&out).contains("bad magic"), "{}", stderr(&out));
    let out = dash2sim(&["verify", "--map", &map, "--ego", &ego, "--width", "0"]);
    assert!(!out.status.success() && stderr(&out).contains("--width"), "{}", stderr(&out));
}

#[test]
fn map_build_cuts_at_a_bbox_and_survives_odd_ways() {
    let dir = scratch("map-odd");
    // A self-intersecting figure-eight, lanes=0, a one-node way, a way with every node missing.
    let osm = write(
        &dir,
        "odd.osm",
        r#"<osm version="0.6">
  <node id="1" lat="60.0000" lon="24.0000"/>
  <node id="2" lat="60.0010" lon="24.0020"/>
  <node id="3" lat="60.0010" lon="24.0000"/>
  <node id="4" lat="60.0000" lon="24.0020"/>
  <node id="5" lat="60.0030" lon="24.0030"/>
  <way id="5"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/><tag k="highway" v="primary"/><tag k="lanes" v="0"/></way>
  <way id="6"><nd ref="3"/><tag k="highway" v="residential"/></way>
  <way id="7"><nd ref="8"/><nd ref="9"/><tag k="highway" v="residential"/></way>
  <way id="8"><nd ref="3"/><nd ref="5"/><tag k="highway" v="residential"/></way>
</osm>"#,
    );
    let map = dir.join("odd.map").display().to_string();
    let out = dash2sim(&["map", "build", &osm, "-o", &map]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("way 5: lanes") && err.contains("way 6: fewer than 2") && err.contains("way 7"), "{err}");
    let lanes: serde_json::Value = serde_json::from_slice(&dash2sim(&["map", "lanes", &map]).stdout).expect("json");
    assert_eq!(
        lanes["lanes"].as_array().map(Vec::len),
        Some(4),
        "2 for the figure-eight (lanes=0 → default), 2 for way 8"
    );
    // --bbox keeps way 5 (inside) and cuts way 8 at the box: node 5 is outside.
    let cut = dir.join("cut.map").display().to_string();
    let out = dash2sim(&["map", "build", &osm, "-o", &cut, "--bbox", "23.999,59.999,24.0025,60.0015"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let lanes: serde_json::Value = serde_json::from_slice(&dash2sim(&["map", "lanes", &cut]).stdout).expect("json");
    assert_eq!(lanes["lanes"].as_array().map(Vec::len), Some(2));
    let info: serde_json::Value =
        serde_json::from_slice(&dash2sim(&["map", "info", &cut, "--json"]).stdout).expect("json");
    assert_eq!(info["osm"]["ways"], 4, "source counts describe the file, not the cut");
    for bad in ["1,2,3", "24.1,60,24.0,61", "a,b,c,d"] {
        let out = dash2sim(&["map", "build", &osm, "-o", &cut, "--bbox", bad]);
        assert!(!out.status.success() && stderr(&out).contains("--bbox"), "{bad}: {}", stderr(&out));
    }
}

#[test]
fn map_check_counts_compliant_poses_and_times_them() {
    let dir = scratch("map-check");
    let drive = dir.join("drive");
    let out = generate_ideal(&drive, "2", "5");
    assert!(out.status.success(), "{}", stderr(&out));
    let map = dir.join("road.map").display().to_string();
    let osm = drive.join("road.osm").display().to_string();
    assert!(dash2sim(&["map", "build", &osm, "-o", &map, "--origin", "60.2711,24.8572"]).status.success());
    let ego = drive.join("ego.tum").display().to_string();
    let out = dash2sim(&["map", "check", &map, "--poses", &ego, "--passes", "2", "--json"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    // The generated drive stays on its road: every pose complies.
    assert_eq!(v["poses"], 51);
    assert_eq!(v["compliant"], 51, "{v}");
    assert!(v["us_per_pose"].as_f64().is_some_and(|t| t > 0.0));
    // The same poses 40 m to the side are off the road.
    let text = std::fs::read_to_string(drive.join("ego.tum")).expect("tum");
    let shifted: String = text
        .lines()
        .map(|l| {
            let mut f: Vec<String> = l.split(' ').map(str::to_owned).collect();
            f[2] = (f[2].parse::<f64>().expect("y") + 40.0).to_string();
            f.join(" ") + "\n"
        })
        .collect();
    let off = write(&dir, "off.tum", &shifted);
    let out = dash2sim(&["map", "check", &map, "--poses", &off, "--json"]);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["compliant"], 0, "{v}");
    let out = dash2sim(&["map", "check", &map, "--poses", &write(&dir, "empty.tum", "")]);
    assert!(!out.status.success() && stderr(&out).contains("no poses"), "{}", stderr(&out));
    let out = dash2sim(&["map", "check", &map, "--poses", &ego, "--passes", "0"]);
    assert!(!out.status.success() && stderr(&out).contains("--passes"));
}
