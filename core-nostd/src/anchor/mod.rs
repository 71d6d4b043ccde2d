//! Incremental Sim(3) anchoring of a visual-odometry trajectory to geo-referenced anchors.
//!
//! Monocular VO knows its trajectory only up to an unknown similarity (and drifts); GNSS
//! fixes and wheel speed know where the car is in metres but are noisy. The [`Anchorer`]
//! estimates, after every anchor, the [`Sim3`] taking VO coordinates to the local ENU
//! frame, in O(1) time and memory per anchor:
//!
//! * **Moments, not points.** Each anchor updates weighted Umeyama moments
//!   ([`Moments`]); the estimate is a closed form of them. Weights are `1/σ²` from the
//!   fix's HDOP/GST σ ([`gnss_sigma`]), times a robust Cauchy factor.
//! * **Outliers.** A fix is rejected when it disagrees with the current estimate by more
//!   than `gate_sigma·σ`, or when it moved farther from the last accepted fix than the
//!   wheels travelled (a multipath jump), so one bad fix never pulls the estimate. After
//!   a long run of rejections the anchorer recovers: fixes are taken at full weight until
//!   they agree with the fit again, so a real shift is followed, not rejected forever.
//! * **Drift.** Past weight decays with time constant `forgetting_time_constant_s`, so
//!   the Sim(3) follows slow VO drift and memory stays bounded on long drives.
//! * **Two windows.** Rotation and scale need a long baseline; the translation is solved
//!   on a short recent window (`translation_time_constant_s`) given them, so the current
//!   position rests on the latest fixes instead of being extrapolated hundreds of metres
//!   from the long window's centroid.
//! * **Latency.** A GNSS fix describes the antenna some tens of ms before it is received.
//!   `K` latency hypotheses (0, step, 2·step, …) are tracked side by side, each pairing
//!   fixes with the VO position at `t_rx − latency`; once the fit is observable their
//!   one-step-ahead prediction errors (in σ, clipped at the gate) are accumulated and
//!   the smallest wins (refined by a parabola through its neighbours). With speed changes the hypotheses separate; at constant velocity the
//!   latency is indistinguishable from a translation, and does no harm.
//! * **Scale from the wheels.** Wheel distance over VO path length (recent window), with
//!   the wheel factor calibrated online against the GNSS path, is fused with the GNSS
//!   scale by inverse variance.
//! * **A rotation prior.** When the VO starts a new session the old one's last camera
//!   attitude, carried across the gap, says how the new frame is turned
//!   ([`Anchorer::set_rotation_prior`]). It weighs in as one more observation of the
//!   rotation (Wahba's problem with the fixes' cross-covariance), forgotten as the fixes
//!   are, so a straight road anchors the new session in seconds instead of waiting for a
//!   bend.
//! * **Observability.** The weakest rotation axis and the scale get a standard deviation
//!   from the moments (inflated for time-correlated GNSS error, scaled by the
//!   a-posteriori variance factor) and are propagated to the current position; until
//!   that is within `max_geometry_sigma_m` the quality says why and no new rotation or
//!   scale is taken — the last observable ones are held (a straight drive leaves roll
//!   about the road axis unknown) and no wild estimate is reported. [`AnchorMode::GravityAligned`] (yaw, scale, translation) needs only
//!   horizontal spread and is the better choice when the VO frame's vertical is known.
//! * **Gravity.** A VO frame's vertical measured by the dashcam's accelerometer
//!   ([`Anchorer::level`]) turns the session's coordinates so that it is their z, and the
//!   fit becomes gravity-aligned from then on: the roll about a straight road, which no
//!   position observes, is what gravity gives.

mod history;
mod wheel;

use nalgebra::Vector3;

use crate::sim3::umeyama::{umeyama_rotation, yaw_rotation, MAX_DECOMPOSITION_ITERATIONS};
use crate::sim3::{AlignMode, Moments, Sim3};
use crate::time::{Duration, Timestamp};
use history::{Odometer, VoHistory, VoSample};
use wheel::WheelScale;

/// The hypotheses' summed prediction errors (squares of residuals over the fixes' stated
/// σ) tell the latency once the worst exceeds the best by this, as a χ² rises by 1 at one
/// σ. Not inflated for the fixes' correlated errors as the fit's σ is: an error common to
/// all hypotheses cancels in their difference (inflated, the device's clock gained on 26 of
/// the 200 tuning drives, against 117 so; docs/pipeline.md#clocks).
pub const LATENCY_SHOWN_CHI2: f64 = 1.0;

/// VO samples kept for latency look-back (3.2 s at 20 Hz).
const VO_HISTORY: usize = 64;
/// GNSS fixes waiting for the VO sample that brackets them.
const PENDING_ANCHORS: usize = 8;
/// After this many consecutive rejected fixes the positions have really moved (receiver
/// reset, datum change, a wrong estimate): the anchorer recovers by taking fixes at full
/// weight until they agree with the fit again, rather than rejecting everything forever.
const MAX_CONSECUTIVE_REJECTIONS: u32 = 30;
/// A fix farther from the last accepted one than the wheels travelled times this factor
/// (plus the gate) is a jump.
const JUMP_TRAVEL_FACTOR: f64 = 1.1;
/// The jump test compares with the last accepted fix only within this time, s.
const JUMP_TEST_WINDOW_S: f64 = 10.0;
/// Of a fix's own σ (scaled by the variance factor), the share the rotation and scale may
/// add at the current position and still be observable, when that is more than
/// `max_geometry_sigma_m`: a phone's 8 m fixes are not held to a metre of geometry, which
/// would add 1 % to their error, but to 2 m, which adds 3 %.
const GEOMETRY_SHARE_OF_FIX: f64 = 0.25;
/// How far the residuals of the long window understate the fixes' error variance: the
/// fit takes an error's part common to the window (correlated for seconds to minutes) into
/// its translation. Measured where the error is known: on the sweep's good receiver (whose
/// stated σ is its true one; seeds 7001–7100) the residuals gave σ0² ≈ 0.25 where 1 is
/// right; on comma2k19's u-blox 0.025 where its error against the fused poses (1.2 m for a
/// stated 2.5 m) makes it 0.1–0.2.
const RESIDUAL_UNDERSTATEMENT: f64 = 4.0;
/// The a-posteriori variance factor is not taken below this, whatever the residuals say
/// (a receiver that states its σ pessimistically is still held to a third of it).
const MIN_VARIANCE_FACTOR: f64 = 0.1;
/// The most the VO's direction may turn between the halves of the second a course prior is
/// taken over, rad (2°).
const MAX_COURSE_BEND_RAD: f64 = 2.0 * core::f64::consts::PI / 180.0;
/// The least the VO must have moved over that second for its direction to count, m.
const MIN_COURSE_TRAVEL_M: f64 = 5.0;
/// Residual components per fix (east, north, up) in the a-posteriori variance factor.
const RESIDUAL_COMPONENTS: f64 = 3.0;
/// The fix σ (m) at which the reported translation's window is
/// `translation_time_constant_s`; a noisier fix lengthens it in proportion, up to the
/// rotation's `forgetting_time_constant_s`. The window trades the relative motion's drift,
/// which grows with its length, against the fixes' noise, which it averages: for a drift
/// that walks and a noise of σ, the best window is proportional to σ. The σ is the stated
/// one, lowered where the residuals show the fixes scatter less than they state (comma2k19's
/// u-blox): lengthened by a stated σ alone, the window averaged a real dead reckoning's
/// drift on that minute (device ATE 1.75 → 2.59 m).
const STEADY_REFERENCE_SIGMA_M: f64 = 1.0;

