//! The sensor profiles (issue #30), measured on generated drives: each perturbation the
//! profile names is present in what the sensors report, of the stated size, and absent from
//! the ideal profile. The figures are measured from the streams against the truth, not read
//! back from the models (where a test needs the drawn value to compare with, it says so).

use dash2sim_core::track3d::Detection3d;
use dash2sim_sim::scenario::actors::ObjectState;
use dash2sim_sim::scenario::profile::{Profile, Receiver};
use dash2sim_sim::scenario::sensors::{to_ego, MountError};
use dash2sim_sim::scenario::{generate, Scenario, ScenarioConfig};

fn drive(seed: u64, profile: Profile) -> Scenario {
    generate(&ScenarioConfig::drive(seed, profile, Receiver::Good))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn std_dev(v: &[f64]) -> f64 {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
}

/// The GNSS antenna's true position at a fix: the frame of that time, through the real
/// mount (the generator's truth; this test measures the generator).
fn antenna(s: &Scenario, t: f64) -> [f64; 2] {
    let f = s.frames.iter().min_by(|a, b| (a.ego.t - t).abs().total_cmp(&(b.ego.t - t).abs())).expect("frames");
    let [forward, left, _] = s.config.camera.true_mount().position;
    let (c, sn) = (f.ego.heading.cos(), f.ego.heading.sin());
    [f.ego.x + forward * c - left * sn, f.ego.y + forward * sn + left * c]
}

/// Per drive: RMS of the fixes' true horizontal error over RMS of the σ they report.
fn gnss_error_over_reported(s: &Scenario) -> f64 {
    let (mut err, mut reported) = (0.0, 0.0);
    for fix in s.gnss.iter().filter(|f| !f.multipath) {
        let [x, y] = antenna(s, fix.t_fix);
        err += (fix.enu[0] - x).powi(2) + (fix.enu[1] - y).powi(2);
        reported += fix.reported_sigma.powi(2);
    }
    (err / reported).sqrt()
}

#[test]
fn a_typical_receiver_misjudges_its_accuracy_by_a_factor_of_its_own_and_reports_late() {
    let ratios =
        |profile| (1..=60).map(|seed| gnss_error_over_reported(&drive(seed, profile)).ln()).collect::<Vec<_>>();
    let (ideal, typical) = (ratios(Profile::Ideal), ratios(Profile::Typical));
    let ideal_median = median(ideal.clone()).exp();
    println!(
        "error / reported σ: ideal median {ideal_median:.3}, spread of ln {:.3}; typical spread of ln {:.3}",
        std_dev(&ideal),
        std_dev(&typical)
    );
    assert!((0.8..1.2).contains(&ideal_median), "the ideal receiver reports its σ: {ideal_median}");
    // ln of a factor log-uniform in [0.5, 2] has σ 0.40; the ideal's spread is sampling alone.
    assert!(std_dev(&typical) > 1.8 * std_dev(&ideal), "{} vs {}", std_dev(&typical), std_dev(&ideal));
    assert!(std_dev(&typical) > 0.3);

    let latency = |profile| -> Vec<f64> {
        (1..=60).map(|seed| drive(seed, profile).gnss.first().map(|f| f.t_receive - f.t_fix).expect("fix")).collect()
    };
    let typical = latency(Profile::Typical);
    assert!(typical.iter().all(|l| (0.0..0.25).contains(l)), "{typical:?}");
    let spread = typical.iter().copied().fold(f64::MIN, f64::max) - typical.iter().copied().fold(f64::MAX, f64::min);
    assert!(spread > 0.15, "latencies drawn across 0–250 ms: {spread}");
    assert!(latency(Profile::Ideal).iter().all(|l| (l - 0.08).abs() < 1e-9));
}

#[test]
fn hard_drives_lose_gnss_for_seconds_and_see_more_multipath() {
    let (mut gaps, mut multipath, mut fixes) = (Vec::new(), 0usize, 0usize);
    for seed in 1..=40 {
        let s = generate(&ScenarioConfig::drive(seed, Profile::Hard, Receiver::Phone));
        fixes += s.gnss.len();
        multipath += s.gnss.iter().filter(|f| f.multipath).count();
        gaps.extend(s.gnss.windows(2).map(|w| w[1].t_fix - w[0].t_fix).filter(|dt| *dt > 1.0));
    }
    println!("hard: {} outages, {multipath} of {fixes} fixes in multipath", gaps.len());
    assert!(!gaps.is_empty() && gaps.iter().all(|g| (4.9..30.5).contains(g)), "{gaps:?}");
    // 5 % of fixes start an episode of 1–3 s (5–15 fixes): far more than 5 % are in one.
    assert!(multipath as f64 / fixes as f64 > 0.1);
    let typical = generate(&ScenarioConfig::drive(1, Profile::Typical, Receiver::Phone));
    assert!(typical.gnss.windows(2).all(|w| w[1].t_fix - w[0].t_fix < 0.3), "no outages in the typical profile");
}

#[test]
fn wheel_speed_carries_a_tyre_scale_of_its_own_per_drive() {
    let scale = |s: &Scenario| {
        let truth: f64 = s.frames.iter().map(|f| f.ego.speed).sum::<f64>() / s.frames.len() as f64;
        let reported: f64 = s.speed.iter().map(|(_, v)| v).sum::<f64>() / s.speed.len() as f64;
        reported / truth
    };
    let typical: Vec<f64> = (1..=40).map(|seed| scale(&drive(seed, Profile::Typical))).collect();
    assert!(typical.iter().all(|k| (0.965..1.035).contains(k)), "{typical:?}");
    let spread = typical.iter().copied().fold(f64::MIN, f64::max) - typical.iter().copied().fold(f64::MAX, f64::min);
    assert!(spread > 0.035, "tyre scales across ±3 %: {spread}");
    let ideal = scale(&drive(1, Profile::Ideal));
    assert!((ideal - 0.99).abs() < 0.003, "{ideal}");
}

/// The true object nearest a detection in the ego frame, if within `gate` metres.
fn nearest<'a>(s: &'a Scenario, frame: usize, d: &Detection3d, gate: f64) -> Option<(&'a ObjectState, [f64; 2])> {
    let f = &s.frames[frame];
    f.objects
        .iter()
        .filter(|o| f.visible.contains(&o.id))
        .map(|o| {
            let b = to_ego(&f.ego, &o.bbox);
            (o, [b.x, b.y])
        })
        .filter(|(_, [x, y])| (x - d.bbox.x).hypot(y - d.bbox.y) < gate)
        .min_by(|a, b| {
            let da = (a.1[0] - d.bbox.x).hypot(a.1[1] - d.bbox.y);
            let db = (b.1[0] - d.bbox.x).hypot(b.1[1] - d.bbox.y);
            da.total_cmp(&db)
        })
}

