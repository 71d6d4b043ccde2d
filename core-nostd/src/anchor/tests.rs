//! Synthetic drives with known answers for the anchorer.

use nalgebra::{Rotation3, Unit, Vector3};

use super::*;
use crate::sim3::rotation_z;

fn ts(s: f64) -> Timestamp {
    Timestamp::from_secs_f64(s).expect("finite")
}

/// A drive with a curve, a hill and a speed change; positions in ENU at time t.
fn truth_at(t: f64) -> Vector3<f64> {
    // Speed rises from 10 to 20 m/s; heading turns by 90° over the drive.
    let s = 10.0 * t + 0.25 * t * t;
    let heading = (s / 600.0) * core::f64::consts::FRAC_PI_2;
    let radius = 600.0 / core::f64::consts::FRAC_PI_2;
    Vector3::new(radius * libm::sin(heading), radius * (1.0 - libm::cos(heading)), 5.0 * libm::sin(t / 7.0))
}

fn speed_at(t: f64) -> f64 {
    10.0 + 0.5 * t
}

struct Run {
    anchorer: Anchorer,
    truth: Sim3,
}

/// Feed `seconds` of VO at 20 Hz, fixes at 10 Hz delayed by `latency`, speed at 50 Hz
/// reading `wheel_bias` times the truth.
fn drive(config: AnchorConfig, truth: Sim3, seconds: f64, latency: f64, wheel_bias: f64, planar_line: bool) -> Run {
    let mut anchorer: Anchorer = Anchorer::new(config);
    let inverse = truth.inverse();
    let path = |t: f64| if planar_line { Vector3::new(10.0 * t + 0.25 * t * t, 0.0, 0.0) } else { truth_at(t) };
    let steps = (seconds * 100.0) as usize;
    for k in 0..=steps {
        let t = k as f64 * 0.01;
        if k % 2 == 0 {
            anchorer.push_speed(ts(t), speed_at(t) * wheel_bias).expect("valid speed");
        }
        if k % 10 == 0 && t > latency {
            anchorer.push_gnss(ts(t), path(t - latency), 1.0).expect("valid fix");
        }
        if k % 5 == 0 {
            anchorer.push_vo(ts(t), inverse.transform_point(&path(t))).expect("valid VO");
        }
    }
    Run { anchorer, truth }
}

fn arbitrary() -> Sim3 {
    let axis = Unit::new_normalize(Vector3::new(1.0, -2.0, 0.5));
    Sim3 {
        rotation: *Rotation3::from_axis_angle(&axis, 1.2).matrix(),
        translation: Vector3::new(30.0, -4.0, 2.0),
        scale: 0.4,
    }
}

#[test]
fn recovers_the_similarity_of_a_noise_free_drive() {
    let run = drive(AnchorConfig::default(), arbitrary(), 30.0, 0.0, 1.0, false);
    let q = run.anchorer.quality();
    assert_eq!(q.observability, Observability::Observable);
    let est = run.anchorer.estimate().expect("estimate");
    // The wheel odometer integrates speed (trapezoids): ten ppm of path error, which the
    // fused scale shares (the fixes' own scale is weighed at their stated σ).
    assert!((est.scale / run.truth.scale - 1.0).abs() < 2e-5, "scale {}", est.scale);
    assert!((est.rotation - run.truth.rotation).norm() < 1e-6);
    // The scale's ten ppm at the fixes' centroid, some hundred metres out.
    assert!(
        (est.translation - run.truth.translation).norm() < 1e-2,
        "{}",
        (est.translation - run.truth.translation).norm()
    );
    assert!(q.rms_residual_m < 1e-2, "{q:?}");
    assert_eq!(q.latency_s, Some(0.0));
    // The position rests on the latest fixes (σ 1 m stated, the residuals' variance
    // factor at its floor of 0.1): √(2·0.1) m, the geometry's share, and the speed times
    // the latency's σ (nine hypotheses 25 ms apart: 0.2 s/√12) — the speed over the VO's
    // last half second, 29.5–30 s (the last fix waits for the VO of its instant).
    let speed = (truth_at(30.0) - truth_at(29.5)).norm() / 0.5;
    let latency_m = speed * 0.2 / libm::sqrt(12.0);
    assert!(latency_m > 1.4, "{latency_m}");
    let expected = libm::sqrt(0.2 + q.geometry_sigma_m * q.geometry_sigma_m + latency_m * latency_m);
    assert!((q.position_sigma_m - expected).abs() < 1e-5, "{q:?} against {expected}");
}