/// Which similarity the anchorer estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AnchorMode {
    /// Full 7-DoF Sim(3): arbitrary VO orientation.
    Full,
    /// 4-DoF: VO z axis is already vertical (gravity-aligned); yaw, scale, translation.
    GravityAligned,
}

/// Anchoring parameters; [`AnchorConfig::default`] suits a car dashcam with a consumer
/// GNSS receiver at 1–10 Hz and VO at 10–30 Hz.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnchorConfig {
    /// Degrees of freedom estimated.
    pub mode: AnchorMode,
    /// Past anchors' weight decays as exp(−Δt/τ) for rotation and scale;
    /// `f64::INFINITY` never forgets.
    pub forgetting_time_constant_s: f64,
    /// Time constant of the recent window the translation is solved on, s. Short, so
    /// that the current position rests on the latest fixes rather than being
    /// extrapolated from the centroid of the long window.
    pub translation_time_constant_s: f64,
    /// Cauchy down-weighting scale, in σ.
    pub robust_scale_sigma: f64,
    /// Residual (in σ) beyond which an anchor is rejected once the estimate is observable.
    pub gate_sigma: f64,
    /// Time over which GNSS errors stay correlated; information is discounted
    /// accordingly when judging observability.
    pub gnss_correlation_time_s: f64,
    /// Largest position error (m, 1σ) that rotation and scale uncertainty may add at
    /// the current VO position for "observable". Rotation about an axis the drive has
    /// run along barely moves points near that axis, so a straight road is fine for
    /// positions while roll stays undetermined (see [`Quality::rotation_sigma_rad`]).
    pub max_geometry_sigma_m: f64,
    /// Largest relative standard deviation of scale for "observable". The default, 4 %,
    /// admits the wheels alone before their factor is calibrated (1 ± 3 %, plus the VO's
    /// path noise): a car's speed signal is a metric scale; what its error does to the
    /// position is in the geometry's σ.
    pub max_scale_rel_sigma: f64,
    /// Minimum anchors before an estimate is reported observable.
    pub min_anchors: u32,
    /// Spacing of latency hypotheses; `Duration::ZERO` disables latency estimation.
    pub latency_step: Duration,
    /// Time constant of the wheel/VO path-length window, s.
    pub wheel_time_constant_s: f64,
    /// Relative σ of the wheel scale beyond calibration (VO path noise, slip).
    pub wheel_scale_rel_sigma: f64,
}

impl Default for AnchorConfig {
    fn default() -> Self {
        AnchorConfig {
            mode: AnchorMode::Full,
            forgetting_time_constant_s: 12.0,
            translation_time_constant_s: 2.0,
            robust_scale_sigma: 3.0,
            gate_sigma: 6.0,
            gnss_correlation_time_s: 2.0,
            max_geometry_sigma_m: 1.0,
            max_scale_rel_sigma: 0.04,
            min_anchors: 5,
            latency_step: Duration::from_millis(25),
            wheel_time_constant_s: 5.0,
            wheel_scale_rel_sigma: 0.002,
        }
    }
}

/// Why the estimate is (not yet) trusted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Observability {
    /// Fewer anchors than `min_anchors`, or no alignment possible yet.
    TooFewAnchors,
    /// Rotation not determined well enough for the current position (anchors too
    /// nearly on a line through it).
    Collinear,
    /// Not enough travel for the scale.
    ScaleUncertain,
    /// Every parameter is within its bound.
    Observable,
}

/// The state of the estimate after the latest anchor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Quality {
    /// Verdict on the latest fit.
    pub observability: Observability,
    /// Anchors that contributed (possibly down-weighted).
    pub anchors_used: u32,
    /// Anchors rejected as outliers.
    pub anchors_rejected: u32,
    /// Anchors dropped (no VO to pair with, or queue full).
    pub anchors_dropped: u32,
    /// Weighted RMS residual of the current fit, m.
    pub rms_residual_m: f64,
    /// Standard deviation of rotation about the weakest axis, rad. On a straight road
    /// this is roll about the road axis and may stay large.
    pub rotation_sigma_rad: f64,
    /// Position error (m, 1σ, 3D) that rotation and scale uncertainty add at the
    /// current VO position, on top of the GNSS mean error.
    pub geometry_sigma_m: f64,
    /// Relative standard deviation of the scale.
    pub scale_rel_sigma: f64,
    /// Horizontal 1-σ error of the current position (DRMS, m): the latest fix's stated σ
    /// scaled by the a-posteriori variance factor — the translation rests on the recent
    /// fixes, whose errors are correlated far beyond its window, so no averaging is
    /// credited — the geometry's σ, and the speed times the latency's σ (the fixes pair
    /// with the VO at `t_rx − latency`, so a latency error moves the translation along the
    /// road).
    pub position_sigma_m: f64,
    /// Estimated GNSS latency, s (when latency estimation is on and data suffice).
    pub latency_s: Option<f64>,
    /// Whether the drive has shown that latency: not at a steady speed on a straight road,
    /// where every hypothesis fits alike ([`LATENCY_SHOWN_CHI2`]).
    pub latency_shown: bool,
    /// Calibrated wheel factor (true / odometer distance), when speed is fed.
    pub wheel_factor: Option<f64>,
}

