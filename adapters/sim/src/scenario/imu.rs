//! The dashcam's inertial sensor as the generator makes it: what a consumer MEMS IMU in the
//! camera's housing reads while the ego drives, and everything that makes its reading
//! wrong.
//!
//! The truth is the ego's planar motion (the generated roads are flat): a turn rate about the
//! vertical and, at the sensor's place ahead of the rear axle, the specific force of the
//! ego's acceleration, its turn and its change of turn rate, plus gravity. Through the
//! camera's **real** mount and the sensor's **real** rotation in the housing it reaches the
//! sensor's axes, where the sensor's own errors apply, each drawn per drive: a turn-on bias
//! that then wanders, sensitivity and cross-axis errors, white noise at the datasheet's
//! density, vibration from the road growing with speed, and a stamp latency. The device is
//! told only the nominal mounts. `docs/scenario.md` gives every number and its source.

use dash2sim_core::imu::{ImuMount, ImuSample, GRAVITY};
use dash2sim_core::nalgebra::{Matrix3, Vector3};
use rand::Rng;

use super::actors::EgoState;
use super::gauss;
use super::sensors::Camera;

/// A consumer MEMS IMU's errors (one drive's draw).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImuModel {
    /// Output data rate, Hz.
    pub rate_hz: f64,
    /// How late each sample's stamp is against the motion it measured, s.
    pub latency_s: f64,
    /// Gyro white-noise density, rad/s/√Hz.
    pub gyro_noise_density: f64,
    /// Accelerometer white-noise density, m/s²/√Hz.
    pub accel_noise_density: f64,
    /// Gyro bias at power-on, rad/s per axis.
    pub gyro_bias: [f64; 3],
    /// Accelerometer bias (zero-g offset), m/s² per axis.
    pub accel_bias: [f64; 3],
    /// How fast the gyro bias wanders (a random walk), rad/s/√s.
    pub gyro_bias_walk: f64,
    /// How fast the accelerometer bias wanders, m/s²/√s.
    pub accel_bias_walk: f64,
    /// Gyro sensitivity error per axis (0.01: reads 1 % high).
    pub gyro_scale: [f64; 3],
    /// Accelerometer sensitivity error per axis.
    pub accel_scale: [f64; 3],
    /// Cross-axis sensitivity: what each axis reads of the two others (xy, xz, yx, yz,
    /// zx, zy), both sensors alike.
    pub cross_axis: [f64; 6],
    /// Road vibration at 20 m/s (proportional to speed): specific force σ, m/s².
    pub vibration_accel: f64,
    /// Road vibration at 20 m/s: angular rate σ, rad/s.
    pub vibration_gyro: f64,
    /// The sensor's nominal rotation to the camera (what the device is told).
    pub mount: ImuMount,
    /// How the sensor really sits against that: roll, pitch, yaw, rad (a PCB soldered and
    /// screwed into a housing).
    pub mount_error: [f64; 3],
}

/// Degrees per second in rad/s.
const DPS: f64 = std::f64::consts::PI / 180.0;
/// One milli-g in m/s².
const MG: f64 = GRAVITY / 1000.0;

impl ImuModel {
    /// The LSM6DSO's white noise and nothing else (ST DS12140 table 2: gyro 3.8 mdps/√Hz,
    /// accelerometer 70 µg/√Hz in high-performance mode), at 100 Hz, exactly where the
    /// device is told: the ideal profile's sensor.
    pub fn ideal() -> Self {
        ImuModel {
            rate_hz: 100.0,
            latency_s: 0.0,
            gyro_noise_density: 3.8e-3 * DPS,
            accel_noise_density: 70e-6 * GRAVITY,
            gyro_bias: [0.0; 3],
            accel_bias: [0.0; 3],
            gyro_bias_walk: 0.0,
            accel_bias_walk: 0.0,
            gyro_scale: [0.0; 3],
            accel_scale: [0.0; 3],
            cross_axis: [0.0; 6],
            vibration_accel: 0.0,
            vibration_gyro: 0.0,
            mount: ImuMount::default(),
            mount_error: [0.0; 3],
        }
    }

    /// One drive's sensor under the typical (`hard` false) or hard profile: the datasheet's
    /// tolerances drawn uniformly (zero-rate level ±1 °/s, zero-g level ±20 mg, sensitivity
    /// ±1 %, cross-axis ±1 %), at the LSM6DSO's 104 Hz; the hard profile's sensor is worse
    /// than its datasheet (twice the offsets, a bias that wanders four times as fast, a
    /// rattling mount).
    pub fn draw(rng: &mut impl Rng, hard: bool) -> Self {
        let k = if hard { 2.0 } else { 1.0 };
        let mut symmetric = |half: f64| rng.random_range(-half..=half);
        let gyro_bias = [symmetric(k * DPS), symmetric(k * DPS), symmetric(k * DPS)];
        let accel_bias = [symmetric(k * 20.0 * MG), symmetric(k * 20.0 * MG), symmetric(k * 20.0 * MG)];
        let gyro_scale = [symmetric(0.01), symmetric(0.01), symmetric(0.01)];
        let accel_scale = [symmetric(0.01), symmetric(0.01), symmetric(0.01)];
        let cross_axis = [(); 6].map(|()| symmetric(0.01));
        let mount_deg = if hard { 2.0 } else { 1.0 };
        let mount_error = [(); 3].map(|()| symmetric(mount_deg).to_radians());
        let latency_s = rng.random_range(0.0..if hard { 0.03 } else { 0.01 });
        ImuModel {
            rate_hz: 104.0,
            latency_s,
            gyro_bias,
            accel_bias,
            gyro_bias_walk: if hard { 4e-5 } else { 1e-5 },
            accel_bias_walk: if hard { 4e-4 } else { 1e-4 },
            gyro_scale,
            accel_scale,
            cross_axis,
            vibration_accel: if hard { 0.5 } else { 0.15 },
            vibration_gyro: if hard { 0.01 } else { 0.003 },
            mount_error,
            ..ImuModel::ideal()
        }
    }

