//! Visual odometry as a monocular dashcam gives it: the true motion of the camera seen
//! through a similarity (VO → ENU) whose scale and heading wander, with noise on every
//! frame-to-frame increment of translation and rotation, and — on a real road — tracking
//! lost now and then and the VO started again with a new origin, orientation and scale.
//!
//! The rotation error of each increment is modelled by what it adds up to: about the
//! vertical it accumulates into a heading random walk (nothing observes the heading);
//! about the horizontal axes gravity holds it, so the tilt of the VO frame is a bounded,
//! correlated error (a VO levelled by the dashcam's accelerometer). Each reported
//! orientation carries white jitter on top.

use std::f64::consts::PI;

use dash2sim_core::nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use dash2sim_core::sim3::{rotation_z, Pose};
use rand::Rng;

use super::gauss;
use dash2sim_linux::trajectory::Trajectory;

/// Tracking loss and re-initialisation: after a gap the VO starts again with a new origin,
/// heading and scale, under a new session number.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reinit {
    /// Time between re-initialisations, s (uniform). A drive starts at a random point of
    /// this cycle, so a short drive may or may not see one.
    pub every_s: (f64, f64),
    /// How long tracking is lost, s (uniform): no VO poses in the gap.
    pub gap_s: (f64, f64),
    /// The new scale is the old one times a factor log-uniform in this range.
    pub scale_factor: (f64, f64),
}

/// How the VO track is made from the truth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoModel {
    /// Metres per VO unit at t = 0.
    pub scale: f64,
    /// VO → ENU rotation at t = 0.
    pub rotation: Matrix3<f64>,
    /// Linear relative scale drift per minute (0.01 = 1 %): the ideal profile's smooth drift.
    pub scale_drift_per_min: f64,
    /// Linear yaw drift, degrees per minute: the ideal profile's smooth drift.
    pub yaw_drift_deg_per_min: f64,
    /// σ of the log-scale random walk after one minute (0.01 ≈ 1 %).
    pub scale_walk_per_sqrt_min: f64,
    /// σ of the heading random walk after one minute, degrees.
    pub yaw_walk_deg_per_sqrt_min: f64,
    /// σ of the VO frame's tilt (pitch and roll each), degrees: a Gauss–Markov error with
    /// a 10 s correlation time (levelling by gravity keeps it bounded).
    pub tilt_deg: f64,
    /// Noise on every translation increment, per axis, relative to its length.
    pub translation_noise: f64,
    /// White error of every reported orientation, per axis, degrees.
    pub rotation_noise_deg: f64,
    /// Tracking loss and re-initialisation, if any.
    pub reinit: Option<Reinit>,
}

/// Correlation time of the VO frame's tilt error, s.
const TILT_CORRELATION_S: f64 = 10.0;

impl VoModel {
    /// An arbitrary 3D orientation and scale 3.7 with 1 %/min scale and 1°/min yaw drift,
    /// both linear, and no noise: the smooth similarity of the ideal profile.
    pub fn arbitrary() -> Self {
        let axis = Unit::new_normalize(Vector3::new(0.4, -0.7, 0.6));
        VoModel {
            scale: 3.7,
            rotation: *Rotation3::from_axis_angle(&axis, 2.3).matrix(),
            scale_drift_per_min: 0.01,
            yaw_drift_deg_per_min: 1.0,
            scale_walk_per_sqrt_min: 0.0,
            yaw_walk_deg_per_sqrt_min: 0.0,
            tilt_deg: 0.0,
            translation_noise: 0.0,
            rotation_noise_deg: 0.0,
            reinit: None,
        }
    }

    /// A gravity-aligned VO frame (visual-inertial odometry, or VO levelled by the
    /// dashcam's accelerometer): z is up, the heading is arbitrary (2.3 rad), scale 3.7,
    /// with 1 %/min scale and 1°/min yaw drift. Anchor it with `--mode gravity`.
    pub fn gravity_aligned() -> Self {
        VoModel { rotation: rotation_z(2.3), ..VoModel::arbitrary() }
    }