/// Why an input was refused. The anchorer's state is unchanged by a refused input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AnchorError {
    /// NaN or infinite value.
    NonFinite,
    /// Non-positive or non-finite σ.
    InvalidSigma,
    /// Timestamp earlier than the previous one of the same stream.
    OutOfOrder,
    /// A matrix that is not a rotation (not orthonormal, or a reflection).
    NotARotation,
}

impl core::fmt::Display for AnchorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            AnchorError::NonFinite => "value is NaN or infinite",
            AnchorError::InvalidSigma => "sigma must be positive and finite",
            AnchorError::OutOfOrder => "timestamp earlier than the previous sample",
            AnchorError::NotARotation => "matrix is not a rotation",
        })
    }
}

impl core::error::Error for AnchorError {}

/// Horizontal 1-σ position error of a fix, m: from GST (σ_lat, σ_lon) when the receiver
/// gives it, else HDOP × user equivalent range error (UERE, typically 2–5 m).
pub fn gnss_sigma(hdop: Option<f64>, gst_lat_lon_sigma_m: Option<(f64, f64)>, uere_m: f64) -> Option<f64> {
    if let Some((a, b)) = gst_lat_lon_sigma_m {
        let s = libm::sqrt(0.5 * (a * a + b * b));
        if s.is_finite() && s > 0.0 {
            return Some(s);
        }
    }
    let s = hdop? * uere_m;
    (s.is_finite() && s > 0.0).then_some(s)
}

/// A GNSS fix waiting for the VO sample after it.
#[derive(Clone, Copy, Debug)]
struct PendingFix {
    t: Timestamp,
    enu: Vector3<f64>,
    sigma: f64,
}

/// One latency hypothesis: moments, its latest fit and its accumulated prediction error.
#[derive(Clone, Copy, Debug)]
struct Hypothesis {
    latency: Duration,
    moments: Moments,
    /// The VO's centroid over the short translation window.
    recent: RecentCentroid,
    /// Weighted means over a window that lengthens with the fixes' σ
    /// ([`STEADY_REFERENCE_SIGMA_M`]): the reported translation.
    steady: RecentMeans,
    /// Latest Umeyama fit of the long window (GNSS only: the hypotheses are scored on
    /// what the fixes alone predict).
    fit: Option<Sim3>,
    prediction_sse: f64,
}

/// What was known of the VO → ENU rotation before the fixes: a rotation and its
/// information (1/σ² per axis, rad⁻²), forgotten as the fixes are.
#[derive(Clone, Copy, Debug)]
struct RotationPrior {
    rotation: nalgebra::Matrix3<f64>,
    information: f64,
}

/// The weight an exponentially weighted mean has after forgetting by `keep` and adding
/// `w`, and the share of the new sample in it; `None` when the weight is not positive or
/// not finite (the update is then refused).
fn forgetful_weight(weight: f64, keep: f64, w: f64) -> Option<(f64, f64)> {
    let weight = weight * keep + w;
    (weight > 0.0 && weight.is_finite()).then(|| (weight, w / weight))
}

/// Exponentially weighted mean of recent VO positions: the short window's centroid, the
/// lever arm the observability is judged on.
#[derive(Clone, Copy, Debug, Default)]
struct RecentCentroid {
    weight: f64,
    mean: Vector3<f64>,
}

impl RecentCentroid {
    /// Forget by `keep` and add `x`; an update that would overflow is refused and leaves
    /// the mean as it was.
    fn push(&mut self, keep: f64, x: &Vector3<f64>, w: f64) {
        let Some((weight, f)) = forgetful_weight(self.weight, keep, w) else { return };
        let mean = self.mean + (x - self.mean) * f;
        if mean.iter().all(|v| v.is_finite()) {
            *self = RecentCentroid { weight, mean };
        }
    }
}

/// Exponentially weighted means of recent pairs.
#[derive(Clone, Copy, Debug, Default)]
struct RecentMeans {
    weight: f64,
    mean_x: Vector3<f64>,
    mean_y: Vector3<f64>,
}

impl RecentMeans {
    /// Forget by `keep` and add the pair; an update that would overflow is refused and
    /// leaves the means as they were.
    fn push(&mut self, keep: f64, x: &Vector3<f64>, y: &Vector3<f64>, w: f64) {
        let Some((weight, f)) = forgetful_weight(self.weight, keep, w) else { return };
        let next = RecentMeans {
            weight,
            mean_x: self.mean_x + (x - self.mean_x) * f,
            mean_y: self.mean_y + (y - self.mean_y) * f,
        };
        if next.mean_x.iter().chain(next.mean_y.iter()).all(|v| v.is_finite()) {
            *self = next;
        }
    }

    /// The translation that puts the recent VO centroid on the recent fix centroid.
    fn translation(&self, rotation: &nalgebra::Matrix3<f64>, scale: f64) -> Vector3<f64> {
        self.mean_y - rotation * self.mean_x * scale
    }
}

/// Incremental anchoring of VO to GNSS and wheel speed, with `K` latency hypotheses.
#[derive(Clone, Debug)]
pub struct Anchorer<const K: usize = 9> {
    config: AnchorConfig,
    hypotheses: [Hypothesis; K],
    history: VoHistory<VO_HISTORY>,
    pending: heapless::Deque<PendingFix, PENDING_ANCHORS>,
    odometer: Odometer,
    wheel: WheelScale,
    last_fix_time: Option<Timestamp>,
    last_accepted: Option<(Timestamp, Vector3<f64>, Option<f64>)>,
    consecutive_rejections: u32,
    /// Taking fixes at full weight after a lasting shift, until they agree again.
    recovering: bool,
    mean_fix_interval_s: f64,
    /// Σw² with the same forgetting as the moments (Σw is in the moments), for Kish's
    /// effective number of anchors (Σw)²/Σw².
    weight_squares: f64,
    /// Rotation and scale of the latest observable fit.
    held: Option<(nalgebra::Matrix3<f64>, f64)>,
    /// A prior on the rotation of this VO session ([`Anchorer::set_rotation_prior`]), VO → ENU.
    prior: Option<RotationPrior>,
    /// VO → the levelled frame the fit works in ([`Anchorer::level`]; identity until then).
    level: nalgebra::Matrix3<f64>,
    /// The session's vertical is known: the fit is gravity-aligned whatever the configured
    /// mode.
    levelled: bool,
    /// Information discount of the latest update (correlation × variance factor).
    inflation: f64,
    /// A-posteriori variance factor of the latest update.
    variance_factor: f64,
    estimate: Option<Sim3>,
    quality: Quality,
}

