//! comma2k19's minute with nothing simulated (issue #54): the real gyro and wheels as the
//! relative motion (no VO), anchored to the real u-blox, against comma's fused poses and the
//! phone's own gyro calibration. The figures are docs/imu.md's.

use dash2sim_sim::datasets::comma_imu::{self, Receiver};
use dash2sim_tests::recorded::scratch;

#[test]
fn gyro_and_wheels_anchored_to_the_ublox_track_the_fused_poses() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let m = comma_imu::run(&dir, &scratch("comma-imu-ublox"), Receiver::Ublox).expect("the minute");
    println!("{m:#?}");
    assert_eq!(m.imu_samples, 6256, "every gyro sample has its accelerometer sample");
    // The device anchors the dead-reckoned track (27.7 s after the first fix on this
    // straight highway) and holds it within 2 m of the fused poses.
    assert!(m.device.matched > 500, "{:?}", m.device);
    assert!(m.device.ape_rmse < 2.0, "device ATE {}", m.device.ape_rmse);
    assert!(m.device.scale_error.abs() < 0.003, "scale {}", m.device.scale_error);
    // The gyro's bias about the vertical, found in motion from the GNSS course, is the
    // phone's own calibration (-0.06836 rad/s) to 1e-3.
    assert!((m.gyro_bias_z - m.reference_gyro_bias_z).abs() < 1e-3, "{} vs {}", m.gyro_bias_z, m.reference_gyro_bias_z);
    // Pitch and roll from gravity follow the fused attitude to within a degree (median);
    // the constant part is the sensor's tilt on the camera.
    assert!(m.pitch_error_median_deg < 1.0 && m.roll_error_median_deg < 1.0, "{m:?}");
    // Finishing redoes the reckoned attitude with the biases the drive found and gives the
    // level track the road's heights: the pitch offset it finds from the fixes' heights is
    // the camera's tilt on the car (the fused poses') plus the sensor's on the camera.
    let expected = m.reference_camera_pitch_deg + m.pitch_offset_median_deg;
    assert!((m.pitch_offset_found_deg - expected).abs() < 0.3, "{} vs {expected}", m.pitch_offset_found_deg);
    // Finishing finds the heading drift the device's gyro bias left and trusts the grade
    // less while the attitude settled: 0.7 m horizontally; in 3D the u-blox's heights,
    // 1.1 m above the fused poses', weigh most.
    assert!(m.finished.ape_horizontal < 0.8, "finished horizontal ATE {}", m.finished.ape_horizontal);
    assert!(m.finished.ape_rmse < 1.6, "finished ATE {}", m.finished.ape_rmse);
    assert!(m.finished.scale_error.abs() < 0.003, "finished scale {}", m.finished.scale_error);
    // The IMU's records are a small part of the log.
    assert!(m.imu_bytes_per_minute < 0.2 * m.log_bytes_per_minute, "{m:?}");
}

#[test]
fn gyro_and_wheels_anchored_to_the_phone_receiver_within_fifteen_seconds() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let m = comma_imu::run(&dir, &scratch("comma-imu-qcom"), Receiver::Qcom).expect("the minute");
    println!("{m:#?}");
    assert_eq!(m.fixes, 30, "the phone's fixes, one every 2 s");
    // Its 0.5 Hz fixes (σ 8.3 m stated; 3.9 m RMS against the fused poses) anchor the
    // dead-reckoned track within 15 s of the first.
    assert!(m.anchored_after_first_fix_s <= 15.0, "anchored after {} s", m.anchored_after_first_fix_s);
    assert!(m.device.matched > 500, "{:?}", m.device);
    assert!(m.device.ape_rmse < 12.0, "device ATE {}", m.device.ape_rmse);
    assert!(m.finished.ape_rmse < m.device.ape_rmse, "finished {} device {}", m.finished.ape_rmse, m.device.ape_rmse);
    // Horizontally within 2.5 m once the drift of the heading the sparse fixes left is
    // found (7.5 m without); the phone's heights wander 14 m about the fused poses' (4.8 m
    // above on average), which no input of the minute corrects.
    assert!(m.finished.ape_horizontal < 2.5, "finished horizontal ATE {}", m.finished.ape_horizontal);
}