#[test]
fn estimates_a_gnss_latency_when_the_speed_changes() {
    let run = drive(AnchorConfig::default(), arbitrary(), 40.0, 0.060, 1.0, false);
    let latency = run.anchorer.quality().latency_s.expect("latency");
    assert!((latency - 0.060).abs() < 0.010, "latency {latency}");
    let est = run.anchorer.estimate().expect("estimate");
    assert!((est.scale / run.truth.scale - 1.0).abs() < 1e-3);
}

#[test]
fn calibrates_biased_wheel_speed_against_the_gnss_path() {
    let run = drive(AnchorConfig::default(), arbitrary(), 30.0, 0.0, 0.99, false);
    let factor = run.anchorer.quality().wheel_factor.expect("calibrated");
    assert!((factor - 1.0 / 0.99).abs() < 1e-3, "factor {factor}");
}

#[test]
fn a_straight_line_is_unobservable_in_full_mode_but_fine_when_gravity_aligned() {
    let full = drive(AnchorConfig::default(), arbitrary(), 20.0, 0.0, 1.0, true);
    assert_ne!(full.anchorer.quality().observability, Observability::Observable);
    assert!(full.anchorer.estimate().is_none(), "no wild estimate on a line");

    let yaw_only = Sim3 { rotation: rotation_z(2.0), translation: Vector3::new(1.0, 2.0, 3.0), scale: 2.0 };
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let four = drive(config, yaw_only, 20.0, 0.0, 1.0, true);
    assert_eq!(four.anchorer.quality().observability, Observability::Observable);
    let est = four.anchorer.estimate().expect("estimate");
    assert!((est.scale - 2.0).abs() < 1e-6);
    assert!((est.rotation - yaw_only.rotation).norm() < 1e-6);
}

#[test]
fn a_multipath_jump_is_rejected_and_changes_nothing() {
    let mut a = drive(AnchorConfig::default(), arbitrary(), 20.0, 0.0, 1.0, false).anchorer;
    let before = *a.estimate().expect("estimate");
    let inverse = arbitrary().inverse();
    let t = 20.05;
    a.push_speed(ts(t), speed_at(t)).expect("speed");
    a.push_gnss(ts(t), truth_at(t) + Vector3::new(0.0, 50.0, 0.0), 1.0).expect("fix");
    a.push_vo(ts(t), inverse.transform_point(&truth_at(t))).expect("vo");
    assert_eq!(a.quality().anchors_rejected, 1);
    assert_eq!(*a.estimate().expect("estimate"), before);
}

#[test]
fn bad_input_is_refused_and_leaves_the_state_alone() {
    let mut a: Anchorer = Anchorer::new(AnchorConfig::default());
    a.push_vo(ts(1.0), Vector3::zeros()).expect("first");
    assert_eq!(a.push_vo(ts(1.0), Vector3::zeros()), Err(AnchorError::OutOfOrder));
    assert_eq!(a.push_vo(ts(2.0), Vector3::new(f64::NAN, 0.0, 0.0)), Err(AnchorError::NonFinite));
    assert_eq!(a.push_gnss(ts(1.0), Vector3::zeros(), 0.0), Err(AnchorError::InvalidSigma));
    assert_eq!(a.push_gnss(ts(1.0), Vector3::zeros(), f64::INFINITY), Err(AnchorError::InvalidSigma));
    assert_eq!(a.push_gnss(ts(1.0), Vector3::new(0.0, f64::INFINITY, 0.0), 1.0), Err(AnchorError::NonFinite));
    assert_eq!(a.push_speed(ts(1.0), f64::NAN), Err(AnchorError::NonFinite));
    a.push_speed(ts(1.0), 3.0).expect("speed");
    assert_eq!(a.push_speed(ts(0.5), 3.0), Err(AnchorError::OutOfOrder));
    a.push_gnss(ts(0.9), Vector3::zeros(), 1.0).expect("fix");
    assert_eq!(a.push_gnss(ts(0.8), Vector3::zeros(), 1.0), Err(AnchorError::OutOfOrder));
    assert_eq!(a.quality().anchors_used, 0, "a fix before any VO cannot be paired");
    assert_eq!(a.quality().anchors_dropped, 1);
}