impl<const K: usize> Anchorer<K> {
    /// An anchorer with no data.
    pub fn new(config: AnchorConfig) -> Self {
        const { assert!(K >= 1, "an Anchorer needs at least one latency hypothesis") };
        let step = config.latency_step;
        let hypotheses = core::array::from_fn(|k| Hypothesis {
            latency: Duration::from_micros(step.micros().saturating_mul(k as i64)),
            moments: Moments::new(),
            recent: RecentCentroid::default(),
            steady: RecentMeans::default(),
            fit: None,
            prediction_sse: 0.0,
        });
        Anchorer {
            config,
            hypotheses,
            history: VoHistory::new(),
            pending: heapless::Deque::new(),
            odometer: Odometer::default(),
            wheel: WheelScale::default(),
            last_fix_time: None,
            last_accepted: None,
            consecutive_rejections: 0,
            recovering: false,
            mean_fix_interval_s: 0.0,
            weight_squares: 0.0,
            held: None,
            prior: None,
            level: nalgebra::Matrix3::identity(),
            levelled: false,
            inflation: 1.0,
            variance_factor: 1.0,
            estimate: None,
            quality: Quality {
                observability: Observability::TooFewAnchors,
                anchors_used: 0,
                anchors_rejected: 0,
                anchors_dropped: 0,
                rms_residual_m: 0.0,
                rotation_sigma_rad: f64::INFINITY,
                geometry_sigma_m: f64::INFINITY,
                scale_rel_sigma: f64::INFINITY,
                position_sigma_m: f64::INFINITY,
                latency_s: None,
                latency_shown: false,
                wheel_factor: None,
            },
        }
    }

    /// The configuration in use.
    pub fn config(&self) -> &AnchorConfig {
        &self.config
    }

    /// The current estimate (VO → ENU): rotation and scale of the latest observable fit,
    /// translation from the recent fixes. `None` until the fit was first observable.
    pub fn estimate(&self) -> Option<&Sim3> {
        self.estimate.as_ref()
    }

    /// The state of the latest fit.
    pub fn quality(&self) -> &Quality {
        &self.quality
    }

    /// The latest VO position mapped into ENU with the current estimate.
    pub fn current_position(&self) -> Option<Vector3<f64>> {
        Some(self.estimate?.transform_point(&(self.level.transpose() * self.history.latest()?.position)))
    }

    /// The degrees of freedom being estimated: the configured mode, or gravity-aligned once
    /// the session is levelled.
    pub fn mode(&self) -> AnchorMode {
        if self.levelled {
            AnchorMode::GravityAligned
        } else {
            self.config.mode
        }
    }

    /// The current VO session's vertical (ENU up in VO coordinates, any length), as the
    /// dashcam's accelerometer measures it through the camera's attitude: the session's
    /// coordinates are turned so that it is their z — the moments, the recent VO, the
    /// held rotation, exactly, so nothing learnt is lost — and the fit is gravity-aligned
    /// from then on ([`AnchorMode::GravityAligned`]): on a straight road the roll about
    /// the road, which no position observes, is gravity's. May be called again as the
    /// vertical is refined; a new VO session forgets it. Refused (state unchanged) unless
    /// `up` is finite and not zero.
    pub fn level(&mut self, up: &Vector3<f64>) -> Result<(), AnchorError> {
        if !up.iter().all(|v| v.is_finite()) {
            return Err(AnchorError::NonFinite);
        }
        let current = self.level * up;
        let Some(turn) = rotation_onto_z(&current) else { return Err(AnchorError::NonFinite) };
        self.level = turn * self.level;
        self.levelled = true;
        self.history.turn(&turn);
        self.wheel.turn(&turn);
        let mode = self.mode();
        for h in &mut self.hypotheses {
            h.moments.turn_x(&turn);
            h.recent.mean = turn * h.recent.mean;
            h.steady.mean_x = turn * h.steady.mean_x;
            h.fit = h.moments.align(align_mode(mode)).ok();
        }
        if let Some((rotation, scale)) = self.held {
            // Only the yaw of the held rotation is the gravity-aligned fit's to keep.
            self.held = yaw_rotation(&(rotation * turn.transpose())).ok().map(|(r, _)| (r, scale));
        }
        Ok(())
    }

    /// The wheel factor (true distance / wheel distance) as calibrated against the GNSS
    /// path so far.
    pub fn wheel_factor(&self) -> Option<f64> {
        self.wheel.measured().map(|_| self.wheel.calibration(self.variance_factor).0)
    }

    /// The VO lost track and started again (a new origin, orientation and scale): what
    /// was learnt about the old VO frame no longer holds, so the fit starts afresh; what
    /// concerns only the car and the receiver — the wheel factor, the odometer, the last
    /// accepted fix for the jump test, the fix rate — is kept.
    pub fn new_vo_session(&mut self) {
        let mut wheel = self.wheel;
        wheel.new_vo_session();
        *self = Anchorer {
            odometer: self.odometer,
            wheel,
            last_fix_time: self.last_fix_time,
            last_accepted: self.last_accepted,
            mean_fix_interval_s: self.mean_fix_interval_s,
            ..Anchorer::new(self.config)
        };
    }