#[test]
fn a_camera_turned_on_its_mount_turns_every_detection_the_device_places() {
    let mut yaws = Vec::new();
    for seed in 1..=20 {
        let s = drive(seed, Profile::Typical);
        let camera_x = s.config.camera.mount_forward;
        let mut offsets = Vec::new();
        for (k, f) in s.frames.iter().enumerate() {
            for d in &f.detections_3d {
                let Some((_, [x, y])) = nearest(&s, k, d, 4.0) else { continue };
                if x - camera_x < 15.0 {
                    continue;
                }
                offsets.push((d.bbox.y.atan2(d.bbox.x - camera_x) - y.atan2(x - camera_x)).to_degrees());
            }
        }
        // The drawn yaw, to compare the measured turn with (the generator's truth).
        let yaw = s.config.camera.mount_error.yaw.to_degrees();
        let measured = median(offsets);
        assert!((measured + yaw).abs() < 0.35, "seed {seed}: detections turned {measured:.2}°, mount yaw {yaw:.2}°");
        yaws.push(yaw);
    }
    assert!(yaws.iter().any(|y| *y > 1.5) && yaws.iter().any(|y| *y < -1.5), "{yaws:?}");
    assert_eq!(drive(1, Profile::Ideal).config.camera.mount_error, MountError::default());
}

/// Typical detector, camera exactly on its nominal mount (to see the detector alone).
fn detector_only(seed: u64, profile: Profile) -> Scenario {
    let mut config = ScenarioConfig::drive(seed, profile, Receiver::Good);
    config.camera.mount_error = MountError::default();
    generate(&config)
}

