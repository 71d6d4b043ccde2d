//! The map's metrics for a pose whose position is in doubt (`Scorer::step_in_doubt`, what
//! the device's verification windows use): an excursion smaller than the doubt is forgiven,
//! a larger one is not, and without doubt the judgement is nuPlan's own. And the doubt held
//! against the ego (`Scorer::step_with`, `verify --decide-at`): objects grown, the footprint
//! moved aside.

use dash2sim_core::drivable::{Channel, Checker};
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{OrientedBox, Pose2, PACIFICA};
use dash2sim_core::score::{Agent, AgentKind, Doubt, PlaceSigma, ScoreConfig, Scorer, Scores};
use dash2sim_tests::road::{straight_road, tile};

/// A two-way road along the x axis: the forward lane (heading east) from y = −3.5 to 0, the
/// backward lane from 0 to 3.5.
fn two_way() -> Vec<u8> {
    tile(&straight_road(), &[("lanes", "2"), ("lanes:forward", "1"), ("lanes:backward", "1"), ("width", "7")])
}

/// Three seconds eastward at 10 m/s with the rear axle at `y`, scored with `doubt` m.
fn drive_east(map: MapView<'_>, y: f64, doubt: f64) -> Scores {
    let mut scorer: Scorer<'_, '_, 1> =
        Scorer::new(Checker::new(map, PACIFICA), Channel::Insensitive, ScoreConfig::default());
    for k in 0..30 {
        let t = 0.1 * f64::from(k);
        let pose = Pose2::new(100.0 + 10.0 * t, y, 0.0);
        scorer.step_in_doubt(t, &pose, &[], doubt).expect("a finite pose, later each time");
    }
    scorer.finish(None)
}

#[test]
fn an_excursion_off_the_road_is_forgiven_only_within_the_doubt() {
    let bytes = two_way();
    let map = MapView::parse(&bytes).expect("valid tile");
    // The right-hand corners 0.8 m beyond the road's edge at y = −3.5.
    let y = -3.5 - 0.8 + PACIFICA.width / 2.0;
    let strict = drive_east(map, y, 0.0);
    assert_eq!(strict.drivable_area, 0.0, "{strict:?}");
    assert!((strict.worst_corner - 0.8).abs() < 0.05, "the worst corner is reported as it is: {strict:?}");
    assert_eq!(drive_east(map, y, 0.4).drivable_area, 0.0, "0.8 m is beyond 0.3 m and a doubt of 0.4 m");
    let doubted = drive_east(map, y, 1.0);
    assert_eq!(doubted.drivable_area, 1.0, "{doubted:?}");
    assert!((doubted.worst_corner - 0.8).abs() < 0.05, "the doubt does not move the pose: {doubted:?}");
    // On the road, the doubt changes nothing.
    assert_eq!(drive_east(map, -1.75, 0.0).score, drive_east(map, -1.75, 2.0).score);
}

#[test]
fn a_centre_just_over_the_divider_is_forgiven_and_a_wrong_way_drive_is_not() {
    let bytes = two_way();
    let map = MapView::parse(&bytes).expect("valid tile");
    // The centre (on the rear axle's line) 0.6 m into the oncoming lane, heading east.
    let over = drive_east(map, 0.6, 0.0);
    assert_eq!(over.driving_direction, 0.0, "10 m against the lane each second: {over:?}");
    assert_eq!(drive_east(map, 0.6, 0.4).driving_direction, 0.0);
    let forgiven = drive_east(map, 0.6, 1.0);
    assert_eq!(forgiven.driving_direction, 1.0, "{forgiven:?}");
    assert!(forgiven.verified, "{forgiven:?}");
    // In the middle of the oncoming lane: 1.75 m from the nearest lane heading east.
    let wrong_way = drive_east(map, 1.75, 1.0);
    assert_eq!(wrong_way.driving_direction, 0.0, "{wrong_way:?}");
    assert!(!wrong_way.verified);
    assert_eq!(drive_east(map, 1.75, 2.0).driving_direction, 1.0, "a doubt of 2 m cannot tell the lanes apart");
}

/// Three seconds eastward at 10 m/s with the rear axle at `y`, past a drum at (115, `drum_y`)
/// `grown` m larger on every side (`Agent::grown`), scored with `doubt` (`Scorer::step_with`).
fn drive_past_a_drum(map: MapView<'_>, y: f64, drum_y: f64, grown: f64, doubt: Doubt) -> (Scores, Vec<bool>) {
    let drum = Agent {
        id: 1,
        kind: AgentKind::Object,
        bbox: OrientedBox { centre: Pose2::new(115.0, drum_y, 0.0), length: 0.6, width: 0.6 },
        velocity: (0.0, 0.0),
        sigma_across: PlaceSigma::NONE,
    }
    .grown(grown);
    let mut scorer: Scorer<'_, '_, 1> =
        Scorer::new(Checker::new(map, PACIFICA), Channel::Insensitive, ScoreConfig::default());
    let mut compliant = Vec::new();
    for k in 0..30 {
        let t = 0.1 * f64::from(k);
        let pose = Pose2::new(100.0 + 10.0 * t, y, 0.0);
        compliant.push(scorer.step_with(t, &pose, &[drum], doubt).expect("a finite pose").compliant);
    }
    (scorer.finish(None), compliant)
}