    /// What is known of the current VO session's rotation (VO → ENU) before its fixes —
    /// on a re-initialisation, the old session's last camera attitude carried across the
    /// gap through the new session's first — with its 1-σ error per axis (rad; only the
    /// yaw counts in [`AnchorMode::GravityAligned`]). It is one more observation of the
    /// rotation, forgotten as the fixes are, so it matters while they do not yet fix the
    /// rotation and fades as they do. A prior replaces the previous one; refused (state
    /// unchanged) unless `rotation` is a proper rotation and σ positive and finite.
    pub fn set_rotation_prior(&mut self, rotation: nalgebra::Matrix3<f64>, sigma_rad: f64) -> Result<(), AnchorError> {
        if !rotation.iter().all(|v| v.is_finite()) {
            return Err(AnchorError::NonFinite);
        }
        if !(sigma_rad.is_finite() && sigma_rad > 0.0) {
            return Err(AnchorError::InvalidSigma);
        }
        let orthonormal = (rotation.transpose() * rotation - nalgebra::Matrix3::identity()).norm() < 1e-6;
        if !(orthonormal && rotation.determinant() > 0.0) {
            return Err(AnchorError::NotARotation);
        }
        let information = 1.0 / (sigma_rad * sigma_rad);
        if !information.is_finite() {
            return Err(AnchorError::InvalidSigma);
        }
        self.prior = Some(RotationPrior { rotation, information });
        Ok(())
    }

    /// A vehicle-speed sample (wheel-based or vehicle speed, m/s).
    pub fn push_speed(&mut self, t: Timestamp, speed_mps: f64) -> Result<(), AnchorError> {
        if !speed_mps.is_finite() {
            return Err(AnchorError::NonFinite);
        }
        if self.odometer.last_time().is_some_and(|last| t < last) {
            return Err(AnchorError::OutOfOrder);
        }
        self.odometer.push(t, speed_mps.max(0.0));
        Ok(())
    }

    /// A VO position (VO frame, unknown scale). Processes any fixes it now brackets.
    pub fn push_vo(&mut self, t: Timestamp, position: Vector3<f64>) -> Result<(), AnchorError> {
        if !position.iter().all(|v| v.is_finite()) {
            return Err(AnchorError::NonFinite);
        }
        if self.history.latest().is_some_and(|s| t <= s.t) {
            return Err(AnchorError::OutOfOrder);
        }
        let position = self.level * position;
        let odometer_m = self.odometer.at(t);
        if let Some(odo) = odometer_m {
            self.wheel.push_frame(t, &position, odo, self.config.wheel_time_constant_s);
        }
        self.history.push(VoSample { t, position, odometer_m });
        while let Some(fix) = self.pending.front().copied() {
            if fix.t > t {
                break;
            }
            self.pending.pop_front();
            self.process_fix(fix);
        }
        Ok(())
    }

    /// A GNSS fix received at `t_rx`, converted to the local ENU frame, with its 1-σ
    /// horizontal error (see [`gnss_sigma`]). It is used as soon as a VO sample at or
    /// after `t_rx` arrives.
    pub fn push_gnss(&mut self, t_rx: Timestamp, enu: Vector3<f64>, sigma_m: f64) -> Result<(), AnchorError> {
        if !enu.iter().all(|v| v.is_finite()) {
            return Err(AnchorError::NonFinite);
        }
        if !(sigma_m.is_finite() && sigma_m > 0.0) {
            return Err(AnchorError::InvalidSigma);
        }
        if self.last_fix_time.is_some_and(|last| t_rx < last) {
            return Err(AnchorError::OutOfOrder);
        }
        if let Some(last) = self.last_fix_time {
            let dt = (t_rx - last).as_secs_f64();
            self.mean_fix_interval_s =
                if self.mean_fix_interval_s == 0.0 { dt } else { 0.9 * self.mean_fix_interval_s + 0.1 * dt };
        }
        self.last_fix_time = Some(t_rx);
        let fix = PendingFix { t: t_rx, enu, sigma: sigma_m };
        if self.history.latest().is_some_and(|s| s.t >= t_rx) {
            self.process_fix(fix);
        } else {
            if self.pending.is_full() {
                // VO has stalled; the oldest waiting fix is the least useful.
                self.pending.pop_front();
                self.quality.anchors_dropped = self.quality.anchors_dropped.saturating_add(1);
            }
            // Cannot fail: a slot is free.
            let _ = self.pending.push_back(fix);
        }
        Ok(())
    }

    /// A GNSS course over ground at `t` (rad clockwise from north, as NMEA gives it) with its
    /// 1-σ (rad): while the session has neither an estimate nor a rotation prior and is
    /// gravity-aligned, the direction the VO moved in over the second before — the camera
    /// moves along the road whatever its yaw on the car — set against the course is the
    /// session's yaw, taken as its rotation prior ([`Anchorer::set_rotation_prior`]). Only
    /// on a straight second (its two halves' directions within 2°) and after 5 m of VO motion
    /// at the latest scale the wheels know; returns whether it was taken.
    pub fn push_course(&mut self, t: Timestamp, course_rad: f64, sigma_rad: f64) -> bool {
        if self.estimate.is_some() || self.prior.is_some() || self.mode() != AnchorMode::GravityAligned {
            return false;
        }
        // The second of VO up to its latest pose, which the fix is at most 0.2 s from.
        let Some(end) = self.history.latest().map(|s| s.t).filter(|end| (t - *end).as_secs_f64().abs() <= 0.2) else {
            return false;
        };
        let half = Duration::from_millis(500);
        let (Some((p0, _)), Some((p1, _)), Some((p2, _))) =
            (self.history.at(end - half - half), self.history.at(end - half), self.history.at(end))
        else {
            return false;
        };
        let direction = |a: Vector3<f64>, b: Vector3<f64>| libm::atan2(b.y - a.y, b.x - a.x);
        let (first, second, whole) = (direction(p0, p1), direction(p1, p2), direction(p0, p2));
        let bend = libm::fabs(libm::remainder(second - first, core::f64::consts::TAU));
        let moved_m = self.wheel.uncalibrated_scale().map_or(0.0, |scale| scale * (p2 - p0).xy().norm());
        if !(bend <= MAX_COURSE_BEND_RAD && moved_m >= MIN_COURSE_TRAVEL_M && course_rad.is_finite()) {
            return false;
        }
        // ENU heading (from east, counter-clockwise) of the course, less the VO's.
        let yaw = core::f64::consts::FRAC_PI_2 - course_rad - whole;
        let rotation = crate::sim3::rotation_z(yaw) * self.level;
        self.set_rotation_prior(rotation, sigma_rad).is_ok()
    }