#[test]
fn fixes_waiting_for_stalled_vo_are_bounded() {
    let mut a: Anchorer = Anchorer::new(AnchorConfig::default());
    a.push_vo(ts(0.0), Vector3::zeros()).expect("vo");
    for k in 1..=20 {
        a.push_gnss(ts(k as f64 * 0.1), Vector3::new(k as f64, 0.0, 0.0), 1.0).expect("fix");
    }
    assert_eq!(a.quality().anchors_dropped, 20 - PENDING_ANCHORS as u32);
}

#[test]
fn sigma_from_gst_or_hdop() {
    assert_eq!(gnss_sigma(Some(1.2), None, 2.5), Some(3.0));
    let s = gnss_sigma(Some(1.2), Some((0.6, 0.8)), 2.5).expect("gst");
    assert!((s - libm::sqrt(0.5)).abs() < 1e-12);
    assert_eq!(gnss_sigma(None, None, 2.5), None);
    assert_eq!(gnss_sigma(Some(f64::NAN), Some((f64::NAN, 1.0)), 2.5), None);
}

#[test]
fn a_lasting_shift_of_the_fixes_is_followed_not_rejected_forever() {
    let mut a = drive(AnchorConfig::default(), arbitrary(), 20.0, 0.0, 1.0, false).anchorer;
    let inverse = arbitrary().inverse();
    let shift = Vector3::new(0.0, 30.0, 0.0);
    for k in 1..=3000 {
        let t = 20.0 + k as f64 * 0.01;
        if k % 2 == 0 {
            a.push_speed(ts(t), speed_at(t)).expect("speed");
        }
        if k % 10 == 0 {
            a.push_gnss(ts(t), truth_at(t) + shift, 1.0).expect("fix");
        }
        if k % 5 == 0 {
            a.push_vo(ts(t), inverse.transform_point(&truth_at(t))).expect("vo");
        }
    }
    let q = a.quality();
    assert!(q.anchors_rejected >= MAX_CONSECUTIVE_REJECTIONS, "the shift was first rejected");
    let now = truth_at(50.0) + shift;
    let followed = a.current_position().expect("estimate");
    assert!((followed - now).norm() < 0.1, "still {} m away after 30 s", (followed - now).norm());
}

// `replay_anchor_input`: the `anchor_inputs` fuzz target's own decoding of its input.
include!("../../../fuzz/anchor_input.rs");

#[test]
fn fuzz_regression_overflowing_translation() {
    // Huge but finite coordinates overflowed the translation of an otherwise valid
    // estimate (found by `cargo fuzz run anchor_inputs`).
    replay_anchor_input(include_bytes!("../../../fuzz/regressions/anchor_inputs-overflowing-translation.bin"));
}

/// A straight road at `speed` m/s along `heading`, seen through `truth` (VO → ENU): the
/// wheels at 50 Hz, a fix every `fix_every` hundredths of a second with deterministic noise
/// of `fix_sigma` per axis (uncorrelated from fix to fix), VO every 50 ms.
struct StraightRoad {
    truth: Sim3,
    speed: f64,
    heading: f64,
    fix_every: usize,
    /// The σ each fix states.
    fix_sigma: f64,
    /// The σ of the fixes' noise per horizontal axis (the stated σ unless a test says).
    noise_sigma: f64,
    /// A step (m) of the VO across the road at 60 s: the relative motion's drift, sudden.
    vo_step_m: f64,
}

impl StraightRoad {
    /// Fixes whose noise is the σ they state, the VO exact.
    fn new(truth: Sim3, speed: f64, heading: f64, fix_every: usize, fix_sigma: f64) -> Self {
        StraightRoad { truth, speed, heading, fix_every, fix_sigma, noise_sigma: fix_sigma, vo_step_m: 0.0 }
    }