#[test]
fn a_typical_detector_confuses_classes_and_misreports_its_covariance_by_a_factor_per_drive() {
    let (mut confused, mut matched) = ([0usize; 2], [0usize; 2]);
    let mut nees: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for (p, profile) in [Profile::Ideal, Profile::Typical].into_iter().enumerate() {
        for seed in 1..=20 {
            let s = detector_only(seed, profile);
            let mut sum = (0.0, 0usize);
            for (k, f) in s.frames.iter().enumerate() {
                for d in &f.detections_3d {
                    let Some((o, [x, y])) = nearest(&s, k, d, 1.0) else { continue };
                    matched[p] += 1;
                    confused[p] += usize::from(o.class as u16 != d.class);
                    if let Some([xx, xy, yy]) = d.position_covariance {
                        let (ex, ey) = (d.bbox.x - x, d.bbox.y - y);
                        let det = xx * yy - xy * xy;
                        sum.0 += (yy * ex * ex - 2.0 * xy * ex * ey + xx * ey * ey) / det;
                        sum.1 += 1;
                    }
                }
            }
            nees[p].push(sum.0 / sum.1 as f64);
        }
    }
    let rate = |p: usize| confused[p] as f64 / matched[p] as f64;
    println!(
        "class confusions: ideal {:.4}, typical {:.4}; NEES medians {:.2} / {:.2}",
        rate(0),
        rate(1),
        median(nees[0].clone()),
        median(nees[1].clone())
    );
    assert!(rate(0) < 0.005, "{}", rate(0));
    assert!((0.01..0.06).contains(&rate(1)), "{}", rate(1));
    // A calibrated detector: NEES ≈ 2 for a 2D position (the gate clips the tail a little).
    assert!((1.4..2.4).contains(&median(nees[0].clone())), "{:?}", nees[0]);
    // × a factor in [0.5, 2]: NEES from about 1 to 4 across drives.
    let typical = &nees[1];
    assert!(typical.iter().any(|n| *n < 1.2) && typical.iter().any(|n| *n > 2.6), "{typical:?}");
}

#[test]
fn nearer_objects_hide_farther_ones_in_the_typical_profile() {
    let rate = |profile| {
        let (mut detected, mut visible) = (0usize, 0usize);
        for seed in 1..=10 {
            let s = detector_only(seed, profile);
            for (k, f) in s.frames.iter().enumerate() {
                visible += f.visible.len();
                detected += f.detections_3d.iter().filter(|d| nearest(&s, k, d, 1.0).is_some()).count();
            }
        }
        detected as f64 / visible as f64
    };
    let (ideal, typical) = (rate(Profile::Ideal), rate(Profile::Typical));
    println!("detected per visible object-frame: ideal {ideal:.3}, typical {typical:.3}");
    assert!(typical < ideal - 0.02, "{typical} vs {ideal}");
}

#[test]
fn the_vo_loses_track_and_starts_again_with_a_new_origin_heading_and_scale() {
    let with_reinit = |profile| (1..=100).filter(|&seed| drive(seed, profile).vo.reinits() > 0).count();
    let (typical, hard) = (with_reinit(Profile::Typical), with_reinit(Profile::Hard));
    println!("40 s drives with a VO re-initialisation: typical {typical} of 100, hard {hard} of 100");
    // One every 2–5 min (typical) or 30–60 s (hard), the drive starting anywhere in the cycle.
    assert!((5..=40).contains(&typical), "{typical}");
    assert!(hard >= 70, "{hard}");
    assert_eq!(with_reinit(Profile::Ideal), 0);

    // Measured from the VO alone against the truth: the gap, and the scale before and after.
    let mut factors = Vec::new();
    for seed in 1..=100 {
        let s = drive(seed, Profile::Hard);
        let frames: Vec<usize> = s.vo.samples.iter().map(|v| v.frame).collect();
        let poses = &s.vo.poses.poses;
        let truth = |k: usize| {
            let e = &s.frames[k].ego;
            [e.x, e.y]
        };
        // Metres per VO unit over the second ending at pose j.
        let scale = |j: usize| {
            let i = j.checked_sub(10)?;
            (frames[j] - frames[i] == 10).then_some(())?;
            let [a, b] = [truth(frames[i]), truth(frames[j])];
            Some((a[0] - b[0]).hypot(a[1] - b[1]) / (poses[j].translation - poses[i].translation).norm())
        };
        for j in 1..frames.len() {
            if frames[j] == frames[j - 1] + 1 {
                continue;
            }
            let gap = s.frames[frames[j]].ego.t - s.frames[frames[j - 1]].ego.t;
            assert!((0.55..=2.15).contains(&gap), "seed {seed}: tracking lost for {gap} s");
            assert_eq!(poses[j].translation.norm(), 0.0, "seed {seed}: a new origin");
            if let (Some(before), Some(after)) = (scale(j - 1), scale((j + 10).min(frames.len() - 1))) {
                factors.push(before / after);
            }
        }
    }
    println!("scale factors across re-initialisations: {} measured", factors.len());
    assert!(factors.len() > 30);
    assert!(factors.iter().all(|f| (0.45..2.2).contains(f)), "{factors:?}");
    assert!(factors.iter().filter(|f| !(0.9..1.1).contains(*f)).count() > factors.len() / 2);
}