    fn best_index(&self) -> usize {
        let mut best = 0;
        for (k, h) in self.hypotheses.iter().enumerate() {
            if h.prediction_sse < self.hypotheses[best].prediction_sse {
                best = k;
            }
        }
        best
    }

    fn process_fix(&mut self, fix: PendingFix) {
        // VO (and odometer) at the instant each hypothesis says the fix describes. The
        // hypotheses are compared on the same fixes, so a fix some look-back cannot
        // reach (the first instants of a drive, a VO gap) is used by none.
        let mut paired = [(Vector3::zeros(), None); K];
        for (slot, h) in paired.iter_mut().zip(&self.hypotheses) {
            match self.history.at(fix.t - h.latency) {
                Some(p) => *slot = p,
                None => {
                    self.quality.anchors_dropped = self.quality.anchors_dropped.saturating_add(1);
                    return;
                }
            }
        }
        let best = self.best_index();
        let (x_best, odo_best) = paired[best];

        let base_weight = 1.0 / (fix.sigma * fix.sigma);
        let mut weight = base_weight;
        // After a long run of rejections the fixes have really moved: recover by taking
        // them at full weight (no gate, no down-weighting) until they agree again.
        if self.consecutive_rejections >= MAX_CONSECUTIVE_REJECTIONS {
            self.recovering = true;
        }
        // Robust weighting against the current fit of the leading hypothesis.
        if let Some(fit) = self.hypotheses[best].fit {
            let u = (fix.enu - fit.transform_point(&x_best)).norm() / fix.sigma;
            if u <= self.config.gate_sigma {
                self.recovering = false;
            }
            if !self.recovering {
                if self.quality.observability == Observability::Observable && u > self.config.gate_sigma {
                    self.reject();
                    return;
                }
                let r = u / self.config.robust_scale_sigma;
                weight /= 1.0 + r * r;
            }
        }
        // Jump test against the wheels: the fix cannot have moved farther than the car.
        if let (Some((t0, p0, Some(o0))), Some(o1), false) = (self.last_accepted, odo_best, self.recovering) {
            let moved = (fix.enu - p0).norm();
            let travelled = (o1 - o0).abs();
            let slack = self.config.gate_sigma * fix.sigma * core::f64::consts::SQRT_2;
            let recent = (fix.t - t0).as_secs_f64() < JUMP_TEST_WINDOW_S;
            if recent && moved > travelled * JUMP_TRAVEL_FACTOR + slack {
                self.reject();
                return;
            }
        }
        self.consecutive_rejections = 0;

        let since_last = self.last_accepted.map_or(0.0, |(t0, _, _)| (fix.t - t0).as_secs_f64());
        let forget = libm::exp(-since_last / self.config.forgetting_time_constant_s);
        let keep_recent = libm::exp(-since_last / self.config.translation_time_constant_s);
        let shortest = self.config.translation_time_constant_s;
        // σ0 of the last estimate: how the residuals compare with the stated σ. Never above
        // 1, so a jump of the fixes (which swells the residuals) does not lengthen the window.
        let residual_ratio = libm::sqrt(self.variance_factor / RESIDUAL_UNDERSTATEMENT).min(1.0);
        let steady_s = (shortest * fix.sigma * residual_ratio / STEADY_REFERENCE_SIGMA_M)
            .min(self.config.forgetting_time_constant_s)
            .max(shortest);
        let keep_steady = libm::exp(-since_last / steady_s);
        let align_mode = align_mode(self.mode());
        let scoring = self.quality.observability == Observability::Observable;
        let gate2 = self.config.gate_sigma * self.config.gate_sigma;
        for (h, (x, _)) in self.hypotheses.iter_mut().zip(paired) {
            // Latency is scored by one-step-ahead prediction error, only once the fits
            // are trustworthy (early near-degenerate fits predict wildly for every
            // hypothesis) and clipped at the gate so no single fix dominates.
            if let (Some(fit), true) = (h.fit, scoring) {
                let u2 = (fix.enu - fit.transform_point(&x)).norm_squared() / (fix.sigma * fix.sigma);
                h.prediction_sse += u2.min(gate2);
            }
            h.moments.forget(forget);
            h.recent.push(keep_recent, &x, weight);
            h.steady.push(keep_steady, &x, &fix.enu, weight);
            // Finite by the checks in push_gnss / push_vo.
            let _ = h.moments.push(&x, &fix.enu, weight);
            h.fit = h.moments.align(align_mode).ok();
        }
        if let Some(prior) = &mut self.prior {
            prior.information *= forget;
        }
        self.weight_squares = self.weight_squares * forget * forget + weight * weight;
        self.quality.anchors_used = self.quality.anchors_used.saturating_add(1);
        self.last_accepted = Some((fix.t, fix.enu, odo_best));

        let best = self.best_index();
        if let (_, Some(odo)) = paired[best] {
            self.wheel.push_fix(fix.t, &fix.enu, fix.sigma, odo, &x_best);
        }
        self.update_estimate(best, &x_best, fix.sigma);
    }

    /// The wheel scale (metres per VO unit) and its variance.
    fn wheel_prior(&self) -> Option<(f64, f64)> {
        let (factor, factor_rel_var) = self.wheel.calibration(self.variance_factor);
        let scale = factor * self.wheel.uncalibrated_scale()?;
        let rel = self.config.wheel_scale_rel_sigma + libm::sqrt(factor_rel_var);
        let var = (rel * scale) * (rel * scale);
        (var > 0.0 && var.is_finite()).then_some((scale, var))
    }

    fn reject(&mut self) {
        self.consecutive_rejections = self.consecutive_rejections.saturating_add(1);
        self.quality.anchors_rejected = self.quality.anchors_rejected.saturating_add(1);
    }

    /// Parabolic refinement of the best latency hypothesis.
    fn latency_estimate(&self, best: usize) -> Option<f64> {
        if self.config.latency_step == Duration::ZERO || K < 3 {
            return None;
        }
        let step = self.config.latency_step.as_secs_f64();
        let base = self.hypotheses[best].latency.as_secs_f64();
        if best == 0 || best + 1 >= K {
            return Some(base);
        }
        let (a, b, c) = (
            self.hypotheses[best - 1].prediction_sse,
            self.hypotheses[best].prediction_sse,
            self.hypotheses[best + 1].prediction_sse,
        );
        let denom = a - 2.0 * b + c;
        let offset = if denom > 0.0 { 0.5 * (a - c) / denom } else { 0.0 };
        Some(base + offset.clamp(-0.5, 0.5) * step)
    }