    /// The sensor's true rotation to the camera.
    pub fn true_rotation(&self) -> Matrix3<f64> {
        let [r, p, y] = self.mount_error;
        self.mount.rotation() * dash2sim_core::imu::so3::from_roll_pitch_yaw(r, p, y)
    }

    /// What each axis reads of a true vector on the sensor's axes: sensitivity and
    /// cross-axis errors.
    fn gain(&self, scale: [f64; 3]) -> Matrix3<f64> {
        let [xy, xz, yx, yz, zx, zy] = self.cross_axis;
        Matrix3::new(1.0 + scale[0], xy, xz, yx, 1.0 + scale[1], yz, zx, zy, 1.0 + scale[2])
    }

    /// The samples over the ego's states (`states` at [`ImuModel::rate_hz`], as
    /// `EgoPlan::drive` gives them), stamped with the device clock: (t, sample).
    pub fn samples(&self, rng: &mut impl Rng, states: &[EgoState], camera: &Camera) -> Vec<(f64, ImuSample)> {
        let n = states.len();
        if n < 3 {
            return Vec::new();
        }
        let dt = (states[n - 1].t - states[0].t) / (n - 1) as f64;
        let unwrap = |a: f64| (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        // Central differences (one-sided at the ends).
        let derivative = |k: usize, f: &dyn Fn(usize, usize) -> f64| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            f(a, b) / ((b - a) as f64 * dt)
        };
        let yaw_rate: Vec<f64> =
            (0..n).map(|k| derivative(k, &|a, b| unwrap(states[b].heading - states[a].heading))).collect();
        let mount = camera.true_mount();
        let [forward, left, _] = mount.position;
        // Body → sensor: body → camera is the camera mount's inverse, camera → sensor the
        // sensor rotation's.
        let body_to_sensor = self.true_rotation().transpose() * mount.rotation().transpose();
        let (gyro_gain, accel_gain) = (self.gain(self.gyro_scale), self.gain(self.accel_scale));
        let white = |density: f64| density * (self.rate_hz / 2.0).sqrt();
        let (gyro_white, accel_white) = (white(self.gyro_noise_density), white(self.accel_noise_density));
        let (mut gyro_bias, mut accel_bias) = (Vector3::from(self.gyro_bias), Vector3::from(self.accel_bias));
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            let (w, v) = (yaw_rate[k], states[k].speed);
            let w_dot = derivative(k, &|a, b| yaw_rate[b] - yaw_rate[a]);
            let a_long = derivative(k, &|a, b| states[b].speed - states[a].speed);
            let gyro_body = Vector3::new(0.0, 0.0, w);
            let force_body =
                Vector3::new(a_long - w_dot * left - w * w * forward, v * w + w_dot * forward - w * w * left, GRAVITY);
            let shaking = v / 20.0;
            let gyro_noise = noise(rng, gyro_white.hypot(self.vibration_gyro * shaking));
            let accel_noise = noise(rng, accel_white.hypot(self.vibration_accel * shaking));
            let gyro = gyro_gain * (body_to_sensor * gyro_body) + gyro_bias + gyro_noise;
            let accel = accel_gain * (body_to_sensor * force_body) + accel_bias + accel_noise;
            out.push((states[k].t + self.latency_s, ImuSample { gyro: gyro.into(), accel: accel.into() }));
            gyro_bias += noise(rng, self.gyro_bias_walk * dt.sqrt());
            accel_bias += noise(rng, self.accel_bias_walk * dt.sqrt());
        }
        out
    }
}

/// The IMU CSV `record --imu` reads ([`dash2sim_linux::record::sources::IMU_CSV_HEADER`]), to a
/// tenth of a microradian per second and ten µm/s²: far below the noise.
pub fn write_csv(out: &mut impl std::io::Write, samples: &[(f64, ImuSample)]) -> std::io::Result<()> {
    writeln!(out, "{}", dash2sim_linux::record::sources::IMU_CSV_HEADER)?;
    for (t, s) in samples {
        let [gx, gy, gz] = s.gyro;
        let [ax, ay, az] = s.accel;
        writeln!(out, "{t:.6},{gx:.7},{gy:.7},{gz:.7},{ax:.5},{ay:.5},{az:.5}")?;
    }
    Ok(())
}