    /// The scale of the linear drift alone at `t` seconds from the start (the true scale
    /// of a track made by [`VoModel::make_vo`]).
    pub fn scale_at(&self, t: f64) -> f64 {
        self.scale * (1.0 + self.scale_drift_per_min * t / 60.0)
    }

    fn linear_rotation_at(&self, t: f64, base: &Matrix3<f64>) -> Matrix3<f64> {
        rotation_z((self.yaw_drift_deg_per_min * t / 60.0).to_radians()) * base
    }

    /// VO poses through the linear drift alone, without noise: truth increments mapped back
    /// through the drifting similarity, and the truth orientations seen from the drifting
    /// VO frame.
    pub fn make_vo(&self, truth: &Trajectory) -> Trajectory {
        let Some(&t0) = truth.stamps.first() else { return Trajectory::default() };
        let mut vo = Trajectory::default();
        let mut x = Vector3::zeros();
        for (k, (&t, pose)) in truth.stamps.iter().zip(&truth.poses).enumerate() {
            if k > 0 {
                let dp = pose.translation - truth.poses[k - 1].translation;
                let tau = t - t0;
                x += self.linear_rotation_at(tau, &self.rotation).transpose() * dp / self.scale_at(tau);
            }
            vo.stamps.push(t);
            let rotation = self.linear_rotation_at(t - t0, &self.rotation).transpose() * pose.rotation;
            vo.poses.push(Pose { rotation, translation: x });
        }
        vo
    }

