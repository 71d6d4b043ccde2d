//! The Lanelet2 example map (`../shared/data/osm/lanelet2/mapping_example.osm`, the
//! Lanelet2 project's own sample) through `map build`: every vehicle lanelet becomes a
//! lane (two for `one_way=no`), and the geometry is consistent — each centreline lies
//! inside its lanelet's polygon with the left bound on its left, successors join end to
//! start, neighbours sit a lane width apart.

use dash2sim_core::map::{segment_distance, MapView};
use dash2sim_linux::ingest::map_tile::{encode, from_osm, lanelet2::LANELET_CLASS};
use dash2sim_linux::ingest::osm;

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
    let bytes = encode(&content, dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M);
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

/// The example's tile, or `None` (the test skipped) without the data.
fn example_tile() -> Option<Vec<u8>> {
    let dir = dash2sim_tests::data_dir("osm/lanelet2")?;
    let data = osm::read(&dir.join("mapping_example.osm")).unwrap_or_else(|e| panic!("{e}"));
    Some(encode(&from_osm(&data, None, &mut Vec::new()), dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M))
}

/// The drivable check through the fine polygon index gives the plain check's answers bit for
/// bit on the Lanelet2 example: 20 000 footprints, half near a lanelet (on it, across its
/// bounds, past its ends), half anywhere in the map's box.
#[test]
fn the_polygon_index_gives_the_checks_answers_on_the_lanelet2_example() {
    use dash2sim_core::drivable::{Channel, Checker};
    use dash2sim_core::obb::PACIFICA;

    let Some(bytes) = example_tile() else { return };
    let map = MapView::parse(&bytes).expect("valid tile");
    let arrays = dash2sim_linux::ingest::map_tile::polygon_index::build(&map).expect("Lanelet2 lanes are polygons");
    let (plain, indexed) = (Checker::new(map, PACIFICA), Checker::new(map, PACIFICA).with_index(arrays.view()));
    let (mut corners, mut occupied) = (dash2sim_tests::CornerTally::default(), 0);
    let mut previous = None;
    for (k, pose) in dash2sim_tests::footprints(&map, 20_000, 6.0, 16).iter().enumerate() {
        let (a, b) = (
            plain.check::<1>(pose, Channel::Insensitive, previous),
            indexed.check::<1>(pose, Channel::Insensitive, previous),
        );
        assert_eq!(
            a.corners.map(|d| d.map(f64::to_bits)),
            b.corners.map(|d| d.map(f64::to_bits)),
            "pose {k}: {pose:?}"
        );
        assert_eq!(a, b, "pose {k}: {pose:?}");
        // The centre's lane of the pose before is preferred where lanelets overlap.
        previous = a.centre_lane.map(|c| c.lane);
        occupied += usize::from(!a.occupied.is_empty());
        corners.add(&a.corners);
    }
    println!(
        "{} corners inside, {} outside, {} with nothing within 10 m; {occupied} poses on a lane; index {} bytes",
        corners.inside,
        corners.outside,
        corners.far,
        arrays.bytes()
    );
    assert!(corners.each_over(10_000) && occupied > 8_000);
}

/// The index's promise itself, where it is tightest (cell corners) and in between: a cell's
/// edges hold the nearest edge of all polygons to any point of the cell within 10 m, and an
/// area's listed edges hold its polygon's nearest edge to any point of the cell and decide
/// whether the polygon holds the point as all its edges do.
#[test]
fn the_polygon_index_lists_the_nearest_edges_of_every_cell() {
    use dash2sim_core::drivable::SEARCH_RADIUS;
    use dash2sim_core::map::{edges_distance, edges_parity};
    use rand::{Rng, SeedableRng};

    let Some(bytes) = example_tile() else { return };
    let map = MapView::parse(&bytes).expect("valid tile");
    let arrays = dash2sim_linux::ingest::map_tile::polygon_index::build(&map).expect("Lanelet2 lanes are polygons");
    let index = arrays.view();
    let rings: Vec<Vec<[f32; 4]>> = (0..map.header().polygons)
        .map(|p| {
            let ring: Vec<(f64, f64)> = map.polygon(p).expect("polygon").collect();
            (0..ring.len())
                .map(|j| {
                    let (a, b) = (ring[(j + ring.len() - 1) % ring.len()], ring[j]);
                    [a.0 as f32, a.1 as f32, b.0 as f32, b.1 as f32]
                })
                .collect()
        })
        .collect();
    let all: Vec<[f32; 4]> = rings.concat();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
    let (mut near, mut depths) = (0, 0);
    for k in 0..20_000 {
        // A point near a random vertex; every other one snapped to a 2 m cell corner.
        let [x, y, ..] = all[rng.random_range(0..all.len())];
        let mut p = (f64::from(x) + rng.random_range(-12.0..12.0), f64::from(y) + rng.random_range(-12.0..12.0));
        if k % 2 == 0 {
            p = ((p.0 / 2.0).round() * 2.0 - 1e-9, (p.1 / 2.0).round() * 2.0 - 1e-9);
        }
        let Some(c) = index.cell_of(p.0, p.1) else { continue };
        let nearest = edges_distance(&all, p);
        if nearest <= SEARCH_RADIUS {
            near += 1;
            assert_eq!(edges_distance(index.edges(c), p), nearest, "point {p:?}");
        }
        for area in index.areas(c) {
            let own = &rings[area.polygon as usize];
            assert_eq!(edges_distance(index.area_edges(area.nearest), p), edges_distance(own, p), "{p:?}, {area:?}");
            let holds = area.whole || edges_parity(index.area_edges(area.crossing), p, area.parity);
            assert_eq!(holds, edges_parity(own, p, false), "point {p:?}, area {area:?}");
            depths += 1;
        }
    }
    assert!(near > 10_000 && depths > 10_000, "{near} {depths}");
}
