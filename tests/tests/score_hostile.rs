//! The score on hostile input: any poses (NaN, infinite, huge, repeated or backward times),
//! any doubt about them and any agents (NaN or huge boxes and velocities) never panic; bad
//! poses are refused with their reason and leave the state alone; the final metrics stay in
//! range.

use dash2sim_core::drivable::{Channel, Checker};
use dash2sim_core::map::MapView;
use dash2sim_core::obb::{OrientedBox, Pose2, PACIFICA};
use dash2sim_core::score::{Agent, AgentKind, PlaceSigma, ScoreConfig, ScoreError, Scorer};
use dash2sim_tests::road::{straight_road, tile};
use proptest::prelude::*;

fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -50.0..550.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(-1e300),
        1 => Just(1e300),
        1 => Just(0.0),
    ]
}

fn agent() -> impl Strategy<Value = Agent> {
    (0u32..6, 0u8..3, value(), value(), value(), value(), value(), value(), value()).prop_map(
        |(id, kind, x, y, heading, length, width, vx, vy)| Agent {
            id,
            kind: [AgentKind::Vehicle, AgentKind::Vru, AgentKind::Object][usize::from(kind)],
            bbox: OrientedBox { centre: Pose2::new(x, y, heading), length, width },
            velocity: (vx, vy),
            sigma_across: PlaceSigma::NONE,
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn hostile_drives_never_panic_and_scores_stay_in_range(
        steps in prop::collection::vec((-0.2..0.3f64, value(), value(), value(), prop::collection::vec(agent(), 0..4)), 1..60),
        doubt in value(),
    ) {
        let bytes = tile(&straight_road(), &[("lanes", "2"), ("maxspeed", "50")]);
        let map = MapView::parse(&bytes).expect("valid");
        let mut scorer: Scorer<'_, '_, 1> = Scorer::new(Checker::new(map, PACIFICA), Channel::Insensitive, ScoreConfig::default());
        let (mut t, mut last_ok): (f64, Option<f64>) = (0.0, None);
        let mut accepted = 0u32;
        for (dt, x, y, heading, agents) in &steps {
            t += dt;
            let pose = Pose2::new(*x, *y, *heading);
            // A device's doubt (`step_in_doubt`) may be anything too: NaN and infinite are none.
            match scorer.step_in_doubt(t, &pose, agents, doubt) {
                Ok(report) => {
                    prop_assert!(pose.is_finite());
                    prop_assert!(last_ok.is_none_or(|l| t > l));
                    prop_assert!(report.speed >= 0.0 || report.speed.is_nan());
                    last_ok = Some(t);
                    accepted += 1;
                }
                Err(ScoreError::NotFinite) => prop_assert!(!pose.is_finite()),
                Err(ScoreError::TimeNotIncreasing) => prop_assert!(last_ok.is_some_and(|l| t <= l)),
            }
        }
        let s = scorer.finish(None);
        prop_assert_eq!(s.poses, accepted);
        for m in [s.no_at_fault_collisions, s.drivable_area, s.driving_direction, s.making_progress, s.progress, s.ttc, s.speed_limit, s.comfort] {
            prop_assert!((0.0..=1.0).contains(&m), "{:?}", s);
        }
        prop_assert!((0.0..=100.0).contains(&s.score), "{:?}", s);
        prop_assert_eq!(s.verified, s.score > 90.0);
    }
}