#[test]
fn the_vo_orientation_carries_noise_in_the_typical_profile_and_none_in_the_ideal() {
    // The VO's frame-to-frame rotation against the truth's (the camera's, through the mount).
    let step_error = |s: &Scenario| {
        let poses = &s.vo.poses.poses;
        let mut errors = Vec::new();
        for j in 1..poses.len() {
            let (a, b) = (s.vo.samples[j - 1], s.vo.samples[j]);
            if b.frame != a.frame + 1 || b.session != a.session {
                continue;
            }
            let vo = poses[j - 1].rotation.transpose() * poses[j].rotation;
            let truth = dash2sim_core::sim3::rotation_z(s.frames[a.frame].ego.heading).transpose()
                * dash2sim_core::sim3::rotation_z(s.frames[b.frame].ego.heading);
            let r = dash2sim_core::nalgebra::Rotation3::from_matrix(&(truth.transpose() * vo));
            errors.push(r.angle().to_degrees());
        }
        errors.iter().sum::<f64>() / errors.len() as f64
    };
    let ideal = step_error(&drive(3, Profile::Ideal));
    let typical = step_error(&drive(3, Profile::Typical));
    println!("mean frame-to-frame rotation error: ideal {ideal:.2e}°, typical {typical:.3}°");
    // The ideal VO turns with the drift only (1°/min: 0.0017° a frame).
    assert!(ideal < 0.003, "{ideal}");
    // Typical: 0.1° white per axis on each orientation, a step sees two: ≈ 0.25° mean.
    assert!((0.1..0.5).contains(&typical), "{typical}");
}

/// The IMU's reading against the truth: what a channel that should read zero (the roll
/// rate: the generated roads are flat) reads on average, and its sample-to-sample noise
/// (first differences over √2, which the slow motion does not reach).
fn roll_rate_bias_and_noise(s: &Scenario) -> (f64, f64) {
    let roll: Vec<f64> = s.imu.iter().map(|(_, sample)| sample.gyro[0]).collect();
    let mean = roll.iter().sum::<f64>() / roll.len() as f64;
    let steps: Vec<f64> = roll.windows(2).map(|w| (w[1] - w[0]) / 2f64.sqrt()).collect();
    (mean, std_dev(&steps))
}

#[test]
fn the_imu_carries_a_turn_on_bias_and_road_vibration_in_the_typical_profile_and_white_noise_only_in_the_ideal() {
    let dps = 1f64.to_radians();
    let typical: Vec<(f64, f64)> =
        (1..=30).map(|seed| roll_rate_bias_and_noise(&drive(seed, Profile::Typical))).collect();
    // The bias: within the datasheet's ±1 °/s (and what the mount's tilt mixes in of the
    // turn), spread across it from drive to drive.
    assert!(typical.iter().all(|(b, _)| b.abs() < dps + 2e-3), "{typical:?}");
    let (lo, hi) = typical.iter().fold((f64::MAX, f64::MIN), |(lo, hi), (b, _)| (lo.min(*b), hi.max(*b)));
    assert!(hi - lo > dps, "biases across ±1 °/s: {lo}..{hi}");
    // The noise: white at the datasheet's density and vibration at ~0.003 rad/s near 20 m/s.
    assert!(typical.iter().all(|(_, n)| (0.0015..0.005).contains(n)), "{typical:?}");
    let ideal = drive(1, Profile::Ideal);
    let (bias, noise) = roll_rate_bias_and_noise(&ideal);
    assert!(bias.abs() < 1e-4, "no bias in the ideal profile: {bias}");
    let white = 3.8e-3 * dps * 50f64.sqrt();
    assert!((noise / white - 1.0).abs() < 0.1, "{noise} vs the datasheet's {white}");
    // The output rate: 104 Hz (the LSM6DSO's) in the typical profile, 100 Hz in the ideal.
    let rate = |s: &Scenario| (s.imu.len() - 1) as f64 / (s.imu[s.imu.len() - 1].0 - s.imu[0].0);
    assert!((rate(&drive(1, Profile::Typical)) - 104.0).abs() < 0.5 && (rate(&ideal) - 100.0).abs() < 0.5);
}