    /// `seconds` of it into `anchorer`, `before(t, anchorer)` at each 10 ms step: the time
    /// the anchorer first became observable.
    fn drive(&self, anchorer: &mut Anchorer, seconds: f64, mut before: impl FnMut(f64, &mut Anchorer)) -> Option<f64> {
        let inverse = self.truth.inverse();
        let direction = Vector3::new(libm::cos(self.heading), libm::sin(self.heading), 0.0);
        let path = |t: f64| direction * self.speed * t;
        let amplitude = self.noise_sigma * core::f64::consts::SQRT_2;
        let across = Vector3::new(-libm::sin(self.heading), libm::cos(self.heading), 0.0);
        let wander = |t: f64| if t < 60.0 { Vector3::zeros() } else { across * self.vo_step_m };
        let mut observable = None;
        for k in 0..=(seconds * 100.0) as usize {
            let t = k as f64 * 0.01;
            before(t, anchorer);
            if k % 2 == 0 {
                anchorer.push_speed(ts(t), self.speed).expect("valid speed");
            }
            if k % self.fix_every == 0 && k > 0 {
                let n = (k / self.fix_every) as f64;
                let noise =
                    Vector3::new(amplitude * libm::sin(n * 12.9898), amplitude * libm::sin(n * 78.233 + 1.0), 0.0);
                anchorer.push_gnss(ts(t), path(t) + noise, self.fix_sigma).expect("valid fix");
            }
            if k % 5 == 0 {
                anchorer.push_vo(ts(t), inverse.transform_point(&(path(t) + wander(t)))).expect("valid VO");
            }
            if observable.is_none() && anchorer.quality().observability == Observability::Observable {
                observable = Some(t);
            }
        }
        observable
    }
}

/// A new VO session on a straight road at 10 m/s (gravity-aligned, turned by 2 rad and
/// scaled by 1/4), fixes at 5 Hz with σ 1.5 m and the wheels, with a rotation prior
/// `(yaw error, σ)` when given: the anchorer after `seconds`, with the time it first became
/// observable.
fn straight_session(prior: Option<(f64, f64)>, seconds: f64) -> (Anchorer, Option<f64>, Sim3) {
    let truth = Sim3 { rotation: rotation_z(2.0), translation: Vector3::new(50.0, -20.0, 0.0), scale: 4.0 };
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let mut anchorer: Anchorer = Anchorer::new(config);
    if let Some((yaw_error, sigma)) = prior {
        anchorer.set_rotation_prior(rotation_z(2.0 + yaw_error), sigma).expect("a rotation");
    }
    let road = StraightRoad::new(truth, 10.0, 0.3, 20, 1.5);
    let observable = road.drive(&mut anchorer, seconds, |_, _| {});
    (anchorer, observable, truth)
}

fn yaw_error_deg(anchorer: &Anchorer, truth: &Sim3) -> f64 {
    let r = anchorer.estimate().expect("an estimate").rotation * truth.rotation.transpose();
    libm::atan2(r[(1, 0)], r[(0, 0)]).to_degrees()
}

#[test]
fn a_rotation_prior_anchors_a_straight_session_in_seconds() {
    let (without, observable_without, _) = straight_session(None, 2.0);
    assert!(observable_without.is_none(), "two seconds of a straight road alone: {:?}", without.quality());
    let (with, observable_with, truth) = straight_session(Some((0.5f64.to_radians(), 1f64.to_radians())), 2.0);
    assert!(observable_with.is_some_and(|t| t <= 2.0), "{observable_with:?} {:?}", with.quality());
    assert!(yaw_error_deg(&with, &truth).abs() < 1.0, "{}", yaw_error_deg(&with, &truth));
    // About the prior's own σ, forgotten for two seconds (1° · e^(2/24)); the fixes alone
    // say far less.
    let (sigma_with, sigma_without) = (with.quality().rotation_sigma_rad, without.quality().rotation_sigma_rad);
    assert!(sigma_with < 1.2f64.to_radians(), "{:?}", with.quality());
    assert!(sigma_without > 2.0 * sigma_with, "{sigma_without} {sigma_with}");
}