#[test]
fn a_doubt_held_against_the_ego_grows_the_objects_and_moves_it_aside() {
    let bytes = two_way();
    let map = MapView::parse(&bytes).expect("valid tile");
    // The ego's right side 0.2 m clear of a drum's edge: nuPlan's verdict is clean.
    let y = -1.75;
    let drum_y = y - PACIFICA.width / 2.0 - 0.2 - 0.3;
    let (point, _) = drive_past_a_drum(map, y, drum_y, 0.0, Doubt::NONE);
    assert_eq!((point.no_at_fault_collisions, point.verified), (1.0, true), "{point:?}");
    // Each object 0.3 m larger on every side: the ego hits it.
    let (against, _) = drive_past_a_drum(map, y, drum_y, 0.3, Doubt::Against { ego: 0.0 });
    assert_eq!(against.no_at_fault_collisions, 0.5, "a static object at fault: {against:?}");
    // 0.1 m larger: still clear.
    let (near, _) = drive_past_a_drum(map, y, drum_y, 0.1, Doubt::Against { ego: 0.0 });
    assert_eq!(near.no_at_fault_collisions, 1.0, "{near:?}");
    // Held against it, the ego's own doubt moves its footprint aside: in the middle of the
    // forward lane its right-hand corners are 0.6 m inside the road's edge, so 0.8 m aside
    // leaves them 0.2 m out (within nuPlan's 0.3 m) and 1.0 m aside 0.4 m out.
    let (_, inside) = drive_past_a_drum(map, y, 50.0, 0.0, Doubt::Against { ego: 0.8 });
    assert!(inside.iter().all(|c| *c), "0.8 m aside is still within 0.3 m of the road");
    let (aside, outside) = drive_past_a_drum(map, y, 50.0, 0.0, Doubt::Against { ego: 1.0 });
    assert!(outside.iter().all(|c| !*c) && aside.drivable_area == 0.0, "{aside:?}");
    // Given to it, the same doubt changes nothing on the road.
    let (given, _) = drive_past_a_drum(map, y, 50.0, -0.3, Doubt::For { ego: 1.0 });
    assert_eq!(given.score, point.score);
}

/// A drive weaving towards the divider and over the road's edge by 0.4 m, past `agent`,
/// scored with `doubt` m one way by a scorer of its own.
fn weave(map: MapView<'_>, doubt: Doubt, agent: Agent) -> Scores {
    let mut scorer: Scorer<'_, '_, 1> =
        Scorer::new(Checker::new(map, PACIFICA), Channel::Insensitive, ScoreConfig::default());
    for k in 0..60 {
        let t = 0.1 * f64::from(k);
        scorer.step_with(t, &weaving_pose(t), &[agent], doubt).expect("a finite pose");
    }
    scorer.finish(None)
}

fn weaving_pose(t: f64) -> Pose2 {
    Pose2::new(100.0 + 12.0 * t, -1.75 + 1.2 * (0.9 * t).sin(), 0.1 * (0.9 * t).cos())
}

fn drum() -> Agent {
    Agent {
        id: 1,
        kind: AgentKind::Object,
        bbox: OrientedBox { centre: Pose2::new(150.0, -5.5, 0.0), length: 0.6, width: 0.6 },
        velocity: (0.0, 0.0),
        sigma_across: PlaceSigma::NONE,
    }
}