    /// The σ of a latency known only to lie within the hypotheses' span, s: a uniform
    /// distribution's, span/√12. The fixes pair with the VO that long before their arrival,
    /// so the translation carries that latency's error times the speed along the road — an
    /// error the fixes' residuals cannot show (the fit absorbs it), which the reported
    /// position's σ adds. The best hypothesis narrows it only where the drive shows the
    /// latency, and a parabola's σ through the best and its neighbours was about twice the
    /// real error on the tuning seeds (docs/pipeline.md#clocks), so the span's σ is kept
    /// throughout.
    fn latency_span_sigma_s(&self) -> f64 {
        self.config.latency_step.as_secs_f64() * (K - 1) as f64 / libm::sqrt(12.0)
    }

    /// The VO's speed over its latest half second, m/s at `scale` metres per VO unit; 0
    /// before it has moved that long.
    fn vo_speed_mps(&self, scale: f64) -> f64 {
        let Some(latest) = self.history.latest() else { return 0.0 };
        let half = Duration::from_millis(500);
        self.history.at(latest.t - half).map_or(0.0, |(p, _)| scale * (latest.position - p).norm() / half.as_secs_f64())
    }

    /// Whether the hypotheses' prediction errors tell the latency: the worst's sum exceeds
    /// the best's by [`LATENCY_SHOWN_CHI2`].
    fn latency_shown(&self, best: usize) -> bool {
        let worst = self.hypotheses.iter().map(|h| h.prediction_sse).fold(0.0, f64::max);
        worst - self.hypotheses[best].prediction_sse >= LATENCY_SHOWN_CHI2
    }

    fn update_estimate(&mut self, best: usize, current: &Vector3<f64>, fix_sigma: f64) {
        self.quality.latency_s = self.latency_estimate(best);
        self.quality.latency_shown = self.quality.latency_s.is_some() && self.latency_shown(best);
        let h = &self.hypotheses[best];
        self.quality.wheel_factor = self.wheel_factor();
        let Some(gnss_fit) = h.fit else {
            self.quality.observability = Observability::TooFewAnchors;
            return;
        };
        let m = &h.moments;
        // Variance inflation: GNSS errors are correlated over `gnss_correlation_time_s`,
        // so neighbouring fixes are not independent; and the stated σ is scaled by the
        // a-posteriori variance factor σ0² = Σw‖r‖²/(3·n_eff − p) — dimensionless: w = 1/σ²,
        // each fix three residual components, p the similarity's parameters — times what
        // residuals understate ([`RESIDUAL_UNDERSTATEMENT`]), never below
        // [`MIN_VARIANCE_FACTOR`].
        let correlation = if self.mean_fix_interval_s > 0.0 {
            (self.config.gnss_correlation_time_s / self.mean_fix_interval_s).max(1.0)
        } else {
            1.0
        };
        let fit = gnss_fit;
        let n_eff = if self.weight_squares > 0.0 { m.weight() * m.weight() / self.weight_squares } else { 0.0 };
        let parameters = match self.mode() {
            AnchorMode::Full => 7.0,
            AnchorMode::GravityAligned => 5.0,
        };
        let dof = RESIDUAL_COMPONENTS * n_eff - parameters;
        let sigma0_sq = if dof > 0.0 { m.weighted_sse(&fit) / dof } else { f64::INFINITY };
        let variance_factor = (RESIDUAL_UNDERSTATEMENT * sigma0_sq).max(MIN_VARIANCE_FACTOR);
        let inflation = correlation * variance_factor;
        self.inflation = inflation;
        self.variance_factor = variance_factor;
        let prior_information = self.prior.map_or(0.0, |p| p.information);
        // The prior is on VO → ENU; the fit is on the levelled frame.
        let prior = self.prior.map(|p| RotationPrior { rotation: p.rotation * self.level.transpose(), ..p });
        let fit = prior.and_then(|p| with_rotation_prior(fit, m, inflation, &p, self.mode())).unwrap_or(fit);
        let sxx = m.covariance_x() * m.weight();
        let trace = sxx.trace().max(0.0);
        // The translation is pinned at a centroid of recent pairs: rotation and scale errors
        // act through the lever arm from there to the current point — from the short
        // window's for observability, from the steady window's for the reported position.
        let offset = current - h.recent.mean;
        let steady_offset = current - h.steady.mean_x;
        let c = fit.scale;
        // Rotation information (rad⁻²) about unit axis a is c²·aᵀ(tr(S)·I − S)a / inflation
        // (S = Σw x'x'ᵀ) from the fixes, plus the prior's, the same about every axis, so
        // the eigen-axes are those of S. A rotation error θ about a moves the current point
        // by θ·c·‖a × offset‖.
        let (rotation_sigma, rotation_var_m2, steady_rotation_var_m2) = match self.mode() {
            AnchorMode::Full => {
                let Some(eig) =
                    nalgebra::SymmetricEigen::try_new(sxx, f64::EPSILON * 5.0, MAX_DECOMPOSITION_ITERATIONS)
                else {
                    self.quality.observability = Observability::Collinear;
                    return;
                };
                let mut weakest = 0.0f64;
                let (mut var, mut steady_var) = (0.0, 0.0);
                for i in 0..3 {
                    let info = c * c * (trace - eig.eigenvalues[i]).max(0.0) / inflation + prior_information;
                    let axis = eig.eigenvectors.column(i);
                    weakest = weakest.max(1.0 / info);
                    for (lever, sum) in [(&offset, &mut var), (&steady_offset, &mut steady_var)] {
                        let lever2 = axis.cross(lever).norm_squared();
                        *sum += if lever2 > 0.0 { c * c * lever2 / info } else { 0.0 };
                    }
                }
                (libm::sqrt(weakest), var, steady_var)
            }
            AnchorMode::GravityAligned => {
                let info = c * c * (sxx[(0, 0)] + sxx[(1, 1)]) / inflation + prior_information;
                let lever2 = |o: &Vector3<f64>| o.x * o.x + o.y * o.y;
                (libm::sqrt(1.0 / info), c * c * lever2(&offset) / info, c * c * lever2(&steady_offset) / info)
            }
        };
        let (fused, scale_var) = fuse_wheel_scale(fit, m, inflation, self.wheel_prior());
        let Some(fit) = fused else {
            self.quality.observability = Observability::TooFewAnchors;
            return;
        };
        let scale_rel_sigma = libm::sqrt(scale_var) / fit.scale;
        let geometry_sigma = libm::sqrt(rotation_var_m2 + scale_var * offset.norm_squared());
        let steady_geometry_sigma = libm::sqrt(steady_rotation_var_m2 + scale_var * steady_offset.norm_squared());
        self.quality.rotation_sigma_rad = rotation_sigma;
        self.quality.geometry_sigma_m = geometry_sigma;
        self.quality.scale_rel_sigma = scale_rel_sigma;
        let latency_sigma_m = self.vo_speed_mps(fit.scale) * self.latency_span_sigma_s();
        self.quality.position_sigma_m = libm::sqrt(
            2.0 * fix_sigma * fix_sigma * variance_factor
                + steady_geometry_sigma * steady_geometry_sigma
                + latency_sigma_m * latency_sigma_m,
        );
        let long_window = Sim3 { translation: m.mean_y() - fit.rotation * m.mean_x() * fit.scale, ..fit };
        self.quality.rms_residual_m =
            if m.weight() > 0.0 { libm::sqrt(m.weighted_sse(&long_window) / m.weight()) } else { 0.0 };
        let geometry_bound =
            self.config.max_geometry_sigma_m.max(GEOMETRY_SHARE_OF_FIX * fix_sigma * libm::sqrt(variance_factor));
        self.quality.observability = if m.count() < self.config.min_anchors {
            Observability::TooFewAnchors
        } else if geometry_sigma.is_nan() || geometry_sigma > geometry_bound {
            Observability::Collinear
        } else if scale_rel_sigma.is_nan() || scale_rel_sigma > self.config.max_scale_rel_sigma {
            Observability::ScaleUncertain
        } else {
            Observability::Observable
        };
        // Rotation and scale are taken when observable and held otherwise (VO drift is
        // slow); the translation always follows the recent fixes.
        if self.quality.observability == Observability::Observable && fit.is_valid() {
            self.held = Some((fit.rotation, fit.scale));
        }
        let steady = &self.hypotheses[best].steady;
        let candidate = self.held.map(|(rotation, scale)| Sim3 {
            rotation,
            translation: steady.translation(&rotation, scale),
            scale,
        });
        // Extreme (finite) inputs can still overflow the product: never report that. The
        // estimate is VO → ENU: the levelling first.
        if let Some(t) = candidate.map(|t| Sim3 { rotation: t.rotation * self.level, ..t }).filter(Sim3::is_valid) {
            self.estimate = Some(t);
        }
    }
}