#[test]
fn a_wrong_prior_fades_as_the_fixes_come() {
    // 5° off while claiming 1°: the fixes take over as the prior is forgotten.
    let (early, _, truth) = straight_session(Some((5f64.to_radians(), 1f64.to_radians())), 3.0);
    let (late, _, _) = straight_session(Some((5f64.to_radians(), 1f64.to_radians())), 60.0);
    let (e0, e1) = (yaw_error_deg(&early, &truth), yaw_error_deg(&late, &truth));
    assert!(e0 > 2.0, "early on the prior weighs in: {e0}");
    assert!(e1.abs() < 0.5, "after a minute the fixes decide: {e1}");
}

#[test]
fn a_prior_that_is_not_a_rotation_is_refused() {
    let mut a: Anchorer = Anchorer::new(AnchorConfig::default());
    let reflection = nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0));
    assert_eq!(a.set_rotation_prior(reflection, 0.01), Err(AnchorError::NotARotation));
    assert_eq!(a.set_rotation_prior(rotation_z(1.0) * 1.1, 0.01), Err(AnchorError::NotARotation));
    assert_eq!(a.set_rotation_prior(rotation_z(f64::NAN), 0.01), Err(AnchorError::NonFinite));
    assert_eq!(a.set_rotation_prior(rotation_z(1.0), 0.0), Err(AnchorError::InvalidSigma));
    assert_eq!(a.set_rotation_prior(rotation_z(1.0), f64::INFINITY), Err(AnchorError::InvalidSigma));
    assert_eq!(a.set_rotation_prior(rotation_z(1.0), 1e-200), Err(AnchorError::InvalidSigma));
    assert!(a.prior.is_none());
}

/// A straight session of a phone-grade receiver: VO in an arbitrary 3D frame (scale 0.4),
/// 25 m/s along a line, fixes every 2 s with σ 8.3 m, the wheels; the anchorer in full
/// Sim(3) mode, levelled by `level_at` (the VO's true vertical, s) when given. Returns it
/// after `seconds`, with the time it first became observable.
fn phone_session(level_at: Option<f64>, seconds: f64) -> (Anchorer, Option<f64>, Sim3) {
    let truth = arbitrary();
    let mut anchorer: Anchorer = Anchorer::new(AnchorConfig::default());
    let up_in_vo = truth.rotation.transpose() * Vector3::z();
    let road = StraightRoad::new(truth, 25.0, 1.1, 200, 8.3);
    let observable = road.drive(&mut anchorer, seconds, |t, a| {
        if level_at.is_some_and(|at| (t - at).abs() < 0.005) {
            a.level(&(up_in_vo * 3.0)).expect("a vertical");
        }
    });
    (anchorer, observable, truth)
}

#[test]
fn gravity_anchors_a_straight_road_that_positions_alone_cannot() {
    fn rotation_error_deg(anchorer: &Anchorer, truth: &Sim3) -> f64 {
        let turn = anchorer.estimate().expect("an estimate").rotation * truth.rotation.transpose();
        libm::acos(((turn.trace() - 1.0) / 2.0).clamp(-1.0, 1.0)).to_degrees()
    }
    // A minute on a straight road: the positions may be placed, but the roll about the
    // road stays unknown to the fixes (a bend would show it wrong).
    let (alone, _, truth) = phone_session(None, 60.0);
    assert_eq!(alone.mode(), AnchorMode::Full);
    assert!(alone.quality().rotation_sigma_rad > 1.0, "{:?}", alone.quality());
    // Levelled from the start: observable within 15 s of the first fix (at 2 s), the whole
    // rotation known (its yaw to the fixes' precision), the scale and the position right.
    let (levelled, observable, _) = phone_session(Some(0.0), 60.0);
    assert_eq!(levelled.mode(), AnchorMode::GravityAligned);
    assert!(observable.is_some_and(|t| t <= 17.0), "{observable:?} {:?}", levelled.quality());
    assert!(levelled.quality().rotation_sigma_rad < 1f64.to_radians(), "{:?}", levelled.quality());
    let error = rotation_error_deg(&levelled, &truth);
    assert!(error < 1.0, "rotation off by {error}° (without gravity {}°)", rotation_error_deg(&alone, &truth));
    let e = levelled.estimate().expect("an estimate");
    assert!((e.scale / truth.scale - 1.0).abs() < 0.02, "scale {} vs {}", e.scale, truth.scale);
    let position = levelled.current_position().expect("a position");
    let true_position = Vector3::new(1500.0 * libm::cos(1.1), 1500.0 * libm::sin(1.1), 0.0);
    assert!((position - true_position).norm() < 10.0, "{position}");
}