/// The drive's sensor as `scenario.json` states it (its truth: nothing on the product's
/// path reads it).
pub fn summary(m: &ImuModel) -> serde_json::Value {
    serde_json::json!({
        "rate_hz": m.rate_hz, "latency_s": m.latency_s,
        "gyro_noise_density_rad_s_sqrt_hz": m.gyro_noise_density,
        "accel_noise_density_m_s2_sqrt_hz": m.accel_noise_density,
        "gyro_bias_rad_s": m.gyro_bias, "accel_bias_m_s2": m.accel_bias,
        "gyro_bias_walk_rad_s_sqrt_s": m.gyro_bias_walk, "accel_bias_walk_m_s2_sqrt_s": m.accel_bias_walk,
        "gyro_scale": m.gyro_scale, "accel_scale": m.accel_scale, "cross_axis": m.cross_axis,
        "vibration_at_20_mps": {"accel_m_s2": m.vibration_accel, "gyro_rad_s": m.vibration_gyro},
        "mount_roll_pitch_yaw_deg": m.mount.roll_pitch_yaw.map(f64::to_degrees),
        "true_mount_error_roll_pitch_yaw_deg": m.mount_error.map(f64::to_degrees),
    })
}

/// Three independent zero-mean Gaussian draws of σ `sigma`.
fn noise(rng: &mut impl Rng, sigma: f64) -> Vector3<f64> {
    Vector3::new(gauss(rng, sigma), gauss(rng, sigma), gauss(rng, sigma))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    /// A circle at `speed` m/s with radius `radius` m, sampled at 100 Hz for `seconds`.
    fn circle(speed: f64, radius: f64, seconds: f64) -> Vec<EgoState> {
        let w = speed / radius;
        (0..=(seconds * 100.0) as usize)
            .map(|k| {
                let t = k as f64 / 100.0;
                let a = w * t;
                EgoState {
                    t,
                    s: speed * t,
                    d: 0.0,
                    x: radius * a.sin(),
                    y: radius * (1.0 - a.cos()),
                    heading: a,
                    speed,
                }
            })
            .collect()
    }

    fn mean(samples: &[(f64, ImuSample)], f: impl Fn(&ImuSample) -> f64) -> f64 {
        samples.iter().map(|(_, s)| f(s)).sum::<f64>() / samples.len() as f64
    }

    #[test]
    fn an_ideal_sensor_reads_the_turn_and_its_centripetal_force_and_gravity() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let (speed, radius) = (20.0, 200.0);
        let camera = Camera { mount_forward: 0.0, ..Camera::default() };
        let samples = ImuModel::ideal().samples(&mut rng, &circle(speed, radius, 20.0), &camera);
        assert!((mean(&samples, |s| s.gyro[2]) - speed / radius).abs() < 1e-4);
        // Centripetal force to the left (+y), gravity up (+z), nothing along the travel.
        assert!((mean(&samples, |s| s.accel[1]) - speed * speed / radius).abs() < 1e-3);
        assert!((mean(&samples, |s| s.accel[2]) - GRAVITY).abs() < 1e-3);
        assert!(mean(&samples, |s| s.accel[0]).abs() < 1e-3);
        // The white noise is the datasheet's density over half the output rate.
        let sd = {
            let m = mean(&samples, |s| s.gyro[0]);
            (mean(&samples, |s| (s.gyro[0] - m).powi(2))).sqrt()
        };
        let expected = 3.8e-3 * DPS * 50f64.sqrt();
        assert!((sd / expected - 1.0).abs() < 0.1, "{sd} vs {expected}");
    }

    #[test]
    fn a_drawn_sensor_is_off_by_its_bias_and_its_rotation_and_stamps_late() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let model = ImuModel { mount_error: [0.0, 0.0, 0.1], ..ImuModel::draw(&mut rng, false) };
        assert!(model.gyro_bias.iter().all(|b| b.abs() <= DPS));
        assert!(model.accel_bias.iter().all(|b| b.abs() <= 20.0 * MG));
        let straight = circle(20.0, 1e9, 30.0);
        let camera = Camera { mount_forward: 0.0, ..Camera::default() };
        let samples = model.samples(&mut rng, &straight, &camera);
        // At constant speed on a straight the gyro reads its bias (± its walk over 30 s).
        assert!((mean(&samples, |s| s.gyro[0]) - model.gyro_bias[0]).abs() < 2e-4);
        // Gravity on the sensor's z, turned by the mount's yaw only: still vertical.
        assert!((mean(&samples, |s| s.accel[2]) - GRAVITY).abs() < 0.25);
        assert!((samples[0].0 - model.latency_s).abs() < 1e-12 && model.latency_s < 0.01);
        // A pitched sensor sees gravity along its x.
        let pitched = ImuModel { mount_error: [0.0, 0.05, 0.0], ..ImuModel::ideal() };
        let samples = pitched.samples(&mut rng, &straight, &camera);
        let along_x = mean(&samples, |s| s.accel[0]);
        assert!((along_x.abs() - GRAVITY * 0.05f64.sin()).abs() < 0.01, "{along_x}");
    }
}
