//! Map tiles of constructed roads for the verification tests: one OSM way through ENU
//! points, written as OSM XML and taken through the real import (`osm::parse_xml`,
//! `map_tile::from_osm`, `map_tile::encode`).

use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_linux::ingest::map_tile::{encode, from_osm};

/// The tiles' ENU origin (latitude, longitude).
pub const ORIGIN: (f64, f64) = (60.2, 24.9);

/// A tile holding one `highway=primary` way through `points` (ENU metres) with `tags`.
pub fn tile(points: &[(f64, f64)], tags: &[(&str, &str)]) -> Vec<u8> {
    tile_of_ways(&[(points, "primary", tags)])
}

/// One way of a constructed road: ENU points, highway class, other tags.
pub type WaySpec<'a> = (&'a [(f64, f64)], &'a str, &'a [(&'a str, &'a str)]);

/// A tile of several ways. Ways meet where they share a point exactly (one OSM node).
pub fn tile_of_ways(ways: &[WaySpec<'_>]) -> Vec<u8> {
    let origin = Geodetic::new(ORIGIN.0, ORIGIN.1, 0.0).expect("origin");
    let frame = LocalFrame::new(origin);
    let mut nodes: Vec<(f64, f64)> = Vec::new();
    let mut node_id = |p: (f64, f64)| match nodes.iter().position(|q| *q == p) {
        Some(i) => i + 1,
        None => {
            nodes.push(p);
            nodes.len()
        }
    };
    let mut way_xml = String::new();
    for (k, (points, class, tags)) in ways.iter().enumerate() {
        way_xml += &format!("  <way id=\"{}\">\n", k + 1);
        for p in points.iter() {
            way_xml += &format!("    <nd ref=\"{}\"/>\n", node_id(*p));
        }
        way_xml += &format!("    <tag k=\"highway\" v=\"{class}\"/>\n");
        for (key, v) in tags.iter() {
            way_xml += &format!("    <tag k=\"{key}\" v=\"{v}\"/>\n");
        }
        way_xml += "  </way>\n";
    }
    let mut xml = String::from("<?xml version=\"1.0\"?>\n<osm version=\"0.6\">\n");
    for (k, (x, y)) in nodes.iter().enumerate() {
        let g = frame.enu_to_geodetic(&Vector3::new(*x, *y, 0.0)).expect("geodetic");
        xml += &format!("  <node id=\"{}\" lat=\"{:.9}\" lon=\"{:.9}\"/>\n", k + 1, g.lat_deg, g.lon_deg);
    }
    xml += &way_xml;
    xml += "</osm>\n";
    let data = dash2sim_linux::ingest::osm::parse_xml(&xml, "test.osm").expect("valid OSM");
    let mut warnings = Vec::new();
    let content = from_osm(&data, Some(origin), &mut warnings);
    assert!(warnings.is_empty(), "{warnings:?}");
    encode(&content, dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M)
}

/// 500 m east from the origin, a node every 5 m.
pub fn straight_road() -> Vec<(f64, f64)> {
    (0..=100).map(|k| (5.0 * f64::from(k), 0.0)).collect()
}