    /// The VO track of a camera moving along `truth`, with every error of the model drawn
    /// from `rng`. A model without random walks, tilt, rotation noise or re-initialisation
    /// draws nothing for them, so such a track depends only on the translation noise's draws.
    pub fn generate(&self, truth: &Trajectory, rng: &mut impl Rng) -> VoTrack {
        let mut track = VoTrack::default();
        let Some(&t0) = truth.stamps.first() else { return track };
        let mut session = Session { number: 0, scale: self.scale, rotation: self.rotation };
        // The clean position and the accumulated noise apart, so that a noise-free model
        // gives exactly `make_vo`'s positions.
        let (mut clean, mut offset) = (Vector3::zeros(), Vector3::zeros());
        let mut walk = Walk::default();
        if self.tilt_deg > 0.0 {
            walk.tilt = [gauss(rng, self.tilt_deg.to_radians()), gauss(rng, self.tilt_deg.to_radians())];
        }
        let mut next_loss = self.reinit.map(|r| t0 + rng.random::<f64>() * uniform(rng, r.every_s));
        let mut lost_until: Option<f64> = None;
        let mut previous: Option<usize> = None;
        let mut previous_t = t0;
        for (k, (&t, pose)) in truth.stamps.iter().zip(&truth.poses).enumerate() {
            walk.advance(self, t - previous_t, rng);
            previous_t = t;
            if let Some(r) = self.reinit {
                if lost_until.is_none() && next_loss.is_some_and(|at| t >= at) {
                    lost_until = Some(t + uniform(rng, r.gap_s));
                    next_loss = None;
                }
                if lost_until.is_some_and(|until| t < until) {
                    previous = None;
                    continue;
                }
                if lost_until.take().is_some() {
                    let (lo, hi) = r.scale_factor;
                    let factor = (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp();
                    session = Session {
                        number: session.number + 1,
                        scale: session.scale * factor,
                        rotation: rotation_z(rng.random_range(-PI..PI)) * self.rotation,
                    };
                    (clean, offset) = (Vector3::zeros(), Vector3::zeros());
                    next_loss = Some(t + uniform(rng, r.every_s));
                }
            }
            let tau = t - t0;
            let scale = self.session_scale(&session, tau, &walk);
            let vo_to_enu = self.session_rotation(&session, tau, &walk);
            if let Some(p) = previous {
                let dp = pose.translation - truth.poses[p].translation;
                let before = clean;
                clean += vo_to_enu.transpose() * dp / scale;
                if self.translation_noise > 0.0 {
                    let sigma = self.translation_noise * (clean - before).norm();
                    offset += Vector3::new(gauss(rng, sigma), gauss(rng, sigma), gauss(rng, sigma));
                }
            }
            let mut rotation = vo_to_enu.transpose() * pose.rotation;
            if self.rotation_noise_deg > 0.0 {
                let sigma = self.rotation_noise_deg.to_radians();
                let jitter = Vector3::new(gauss(rng, sigma), gauss(rng, sigma), gauss(rng, sigma));
                rotation *= Rotation3::from_scaled_axis(jitter).matrix();
            }
            track.poses.stamps.push(t);
            track.poses.poses.push(Pose { rotation, translation: clean + offset });
            track.samples.push(VoSample { frame: k, session: session.number, scale, vo_to_enu });
            previous = Some(k);
        }
        track
    }

    fn session_scale(&self, session: &Session, tau: f64, walk: &Walk) -> f64 {
        let linear = session.scale * (1.0 + self.scale_drift_per_min * tau / 60.0);
        if self.scale_walk_per_sqrt_min > 0.0 {
            linear * walk.log_scale.exp()
        } else {
            linear
        }
    }

    fn session_rotation(&self, session: &Session, tau: f64, walk: &Walk) -> Matrix3<f64> {
        let mut base = session.rotation;
        if self.tilt_deg > 0.0 {
            base = Rotation3::from_euler_angles(walk.tilt[0], walk.tilt[1], 0.0).matrix() * base;
        }
        if self.yaw_walk_deg_per_sqrt_min > 0.0 {
            base = rotation_z(walk.yaw) * base;
        }
        self.linear_rotation_at(tau, &base)
    }
}

/// One VO session: its number and its similarity at its start.
#[derive(Clone, Copy, Debug)]
struct Session {
    number: u32,
    scale: f64,
    rotation: Matrix3<f64>,
}

/// The random walks and the tilt, advanced frame by frame.
#[derive(Clone, Copy, Debug, Default)]
struct Walk {
    log_scale: f64,
    yaw: f64,
    tilt: [f64; 2],
}

impl Walk {
    fn advance(&mut self, model: &VoModel, dt: f64, rng: &mut impl Rng) {
        if dt <= 0.0 {
            return;
        }
        let per_sqrt_s = (dt / 60.0).sqrt();
        if model.scale_walk_per_sqrt_min > 0.0 {
            self.log_scale += gauss(rng, model.scale_walk_per_sqrt_min * per_sqrt_s);
        }
        if model.yaw_walk_deg_per_sqrt_min > 0.0 {
            self.yaw += gauss(rng, model.yaw_walk_deg_per_sqrt_min.to_radians() * per_sqrt_s);
        }
        if model.tilt_deg > 0.0 {
            let phi = (-dt / TILT_CORRELATION_S).exp();
            let fresh = (1.0 - phi * phi).sqrt() * model.tilt_deg.to_radians();
            for tilt in &mut self.tilt {
                *tilt = phi * *tilt + gauss(rng, fresh);
            }
        }
    }
}

fn uniform(rng: &mut impl Rng, (lo, hi): (f64, f64)) -> f64 {
    if hi > lo {
        rng.random_range(lo..hi)
    } else {
        lo
    }
}

/// A generated VO track: the poses the camera process reports (none while tracking is
/// lost) and, per pose, the truth behind it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VoTrack {
    /// The VO poses of the camera (VO frame, VO units), at frame times.
    pub poses: Trajectory,
    /// The truth behind each pose, in the same order.
    pub samples: Vec<VoSample>,
}

/// The truth behind one VO pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoSample {
    /// Index of the truth pose (the frame, from 0) it was made from.
    pub frame: usize,
    /// VO session: 0 at the start, one more after each re-initialisation.
    pub session: u32,
    /// True metres per VO unit.
    pub scale: f64,
    /// True VO → ENU rotation.
    pub vo_to_enu: Matrix3<f64>,
}

impl VoTrack {
    /// The pose and session of frame `frame` (from 0), if the VO tracked it.
    pub fn at_frame(&self, frame: usize) -> Option<(&Pose, u32)> {
        let k = self.samples.binary_search_by_key(&frame, |s| s.frame).ok()?;
        Some((self.poses.poses.get(k)?, self.samples.get(k)?.session))
    }

