//! The nuPlan map of a real village's OpenStreetMap roads (Ulm, `../shared/data/osm/osmnx`):
//! nuPlan looks up *the* lane under a point and refuses two, so at every junction the lanes
//! must be cut and lane connectors must carry the drive across (issue #15).
//!
//! The drive (`tests/fixtures/village-junctions.tum`, 44 s at 3 m/s straight through four
//! junctions along the map's own lanes and connectors) was made by
//! `scripts/nuplan_junction_drive.py`; `.ci/run` replays it in nuPlan's simulator and compares
//! nuPlan's metrics with `verify`'s. Here: the geometry those metrics rely on.

use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use dash2sim_export::nuplan::gpkg::Layer;
use dash2sim_export::nuplan::map::layers;
use dash2sim_export::projection::Projection;
use dash2sim_linux::geometry::contains;
use dash2sim_tests::{data_dir, workspace_root};

const ORIGIN: (f64, f64) = (48.135_704_8, 10.069_590_1);
/// Grid of the overlap search, m.
const GRID_M: f64 = 0.2;

fn polygons<'a>(all: &'a [Layer], name: &str) -> Vec<&'a [(f64, f64)]> {
    let layer = all.iter().find(|l| l.name == name).unwrap_or_else(|| panic!("no layer {name}"));
    layer.features.iter().map(|(_, g, _)| g.points()).collect()
}

fn bounds(ring: &[(f64, f64)]) -> [f64; 4] {
    ring.iter().fold([f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY], |b, p| {
        [b[0].min(p.0), b[1].min(p.1), b[2].max(p.0), b[3].max(p.1)]
    })
}

/// Points of a `GRID_M` grid that lie in two of `rings`: (first ring, second ring, count).
fn shared_points(rings: &[&[(f64, f64)]]) -> Vec<(usize, usize, usize)> {
    let boxes: Vec<[f64; 4]> = rings.iter().map(|r| bounds(r)).collect();
    let mut shared = Vec::new();
    for a in 0..rings.len() {
        for b in a + 1..rings.len() {
            let (p, q) = (boxes[a], boxes[b]);
            let (x0, y0, x1, y1) = (p[0].max(q[0]), p[1].max(q[1]), p[2].min(q[2]), p[3].min(q[3]));
            let mut count = 0;
            let mut x = (x0 / GRID_M).floor() * GRID_M;
            while x <= x1 {
                let mut y = (y0 / GRID_M).floor() * GRID_M;
                while y <= y1 {
                    count += usize::from(contains(rings[a], (x, y)) && contains(rings[b], (x, y)));
                    y += GRID_M;
                }
                x += GRID_M;
            }
            if count > 0 {
                shared.push((a, b, count));
            }
        }
    }
    shared
}

#[test]
fn village_lanes_never_overlap_and_connectors_carry_the_drive_through_its_junctions() {
    let Some(dir) = data_dir("osm/osmnx") else { return };
    let osm = dash2sim_linux::ingest::osm::read(&dir.join("planet_10.068_48.135_10.071_48.137.osm")).expect("osm");
    let origin = Geodetic::new(ORIGIN.0, ORIGIN.1, 0.0).expect("origin");
    let content = dash2sim_linux::ingest::map_tile::from_osm(&osm, Some(origin), &mut Vec::new());
    let tile = dash2sim_linux::ingest::map_tile::encode(&content, dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M);
    let view = MapView::parse(&tile).expect("tile");
    let projection = Projection::new(origin).expect("projection");
    let (all, ids) = layers(&view, &projection).expect("layers");

    let lanes = polygons(&all, "lanes_polygons");
    let connectors = polygons(&all, "gen_lane_connectors_scaled_width_polygons");
    // The ways are cut where others join them: more lanes than the tile has, and turns.
    assert!(lanes.len() > content.lanes.len(), "{} pieces of {} lanes", lanes.len(), content.lanes.len());
    assert!(connectors.len() > lanes.len(), "{} connectors", connectors.len());
    // No point lies in two lanes, nor in two roadblocks (nuPlan's get_one_map_object).
    assert_eq!(shared_points(&lanes), vec![], "lanes overlap (index, index, grid points)");
    assert_eq!(shared_points(&polygons(&all, "lane_groups_polygons")), vec![], "roadblocks overlap");

    // The drive: every pose in at most one lane, and in a lane or a connector (nuPlan's route
    // extraction finds an object for it); it crosses junctions (poses in connectors only)
    // and passes through several roadblocks in order.
    let tum = std::fs::read_to_string(workspace_root().join("tests/fixtures/village-junctions.tum")).expect("fixture");
    let enu: Vec<(f64, f64, f64)> = tum
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|f| f.parse().expect("number")).collect();
            (v[1], v[2], 0.0)
        })
        .collect();
    let poses = projection.project(&enu);
    assert_eq!(poses.len(), 441);
    let (mut in_junction, mut route) = (0, Vec::new());
    for (k, &p) in poses.iter().enumerate() {
        let in_lanes = lanes.iter().filter(|r| contains(r, p)).count();
        let in_connectors = connectors.iter().filter(|r| contains(r, p)).count();
        assert!(in_lanes <= 1, "pose {k} lies in {in_lanes} lanes");
        assert!(in_lanes + in_connectors >= 1, "pose {k} lies in no lane and no connector");
        in_junction += usize::from(in_lanes == 0);
        if let Some(r) = ids.roadblock_at(p) {
            if route.last() != Some(&r) {
                route.push(r);
            }
        }
    }
    assert!(in_junction > 20, "{in_junction} poses between lanes");
    let mut distinct = route.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert!(route.len() >= 5 && distinct.len() == route.len(), "roadblocks along the drive: {route:?}");
}