#[test]
fn one_pass_both_ways_scores_as_two_scorers_do() {
    let bytes = two_way();
    let map = MapView::parse(&bytes).expect("valid tile");
    // The weave's rightmost pass (y = −2.95 m, 162.8 m east) 0.4 m clear of a drum's edge,
    // its place known to σ 0.25 m across the path.
    let right_side = -1.75 - 1.2 - PACIFICA.width / 2.0;
    let tight = Agent {
        bbox: OrientedBox { centre: Pose2::new(162.8, right_side - 0.4 - 0.3, 0.0), length: 0.6, width: 0.6 },
        sigma_across: PlaceSigma::from_m(0.25),
        ..drum()
    };
    for (agent, agent_sigmas) in [(drum(), 0.0), (drum(), 2.0), (tight, 0.0), (tight, 2.0)] {
        let by = agent_sigmas * agent.sigma_across.m();
        for doubt in [0.0, 0.3, 0.8, 1.5] {
            let mut both: Scorer<'_, '_, 1> =
                Scorer::new(Checker::new(map, PACIFICA), Channel::Insensitive, ScoreConfig::default());
            for k in 0..60 {
                let t = 0.1 * f64::from(k);
                both.step_both_ways(t, &weaving_pose(t), &[agent], doubt, agent_sigmas).expect("a finite pose");
            }
            let lenient = weave(map, Doubt::For { ego: doubt }, agent.grown(-by));
            let strict = weave(map, Doubt::Against { ego: doubt }, agent.grown(by));
            assert_eq!(both.finish(None), lenient, "doubt {doubt}, {agent:?} × {agent_sigmas}");
            assert_eq!(both.finish_against(None), Some(strict), "doubt {doubt}, {agent:?} × {agent_sigmas}");
            if doubt == 0.8 && agent_sigmas == 0.0 {
                // The weave's excursions are forgiven within 0.8 m of doubt and not held
                // against the ego with it.
                assert_eq!((lenient.drivable_area, strict.drivable_area), (1.0, 0.0), "{lenient:?} {strict:?}");
            }
            // The tight drum is passed clear as placed and shrunk by 2σ; grown by 2σ (0.5 m)
            // it is hit — the collision is in doubt.
            let hit_against = agent == tight && agent_sigmas == 2.0;
            assert_eq!(lenient.no_at_fault_collisions, 1.0, "{agent:?} × {agent_sigmas}: {lenient:?}");
            let expected = if hit_against { 0.5 } else { 1.0 };
            assert_eq!(strict.no_at_fault_collisions, expected, "{agent:?} × {agent_sigmas}: {strict:?}");
        }
    }
    // A scorer stepped one way has nothing held against the ego.
    let mut one: Scorer<'_, '_, 1> =
        Scorer::new(Checker::new(map, PACIFICA), Channel::Insensitive, ScoreConfig::default());
    one.step_in_doubt(0.0, &weaving_pose(0.0), &[], 1.0).expect("a finite pose");
    assert_eq!(one.finish_against(None), None);
}

#[test]
fn a_place_sigma_is_rounded_up_to_five_centimetres_and_saturates() {
    assert_eq!(PlaceSigma::from_m(0.25).m(), 0.25);
    assert!((PlaceSigma::from_m(0.251).m() - 0.30).abs() < 1e-12);
    assert!((PlaceSigma::from_m(0.001).m() - 0.05).abs() < 1e-12);
    assert!((PlaceSigma::from_m(40.0).m() - 12.75).abs() < 1e-12);
    for none in [0.0, -1.0, f64::NAN] {
        assert_eq!(PlaceSigma::from_m(none), PlaceSigma::NONE);
    }
    assert_eq!(PlaceSigma::from_m(f64::INFINITY).m(), PlaceSigma::from_m(40.0).m());
}

#[test]
fn the_motion_beside_gives_comfort_the_benefit_of_the_doubt_only() {
    let bytes = two_way();
    let map = MapView::parse(&bytes).expect("valid tile");
    let checker = Checker::new(map, PACIFICA);
    // A cruise at 12 m/s in the forward lane whose stepped ego is pulled 0.5 m sideways
    // within 0.3 s at 2 s (a correction eased in hard), its motion alone straight.
    let mut scorer: Scorer<'_, '_, 1> = Scorer::new(checker, Channel::Insensitive, ScoreConfig::default());
    let mut plain: Scorer<'_, '_, 1> = Scorer::new(checker, Channel::Insensitive, ScoreConfig::default());
    for k in 0..60 {
        let t = 0.1 * f64::from(k);
        let pulled = 0.5 * ((t - 2.0) / 0.3).clamp(0.0, 1.0);
        let stepped = Pose2::new(100.0 + 12.0 * t, -1.75 + pulled, 0.0);
        scorer.step_both_ways(t, &stepped, &[], 0.0, 0.0).expect("a finite pose");
        scorer.motion_beside(t, &Pose2::new(100.0 + 12.0 * t, -1.75, 0.0));
        plain.step_both_ways(t, &stepped, &[], 0.0, 0.0).expect("a finite pose");
    }
    let against = scorer.finish_against(None).expect("stepped both ways");
    assert_eq!(against.comfort, 0.0, "held against the ego, the stepped path's comfort: {against:?}");
    assert_eq!(scorer.finish(None).comfort, 1.0, "its motion alone is comfortable");
    assert_eq!(plain.finish(None).comfort, 0.0, "with no motion beside, the stepped path decides");
}