#[test]
fn levelling_late_loses_nothing_the_session_learnt() {
    // The moments are turned, not restarted: levelled after 9 s (four fixes in) or before
    // the first, the fits agree — to what the first fixes' robust weights, taken against
    // the full fit rather than the levelled one, make of them.
    let (early, _, _) = phone_session(Some(0.0), 30.0);
    let (late, _, _) = phone_session(Some(9.0), 30.0);
    assert_eq!(early.quality().anchors_used, late.quality().anchors_used);
    let (a, b) = (early.estimate().expect("early"), late.estimate().expect("late"));
    let turn = a.rotation * b.rotation.transpose();
    let angle = libm::acos(((turn.trace() - 1.0) / 2.0).clamp(-1.0, 1.0)).to_degrees();
    assert!(angle < 0.1, "{angle}°");
    assert!((a.scale / b.scale - 1.0).abs() < 5e-3, "{} vs {}", a.scale, b.scale);
    let (p, q) = (early.current_position().expect("early"), late.current_position().expect("late"));
    // Within a third of the fixes' σ (8.3 m): the latency hypotheses, scored against
    // different early fits, lead to slightly different recent translations.
    assert!((p - q).norm() < 3.0, "{p} vs {q}");
}

#[test]
fn a_vertical_that_is_not_a_direction_is_refused() {
    let mut a: Anchorer = Anchorer::new(AnchorConfig::default());
    assert_eq!(a.level(&Vector3::zeros()), Err(AnchorError::NonFinite));
    assert_eq!(a.level(&Vector3::new(0.0, f64::NAN, 1.0)), Err(AnchorError::NonFinite));
    assert_eq!(a.mode(), AnchorMode::Full);
    // Straight down is a vertical too (half a turn).
    assert_eq!(a.level(&Vector3::new(0.0, 0.0, -2.0)), Ok(()));
    assert_eq!(a.mode(), AnchorMode::GravityAligned);
}

#[test]
fn the_gnss_course_gives_an_unanchored_session_its_yaw() {
    // The phone's straight road, gravity-aligned: its fixes alone take a while; with the
    // course of each fix (σ 1°) the session's yaw is known from the first fix on.
    let truth = Sim3 { rotation: rotation_z(-2.5), translation: Vector3::new(3.0, 4.0, 0.0), scale: 0.4 };
    let road = StraightRoad::new(truth, 25.0, 1.1, 200, 8.3);
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let course = core::f64::consts::FRAC_PI_2 - 1.1;
    let mut alone: Anchorer = Anchorer::new(config);
    road.drive(&mut alone, 10.5, |_, _| {});
    let mut with: Anchorer = Anchorer::new(config);
    let mut taken = 0;
    let observable = road.drive(&mut with, 10.5, |t, a| {
        // Each fix's course, pushed as the receiver sends it (just before the fix).
        if ((t * 100.0).round() as usize).is_multiple_of(200) && t > 0.0 {
            taken += usize::from(a.push_course(ts(t), course, 1f64.to_radians()));
        }
    });
    assert_eq!(taken, 1, "taken once, while the session had no prior");
    // Observable at the fifth fix, the least it asks for, with the yaw of the course.
    assert!(observable.is_some_and(|t| t <= 10.0), "{observable:?}");
    assert!(yaw_error_deg(&with, &truth).abs() < 1.0, "{}", yaw_error_deg(&with, &truth));
    let (sigma_with, sigma_alone) = (with.quality().rotation_sigma_rad, alone.quality().rotation_sigma_rad);
    assert!(sigma_with < 0.6 * sigma_alone, "yaw σ {sigma_with} with the course, {sigma_alone} from five fixes");
}

