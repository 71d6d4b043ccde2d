//! comma2k19's minute with nothing simulated (issue #54): the real gyro and wheels as the
//! relative motion (no VO), anchored to the real u-blox and to the real phone-grade
//! receiver, against comma's fused poses.

use dash2sim_linux::datasets::comma_imu::{self, Receiver};
use dash2sim_tests::recorded::scratch;

#[test]
fn gyro_and_wheels_anchored_to_the_ublox() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let m = comma_imu::run(&dir, &scratch("comma-imu-ublox"), Receiver::Ublox).expect("the minute");
    println!("{m:#?}");
    assert!(m.imu_samples > 6000, "every IMU sample paired: {}", m.imu_samples);
    assert!(m.device.matched > 900, "{:?}", m.device);
    assert!(m.device.ape_rmse < 2.0, "device ATE {}", m.device.ape_rmse);
    assert!(m.finished.ape_rmse < 1.3, "finished ATE {}", m.finished.ape_rmse);
    assert!(m.finished.scale_error.abs() < 0.003, "scale {}", m.finished.scale_error);
    assert!(m.pitch_error_median_deg < 0.5 && m.roll_error_median_deg < 0.5, "{m:?}");
}

#[test]
fn gyro_and_wheels_anchored_to_the_phone_receiver() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let m = comma_imu::run(&dir, &scratch("comma-imu-qcom"), Receiver::Qcom).expect("the minute");
    println!("{m:#?}");
    assert!(m.anchored_after_first_fix_s < 15.0, "{m:?}");
    assert!(m.finished.ape_rmse < 2.5, "finished ATE {}", m.finished.ape_rmse);
}
