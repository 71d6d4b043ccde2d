//! The car's forward axis in the IMU's frame (`dash2sim_core::imu::forward`), found from the
//! car's braking and speeding up, against the generator's truth: how far the sensor is
//! turned on the car (the camera's yaw on its mount plus the sensor's in the housing). On
//! typical generated drives of 60 s (the ego brakes for the work zone and speeds up after
//! it), seeds 5001–5020, picked after the estimator was built and diagnosed on others; the estimator is fed the samples, the wheels'
//! reported speed and the gyro's rate as the device has them (its bias unknown).

use dash2sim_core::imu::forward::ForwardAxis;
use dash2sim_sim::scenario::profile::{Profile, Receiver};
use dash2sim_sim::scenario::{generate, ScenarioConfig};

#[test]
fn braking_and_speeding_up_show_how_far_the_sensor_is_turned_on_the_car() {
    let mut errors = Vec::new();
    for seed in 5001..=5020 {
        let config =
            ScenarioConfig { duration_s: 60.0, ..ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good) };
        let drive = generate(&config);
        let mut forward = ForwardAxis::default();
        let (mut previous, mut wheel) = (drive.imu[0].0, drive.speed.iter().peekable());
        let mut speed = 0.0;
        for (t, sample) in &drive.imu {
            while let Some((_, v)) = wheel.next_if(|(tw, _)| tw <= t) {
                speed = *v;
            }
            forward.push(t - previous, &sample.accel.into(), speed, sample.gyro[2], config.camera.mount_forward);
            previous = *t;
        }
        let truth = -(config.camera.mount_error.yaw + config.imu.mount_error[2]).to_degrees();
        let found = forward.yaw().unwrap_or_else(|| panic!("seed {seed}: the drive braked and sped up")).to_degrees();
        errors.push(found - truth);
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    println!(
        "forward axis error over 20 typical drives: RMS {rms:.2}°, worst {:.2}°",
        errors.iter().fold(0f64, |m, e| m.max(e.abs()))
    );
    // Against a truth spread over ±4° (camera ±3°, sensor ±1°; RMS about 1.8°, which is
    // the error of assuming the nominal mount). Measured: RMS 0.88°, worst 1.71°.
    assert!(rms < 1.0 && errors.iter().all(|e| e.abs() < 2.5), "{errors:?}");
}

/// The whole chain on the device: a camera that publishes no VO, gyro + wheels dead
/// reckoning, the camera turned by the forward axis once it is known, and the mount
/// calibration started again from there — the camera's yaw (and pitch) on the car it ends
/// with, against the truth, and against taking the nominal mount (what the device had without the IMU's
/// forward axis). Typical 60 s drives, seeds 5001–5010.
#[test]
fn without_vo_the_camera_s_yaw_on_the_car_comes_from_the_imu() {
    use dash2sim_core::binlog::Record;
    use dash2sim_core::geo::Geodetic;
    use dash2sim_core::pipeline::RelativeMotion;
    use dash2sim_linux::record::{self, Setup, Sources};
    let (mut calibrated, mut nominal) = (Vec::new(), Vec::new());
    let (mut pitch, mut pitch_nominal) = (Vec::new(), Vec::new());
    for seed in 5001..=5010 {
        let config =
            ScenarioConfig { duration_s: 60.0, ..ScenarioConfig::drive(seed, Profile::Typical, Receiver::Good) };
        let dir = std::env::temp_dir().join(format!("dash2sim-forward-{}-{seed}", std::process::id()));
        dash2sim_sim::scenario::write::write_scenario(&generate(&config), &dir).expect("drive");
        let sources = Sources { vo: None, ..Sources::scenario(&dir) };
        let (stream, _) = record::read_sources(&sources).expect("sources");
        let [lat, lon, height] = config.origin;
        let origin = Geodetic::new(lat, lon, height).expect("origin");
        let setup = Setup { relative_motion: RelativeMotion::ImuWheels, ..Setup::work_zone(origin, None, [0; 16]) };
        let recording = record::run_stream(&stream, &setup).expect("record");
        let log = dash2sim_linux::log::decode(&recording.log, "forward").expect("log");
        let last = log
            .records
            .iter()
            .rev()
            .find_map(|r| if let Record::MountEstimate(m) = r { Some(*m) } else { None })
            .expect("a mount estimate");
        let truth = config.camera.mount_error.yaw;
        calibrated.push((last.yaw_e6 as f64 * 1e-6 - truth).to_degrees());
        nominal.push(-truth.to_degrees());
        let truth = config.camera.mount_error.pitch;
        pitch.push((last.pitch_e6 as f64 * 1e-6 - truth).to_degrees());
        pitch_nominal.push(-truth.to_degrees());
        let _ = std::fs::remove_dir_all(&dir);
    }
    let rms = |v: &[f64]| (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt();
    println!("camera yaw on the car, no VO: RMS {:.2}° calibrated, {:.2}° nominal", rms(&calibrated), rms(&nominal));
    // Measured: RMS 1.40° against the nominal mount's 2.14°. What is left is the forward
    // axis's own error (0.85° above) and the sensor's turn in the housing (±1°), which
    // nothing without the camera's own motion can separate from the camera's.
    assert!(rms(&calibrated) < 0.75 * rms(&nominal), "{calibrated:?} vs {nominal:?}");
    // The pitch from where the detected objects stand (`pipeline::ground`): without it the
    // dead-reckoned camera's pitch was gravity's, 1–1.5° off with the accelerometer's bias,
    // and the tracker refused most detections as floating or sunk.
    println!(
        "camera pitch on the car, no VO: RMS {:.2}° from the ground, {:.2}° nominal",
        rms(&pitch),
        rms(&pitch_nominal)
    );
    assert!(rms(&pitch) < 0.3 && rms(&pitch) < 0.3 * rms(&pitch_nominal), "{pitch:?} vs {pitch_nominal:?}");
}