#[test]
fn a_course_on_a_bend_or_before_the_vo_has_moved_is_not_taken() {
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let mut a: Anchorer = Anchorer::new(config);
    assert!(!a.push_course(ts(1.0), 0.3, 0.02), "no VO yet");
    // A bend: 0.3 rad/s while the wheels read 10 m/s.
    for k in 0..=300 {
        let t = k as f64 * 0.01;
        if k % 2 == 0 {
            a.push_speed(ts(t), 10.0).expect("speed");
        }
        if k % 5 == 0 {
            let h = 0.3 * t;
            let p = Vector3::new(libm::sin(h), 1.0 - libm::cos(h), 0.0) * (10.0 / 0.3);
            a.push_vo(ts(t), p).expect("VO");
        }
    }
    assert!(!a.push_course(ts(3.0), 0.3, 0.02), "turning: the VO's direction is not the course's");
    // Full mode, unlevelled: a yaw says too little of the rotation.
    let mut full: Anchorer = Anchorer::new(AnchorConfig::default());
    assert!(!full.push_course(ts(1.0), 0.3, 0.02));
}

/// Horizontal RMS error (m) of the anchored position over `seconds` (from, to) of 90 s on
/// a straight road at 15 m/s, gravity-aligned, a fix a second stating `fix_sigma` with
/// noise of `noise_sigma` per axis, the VO stepping `vo_step_m` across the road at 60 s.
fn position_rms_on_a_straight_road(fix_sigma: f64, noise_sigma: f64, vo_step_m: f64, seconds: (f64, f64)) -> f64 {
    let truth = Sim3 { rotation: rotation_z(0.7), translation: Vector3::new(10.0, 5.0, 0.0), scale: 2.0 };
    let config = AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() };
    let mut anchorer: Anchorer = Anchorer::new(config);
    let road = StraightRoad { noise_sigma, vo_step_m, ..StraightRoad::new(truth, 15.0, 0.4, 100, fix_sigma) };
    let direction = Vector3::new(libm::cos(road.heading), libm::sin(road.heading), 0.0);
    let (mut sum, mut n) = (0.0, 0.0);
    road.drive(&mut anchorer, 90.0, |t, a| {
        let at_second = (t - libm::round(t)).abs() < 0.005;
        let measured = t > seconds.0 && t <= seconds.1;
        if let (true, true, Some(p)) = (at_second, measured, a.current_position()) {
            // The latest VO pose is 10 ms old at this step.
            sum += (p - direction * road.speed * (t - 0.01)).xy().norm_squared();
            n += 1.0;
        }
    });
    assert!(n >= seconds.1 - seconds.0 - 1.0, "anchored throughout: {:?}", anchorer.quality());
    libm::sqrt(sum / n)
}

#[test]
fn a_phones_fixes_are_averaged_over_a_longer_window_than_a_good_receivers() {
    // A fix of σ 8 m (horizontal error 11 m RMS): the reported translation's window grows
    // with the stated σ (16 s, held to the rotation's 12) where a 2 s one would average
    // about two fixes and leave ~8 m.
    let phone = position_rms_on_a_straight_road(8.0, 8.0, 0.0, (30.0, 90.0));
    assert!(phone < 4.0, "{phone}");
    // A good receiver's 1 m fixes keep the 2 s window: the position follows them closely.
    let good = position_rms_on_a_straight_road(1.0, 1.0, 0.0, (30.0, 90.0));
    assert!(good < 1.1, "{good}");
}

#[test]
fn fixes_better_than_they_state_keep_the_short_window() {
    // A receiver that states σ 8 m but scatters 0.3 m (comma2k19's u-blox states more than
    // it scatters), and a relative motion that steps 3 m across the road at 60 s (a real
    // dead reckoning's drift, sudden): the residuals say the fixes are better than stated,
    // so the window stays short and the position is back within half a metre (0.44 m RMS
    // from 2 s to 12 s after the step); a window grown with the stated σ alone (12 s) is
    // still 0.93 m off.
    let after_the_step = position_rms_on_a_straight_road(8.0, 0.3, 3.0, (62.0, 72.0));
    assert!(after_the_step < 0.65, "{after_the_step}");
}