fn align_mode(mode: AnchorMode) -> AlignMode {
    match mode {
        AnchorMode::Full => AlignMode::Sim3,
        AnchorMode::GravityAligned => AlignMode::YawScale,
    }
}

/// The smallest rotation taking `v` onto +z; `None` for a zero vector.
fn rotation_onto_z(v: &Vector3<f64>) -> Option<nalgebra::Matrix3<f64>> {
    let n = v.norm();
    if !(n.is_finite() && n > 0.0) {
        return None;
    }
    let u = v / n;
    let axis = u.cross(&Vector3::z());
    let sin = axis.norm();
    if sin < 1e-12 {
        // Already up, or straight down (half a turn about x).
        return Some(if u.z > 0.0 {
            nalgebra::Matrix3::identity()
        } else {
            nalgebra::Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
        });
    }
    let angle = libm::atan2(sin, u.z);
    Some(*nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle).matrix())
}

/// The fit's rotation with the prior's weighed in: the rotation maximising
/// tr(Rᵀ·(c·Σw y'x'ᵀ / inflation + ½·prior information·R_prior)) — Wahba's problem with the
/// fixes' cross-covariance (at the fit's scale, discounted as for observability) and the
/// prior as one more observation — and the scale that goes with it.
fn with_rotation_prior(
    fit: Sim3,
    moments: &Moments,
    inflation: f64,
    prior: &RotationPrior,
    mode: AnchorMode,
) -> Option<Sim3> {
    let cross = moments.cross_covariance() * moments.weight();
    let b = cross * (fit.scale / inflation) + prior.rotation * (0.5 * prior.information);
    let rotation = match mode {
        AnchorMode::Full => umeyama_rotation(&b),
        AnchorMode::GravityAligned => yaw_rotation(&b),
    }
    .ok()?
    .0;
    let spread = (moments.covariance_x() * moments.weight()).trace();
    let scale = rotation.component_mul(&cross).sum() / spread;
    let fit = Sim3 { rotation, scale, translation: moments.mean_y() - rotation * moments.mean_x() * scale };
    (fit.is_valid() && scale > 0.0).then_some(fit)
}

/// Fuse an Umeyama fit's scale with the wheel scale by inverse variance and move the
/// translation accordingly; returns the fit and the variance of its scale.
fn fuse_wheel_scale(fit: Sim3, moments: &Moments, inflation: f64, wheel: Option<(f64, f64)>) -> (Option<Sim3>, f64) {
    // Information on the scale from the GNSS fixes: the fit's cost is quadratic in c
    // with curvature tr(S) (S = Σw x'x'ᵀ, w = 1/σ²).
    let trace = (moments.covariance_x() * moments.weight()).trace();
    let gnss_var = inflation / trace;
    let (scale, var) = match wheel {
        Some((wheel_scale, wheel_var)) if gnss_var.is_finite() && gnss_var > 0.0 => {
            let var = 1.0 / (1.0 / gnss_var + 1.0 / wheel_var);
            ((fit.scale / gnss_var + wheel_scale / wheel_var) * var, var)
        }
        _ => (fit.scale, gnss_var),
    };
    let fused = Sim3 { translation: moments.mean_y() - fit.rotation * moments.mean_x() * scale, scale, ..fit };
    (fused.is_valid().then_some(fused), var)
}

#[cfg(test)]
mod tests;