    /// Number of re-initialisations.
    pub fn reinits(&self) -> u32 {
        self.samples.last().map_or(0, |s| s.session)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;

    fn straight(seconds: f64, speed: f64) -> Trajectory {
        let mut t = Trajectory::default();
        for k in 0..=(seconds * 10.0) as usize {
            let s = k as f64 / 10.0;
            t.stamps.push(s);
            t.poses.push(Pose { rotation: rotation_z(0.3), translation: Vector3::new(speed * s, 0.0, 0.0) });
        }
        t
    }

    #[test]
    fn a_noise_free_model_gives_the_linear_track() {
        let truth = straight(30.0, 20.0);
        let model = VoModel::gravity_aligned();
        let track = model.generate(&truth, &mut ChaCha8Rng::seed_from_u64(3));
        assert_eq!(track.poses, model.make_vo(&truth));
        assert_eq!(track.reinits(), 0);
        assert!((track.samples[300].scale - model.scale_at(30.0)).abs() < 1e-12);
    }

    #[test]
    fn re_initialisation_leaves_a_gap_and_starts_a_new_session() {
        let truth = straight(300.0, 20.0);
        let reinit = Reinit { every_s: (40.0, 60.0), gap_s: (0.5, 2.0), scale_factor: (0.5, 2.0) };
        let model = VoModel { reinit: Some(reinit), ..VoModel::gravity_aligned() };
        let track = model.generate(&truth, &mut ChaCha8Rng::seed_from_u64(9));
        // 300 s at one re-init every 40–60 s: at least 4, at most 7 (the first is early).
        assert!((4..=7).contains(&track.reinits()), "{} re-inits", track.reinits());
        for w in track.samples.windows(2) {
            if w[1].session != w[0].session {
                assert_eq!(w[1].session, w[0].session + 1);
                let gap = truth.stamps[w[1].frame] - truth.stamps[w[0].frame];
                assert!((0.5..=2.2).contains(&gap), "a gap of {gap} s");
                let k = track.samples.iter().position(|s| s == &w[1]).expect("present");
                assert_eq!(track.poses.poses[k].translation, Vector3::zeros(), "a new origin");
                let ratio = w[1].scale / w[0].scale;
                assert!((0.49..=2.01).contains(&ratio), "scale × {ratio}");
            } else {
                assert_eq!(w[1].frame, w[0].frame + 1, "no gap inside a session");
            }
        }
    }

    #[test]
    fn random_walks_spread_as_the_square_root_of_time() {
        // 200 drives of 4 minutes: the log-scale's spread after 1 and 4 minutes.
        let truth = straight(240.0, 20.0);
        let model = VoModel {
            scale_drift_per_min: 0.0,
            yaw_drift_deg_per_min: 0.0,
            scale_walk_per_sqrt_min: 0.02,
            yaw_walk_deg_per_sqrt_min: 1.0,
            ..VoModel::gravity_aligned()
        };
        let (mut at_1, mut at_4, mut yaw_4) = (0.0, 0.0, 0.0);
        for seed in 0..200 {
            let track = model.generate(&truth, &mut ChaCha8Rng::seed_from_u64(seed));
            let log = |k: usize| (track.samples[k].scale / model.scale).ln();
            at_1 += log(600).powi(2);
            at_4 += log(2400).powi(2);
            let r = track.samples[2400].vo_to_enu * rotation_z(2.3).transpose();
            yaw_4 += r[(1, 0)].atan2(r[(0, 0)]).to_degrees().powi(2);
        }
        let (s1, s4, y4) = ((at_1 / 200.0).sqrt(), (at_4 / 200.0).sqrt(), (yaw_4 / 200.0).sqrt());
        assert!((0.016..0.024).contains(&s1), "σ after 1 min {s1}");
        assert!((0.032..0.048).contains(&s4), "σ after 4 min {s4}");
        assert!((1.6..2.4).contains(&y4), "yaw σ after 4 min {y4}°");
    }
}
