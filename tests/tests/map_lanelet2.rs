//! The Lanelet2 example map (`../shared/data/osm/lanelet2/mapping_example.osm`, the
//! Lanelet2 project's own sample) through `map build`: every vehicle lanelet becomes a
//! lane (two for `one_way=no`), and the geometry is consistent — each centreline lies
//! inside its lanelet's polygon with the left bound on its left, successors join end to
//! start, neighbours sit a lane width apart.

use dash2sim_core::map::{segment_distance, MapView};
use dash2sim_linux::map_tile::{encode, from_osm, lanelet2::LANELET_CLASS};
use dash2sim_linux::osm;

#[test]
fn the_lanelet2_example_becomes_consistent_lanes() {
    let Some(dir) = dash2sim_tests::data_dir("osm/lanelet2") else { return };
    let data = osm::read(&dir.join("mapping_example.osm")).unwrap_or_else(|e| panic!("{e}"));
    // Counted straight from the relations' tags, independently of the importer.
    let vehicle: Vec<&osm::Relation> = data
        .relations
        .iter()
        .filter(|r| r.tag("type") == Some("lanelet"))
        .filter(|r| matches!(r.tag("subtype"), Some("road" | "highway") | None))
        .collect();
    let two_way = vehicle.iter().filter(|r| r.tag("one_way") == Some("no")).count();
    let mut warnings = Vec::new();
    let content = from_osm(&data, None, &mut warnings);
    assert!(warnings.is_empty(), "{warnings:?}");
    let bytes = encode(&content, dash2sim_linux::map_tile::DEFAULT_CELL_M);
    let map = MapView::parse(&bytes).expect("valid tile");
    println!(
        "{} vehicle lanelets ({two_way} two-way) → {} lanes, {} bytes",
        vehicle.len(),
        map.header().lanes,
        bytes.len()
    );
    assert_eq!(map.header().lanes as usize, vehicle.len() + two_way);
    assert_eq!(map.header().polygons as usize, vehicle.len());

    let (mut successors, mut neighbours) = (0, 0);
    for i in 0..map.header().lanes {
        let lane = map.lane(i).expect("lane");
        assert_eq!(lane.class, LANELET_CLASS);
        // Widths are mean distances between the bounds; a few lanelets fan out (bounds
        // of very different lengths), so only a floor is asserted.
        assert!(lane.width > 1.0, "lane {i}: width {}", lane.width);
        let points: Vec<(f64, f64)> = lane.points().collect();
        // Every centreline point is inside the polygon (the ends lie on its edges).
        for &(x, y) in &points[1..points.len() - 1] {
            assert!(lane.distance_outside(x, y) < 0.0, "lane {i}: centreline leaves its lanelet");
        }
        // The polygon runs forward along the left bound and back along the right one, so
        // it is clockwise when the left bound is on the left of the lanelet's direction.
        // A two-way lanelet's reverse lane follows it, sharing the polygon, its
        // centreline reversed.
        let area = lane.area.expect("lanelet lanes have areas");
        let ring: Vec<(f64, f64)> = map.polygon(area).expect("polygon").collect();
        let signed_area: f64 = (0..ring.len())
            .map(|k| {
                let (a, b) = (ring[k], ring[(k + 1) % ring.len()]);
                a.0 * b.1 - b.0 * a.1
            })
            .sum::<f64>()
            / 2.0;
        assert!(signed_area < 0.0, "lane {i}: left bound on the wrong side ({signed_area} m²)");
        if let Some(forward) = map.lane(i.wrapping_sub(1)).filter(|p| p.area == Some(area)) {
            let mut back: Vec<(f64, f64)> = forward.points().collect();
            back.reverse();
            assert_eq!(back, points, "lane {i} is lane {}'s reverse", i - 1);
        }
        for s in lane.successors() {
            let next: Vec<(f64, f64)> = map.lane(s).expect("successor").points().collect();
            let gap = (points[points.len() - 1].0 - next[0].0).hypot(points[points.len() - 1].1 - next[0].1);
            assert!(gap < 0.5, "lane {i} → {s}: {gap} m apart");
            successors += 1;
        }
        if let Some(r) = lane.right {
            let right = map.lane(r).expect("neighbour");
            assert_eq!(right.left, Some(i), "neighbours are mutual");
            // Its centreline lies to the right, across the shared bound.
            let theirs: Vec<(f64, f64)> = right.points().collect();
            let q = theirs[theirs.len() / 2];
            let (a, b) = points
                .windows(2)
                .map(|w| (w[0], w[1]))
                .min_by(|s, t| segment_distance(q, s.0, s.1).total_cmp(&segment_distance(q, t.0, t.1)))
                .expect("segments");
            let cross = (b.0 - a.0) * (q.1 - a.1) - (b.1 - a.1) * (q.0 - a.0);
            assert!(cross < 0.0 && segment_distance(q, a, b) < 10.0, "lane {i} ↔ {r}: not on the right");
            neighbours += 1;
        }
    }
    println!("{successors} successor links, {neighbours} neighbour pairs");
    assert!(successors > 300 && neighbours > 20, "{successors} {neighbours}");
}
