//! What a dashcam would record of a generated scene: a pinhole camera's 2D detections, a
//! monocular 3D detector's boxes (depth error growing with range, misses rising with range
//! and occlusion, false positives, class confusions, heading flips, a covariance that is
//! only roughly calibrated), GNSS fixes (correlated error, multipath jumps, outages, an
//! accuracy the receiver misreports, latency) and wheel speed (scale bias, latency, noise,
//! CAN resolution). The camera sits on the car where it was stuck, not where the device
//! is told it is ([`MountError`]).

use std::f64::consts::PI;

use dash2sim_core::box2d::Box2d;
use dash2sim_core::box3d::Box3d;
use dash2sim_core::nalgebra::{Matrix3, Vector3};
use dash2sim_core::pipeline::CameraMount;
use dash2sim_core::track3d::Detection3d;
use rand::Rng;
use rand_distr::{Distribution, Poisson};

use super::actors::{Class, EgoState, ObjectState};
use super::gauss;
use super::road::wrap;

/// A forward-looking pinhole camera on the ego vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Focal length, pixels.
    pub focal_px: f64,
    /// Image width, pixels.
    pub width: f64,
    /// Image height, pixels.
    pub height: f64,
    /// Mounting height above the ground, metres.
    pub mount_height: f64,
    /// Mounting position ahead of the ego reference point (rear axle), metres.
    pub mount_forward: f64,
    /// How the real mount differs from the nominal one above (which is what the device is
    /// told: [`CameraMount::default`]).
    pub mount_error: MountError,
}

/// How a dashcam really sits against its nominal mount: turned and moved a little, as a
/// camera stuck behind a windscreen by hand does.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MountError {
    /// Yaw of the camera against the body, rad (positive: looking left).
    pub yaw: f64,
    /// Pitch of the camera against the body, rad (the core's convention: about the left axis).
    pub pitch: f64,
    /// Position error (forward, left, up), m.
    pub offset: [f64; 3],
}

impl Default for Camera {
    /// A 1280 × 720 dashcam with a 65° horizontal field of view behind the windscreen,
    /// mounted exactly where the device is told.
    fn default() -> Self {
        Camera {
            focal_px: 1000.0,
            width: 1280.0,
            height: 720.0,
            mount_height: 1.3,
            mount_forward: 1.8,
            mount_error: MountError::default(),
        }
    }
}

/// A box in the ego frame (x forward, y left, z up from the ground under the reference point).
pub fn to_ego(ego: &EgoState, b: &Box3d) -> Box3d {
    let (c, s) = (ego.heading.cos(), ego.heading.sin());
    let (dx, dy) = (b.x - ego.x, b.y - ego.y);
    Box3d { x: c * dx + s * dy, y: -s * dx + c * dy, yaw: wrap(b.yaw - ego.heading), ..*b }
}

/// A box from the ego frame into the world frame.
pub fn to_world(ego: &EgoState, b: &Box3d) -> Box3d {
    let (c, s) = (ego.heading.cos(), ego.heading.sin());
    Box3d { x: ego.x + c * b.x - s * b.y, y: ego.y + s * b.x + c * b.y, yaw: wrap(b.yaw + ego.heading), ..*b }
}

/// A horizontal covariance (xx, xy, yy) turned by `angle`: R C Rᵀ.
pub fn rotate_covariance([xx, xy, yy]: [f64; 3], angle: f64) -> [f64; 3] {
    let (c, s) = (angle.cos(), angle.sin());
    [
        c * c * xx - 2.0 * c * s * xy + s * s * yy,
        c * s * (xx - yy) + (c * c - s * s) * xy,
        s * s * xx + 2.0 * c * s * xy + c * c * yy,
    ]
}

/// An ego-frame detection in the world frame (box and covariance).
pub fn detection_to_world(ego: &EgoState, d: &Detection3d) -> Detection3d {
    Detection3d {
        bbox: to_world(ego, &d.bbox),
        position_covariance: d.position_covariance.map(|c| rotate_covariance(c, ego.heading)),
        ..*d
    }
}

impl Camera {
    /// The mount the device is told: the nominal position, levelled axes.
    pub fn nominal_mount(&self) -> CameraMount {
        CameraMount { position: [self.mount_forward, 0.0, self.mount_height], roll_pitch_yaw: [0.0; 3] }
    }

    /// The real mount: the nominal one moved and turned by [`Camera::mount_error`].
    pub fn true_mount(&self) -> CameraMount {
        let e = &self.mount_error;
        CameraMount {
            position: [self.mount_forward + e.offset[0], e.offset[1], self.mount_height + e.offset[2]],
            roll_pitch_yaw: [0.0, e.pitch, e.yaw],
        }
    }

    /// An ego-frame point in the real camera's frame (x forward, y left, z up).
    fn ego_to_camera(&self, mount: &(Matrix3<f64>, Vector3<f64>), p: Vector3<f64>) -> Vector3<f64> {
        mount.0.transpose() * (p - mount.1)
    }

    fn true_mount_transform(&self) -> (Matrix3<f64>, Vector3<f64>) {
        let m = self.true_mount();
        (m.rotation(), Vector3::from(m.position))
    }

    /// The image box of an ego-frame 3D box seen by the real camera, clipped to the image,
    /// and the fraction of it inside the image; `None` when any corner is behind the camera
    /// or nothing is inside.
    pub fn project(&self, b: &Box3d) -> Option<(Box2d, f64)> {
        let (c, s) = (b.yaw.cos(), b.yaw.sin());
        let mount = self.true_mount_transform();
        let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for (dl, dw, dh) in [(1.0, 1.0, 1.0), (1.0, -1.0, 1.0), (-1.0, 1.0, 1.0), (-1.0, -1.0, 1.0)]
            .into_iter()
            .flat_map(|(l, w, _)| [(l, w, 1.0), (l, w, -1.0)])
        {
            let (l, w) = (dl * b.l / 2.0, dw * b.w / 2.0);
            let corner = Vector3::new(b.x + l * c - w * s, b.y + l * s + w * c, b.z + dh * b.h / 2.0);
            let [x, y, z] = self.ego_to_camera(&mount, corner).into();
            if x < 0.5 {
                return None;
            }
            let (u, v) = (self.width / 2.0 - self.focal_px * y / x, self.height / 2.0 - self.focal_px * z / x);
            (u0, v0, u1, v1) = (u0.min(u), v0.min(v), u1.max(u), v1.max(v));
        }
        let full = (u1 - u0) * (v1 - v0);
        let (cu0, cv0, cu1, cv1) = (u0.max(0.0), v0.max(0.0), u1.min(self.width), v1.min(self.height));
        if cu1 <= cu0 || cv1 <= cv0 || full <= 0.0 {
            return None;
        }
        let clipped = Box2d::new(cu0, cv0, cu1 - cu0, cv1 - cv0).ok()?;
        Some((clipped, clipped.area() / full))
    }

    /// Bearing of the image's left and right edges from the camera axis, radians.
    pub fn half_fov(&self) -> f64 {
        (self.width / 2.0 / self.focal_px).atan()
    }
}

/// Whether the detector can see an object at all (in range, enough of it in the image),
/// and its ego-frame box.
pub fn observable(camera: &Camera, ego: &EgoState, object: &ObjectState) -> Option<(Box3d, Box2d, f64)> {
    let local = to_ego(ego, &object.bbox);
    if local.x.hypot(local.y) > object.class.max_range() {
        return None;
    }
    let (image, visibility) = camera.project(&local)?;
    (visibility >= 0.3 && image.h >= 6.0).then_some((local, image, visibility))
}

/// A 2D detection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection2d {
    /// Class.
    pub class: Class,
    /// Image box.
    pub bbox: Box2d,
    /// Score in [0, 1].
    pub score: f64,
}

/// A ground-truth image box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Object2d {
    /// Object id.
    pub id: u32,
    /// Class.
    pub class: Class,
    /// Image box (clipped).
    pub bbox: Box2d,
    /// Fraction of the box inside the image.
    pub visibility: f64,
}

/// The detector error model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetectorModel {
    /// Detection probability close by; it falls quadratically to `p_far` at the class's range.
    pub p_near: f64,
    /// Detection probability at the class's range.
    pub p_far: f64,
    /// Depth error σ = a + b · range (monocular depth grows worse with distance).
    pub depth_sigma: (f64, f64),
    /// Bearing error σ, radians.
    pub bearing_sigma: f64,
    /// Height-of-centre error σ, metres.
    pub z_sigma: f64,
    /// Relative size error σ.
    pub size_sigma: f64,
    /// Heading error σ, radians.
    pub yaw_sigma: f64,
    /// Probability that a heading comes out turned by π.
    pub yaw_flip: f64,
    /// Mean false positives per frame (3D and 2D each).
    pub false_positives: f64,
    /// Image-box edge error σ = a + b · box size, pixels.
    pub edge_sigma: (f64, f64),
    /// The covariance each detection reports is the error model's times this factor (1: a
    /// calibrated detector; a real one is off by a factor it does not know).
    pub covariance_factor: f64,
    /// Probability that a cone is reported as a drum (and back), a sign as an arrow board
    /// (and back).
    pub confusion: f64,
    /// Whether nearer objects hide farther ones: the detection probability is scaled by the
    /// fraction of the object's image box that no nearer object covers.
    pub occlusion: bool,
}

impl Default for DetectorModel {
    fn default() -> Self {
        DetectorModel {
            p_near: 0.95,
            p_far: 0.6,
            depth_sigma: (0.03, 0.015),
            bearing_sigma: 0.004,
            z_sigma: 0.05,
            size_sigma: 0.04,
            yaw_sigma: 0.05,
            yaw_flip: 0.1,
            false_positives: 0.4,
            edge_sigma: (1.0, 0.03),
            covariance_factor: 1.0,
            confusion: 0.0,
            occlusion: false,
        }
    }
}

/// How much of each image box nearer boxes cover (0: none, 1: all), for boxes given with
/// their ranges; the same order as the input.
pub fn occlusion(boxes: &[(Box2d, f64)]) -> Vec<f64> {
    boxes
        .iter()
        .map(|(b, range)| {
            let covered: f64 =
                boxes.iter().filter(|(_, other)| other < range).map(|(other, _)| intersection_area(b, other)).sum();
            (covered / b.area().max(1e-9)).min(1.0)
        })
        .collect()
}

fn intersection_area(a: &Box2d, b: &Box2d) -> f64 {
    let w = (a.right().min(b.right()) - a.x.max(b.x)).max(0.0);
    let h = (a.bottom().min(b.bottom()) - a.y.max(b.y)).max(0.0);
    w * h
}

impl DetectorModel {
    fn detected(&self, rng: &mut impl Rng, range: f64, max_range: f64, occluded: f64) -> bool {
        let u = (range / max_range).clamp(0.0, 1.0);
        let p = self.p_near - (self.p_near - self.p_far) * u * u;
        rng.random::<f64>() < p * (1.0 - occluded)
    }

    /// The covariance of a centre seen at `range` and `bearing` from the camera, in the
    /// camera's horizontal axes: depth error along the ray, bearing error across it (the
    /// error model's, not scaled by `covariance_factor`).
    pub fn position_covariance(&self, range: f64, bearing: f64) -> [f64; 3] {
        let along = self.depth_sigma.0 + self.depth_sigma.1 * range;
        let across = (range * self.bearing_sigma).max(0.01);
        rotate_covariance([along * along, 0.0, across * across], bearing)
    }

    /// The covariance the detector reports for such a centre.
    fn reported_covariance(&self, range: f64, bearing: f64) -> [f64; 3] {
        let c = self.position_covariance(range, bearing);
        if self.covariance_factor == 1.0 {
            c
        } else {
            c.map(|v| v * self.covariance_factor)
        }
    }

    fn score(&self, rng: &mut impl Rng, range: f64, max_range: f64) -> f64 {
        (0.95 - 0.4 * range / max_range + gauss(rng, 0.05)).clamp(0.05, 1.0)
    }

    fn reported_class(&self, rng: &mut impl Rng, class: Class) -> Class {
        let other = match class {
            Class::Cone => Class::Drum,
            Class::Drum => Class::Cone,
            Class::Sign => Class::ArrowBoard,
            Class::ArrowBoard => Class::Sign,
            _ => return class,
        };
        if self.confusion > 0.0 && rng.random::<f64>() < self.confusion {
            other
        } else {
            class
        }
    }

    /// A noisy box of an object seen by the real camera, or `None` when it is missed
    /// (`occluded`: the fraction of its image box nearer objects cover). The detector
    /// measures in the real camera's frame; the box is returned in the ego frame as the
    /// device puts it, through the nominal mount, so a mount error shows as it would.
    pub fn detect_3d(
        &self,
        rng: &mut impl Rng,
        camera: &Camera,
        class: Class,
        truth: &Box3d,
        occluded: f64,
    ) -> Option<Detection3d> {
        let mount = camera.true_mount_transform();
        let centre = camera.ego_to_camera(&mount, Vector3::new(truth.x, truth.y, truth.z));
        let (cx, cy) = (centre.x, centre.y);
        let range = cx.hypot(cy);
        if !self.detected(rng, range, class.max_range(), occluded) {
            return None;
        }
        let depth = range + gauss(rng, self.depth_sigma.0 + self.depth_sigma.1 * range);
        let bearing = cy.atan2(cx) + gauss(rng, self.bearing_sigma);
        let mut size = [truth.l, truth.w, truth.h];
        for v in &mut size {
            *v *= 1.0 + gauss(rng, self.size_sigma);
        }
        let yaw = if class.has_heading() {
            let flip = if rng.random::<f64>() < self.yaw_flip { PI } else { 0.0 };
            wrap(truth.yaw - camera.mount_error.yaw + gauss(rng, self.yaw_sigma) + flip)
        } else {
            rng.random_range(-PI..PI)
        };
        // On the nominal mount the height comes straight from the ego frame (bit for bit the
        // ideal profile's of before mount errors); otherwise through the real camera.
        let z = if camera.mount_error == MountError::default() {
            truth.z + gauss(rng, self.z_sigma)
        } else {
            camera.mount_height + centre.z + gauss(rng, self.z_sigma)
        };
        let bbox = Box3d {
            x: camera.mount_forward + depth * bearing.cos(),
            y: depth * bearing.sin(),
            z,
            yaw,
            l: size[0],
            w: size[1],
            h: size[2],
        };
        let score = self.score(rng, range, class.max_range());
        let class = self.reported_class(rng, class);
        Some(Detection3d {
            class: class as u16,
            bbox,
            score,
            position_covariance: Some(self.reported_covariance(depth.max(0.0), bearing)),
        })
    }

    /// A noisy image box of a seen object, or `None` when it is missed.
    pub fn detect_2d(
        &self,
        rng: &mut impl Rng,
        camera: &Camera,
        class: Class,
        range: f64,
        truth: &Box2d,
        occluded: f64,
    ) -> Option<Detection2d> {
        if !self.detected(rng, range, class.max_range(), occluded) {
            return None;
        }
        let sigma = |size: f64| self.edge_sigma.0 + self.edge_sigma.1 * size;
        let left = truth.x + gauss(rng, sigma(truth.w));
        let right = truth.right() + gauss(rng, sigma(truth.w));
        let top = truth.y + gauss(rng, sigma(truth.h));
        let bottom = truth.bottom() + gauss(rng, sigma(truth.h));
        let (left, right) = (left.clamp(0.0, camera.width), right.clamp(0.0, camera.width));
        let (top, bottom) = (top.clamp(0.0, camera.height), bottom.clamp(0.0, camera.height));
        let bbox = Box2d::new(left, top, right - left, bottom - top).ok()?;
        let score = self.score(rng, range, class.max_range());
        Some(Detection2d { class: self.reported_class(rng, class), bbox, score })
    }

    fn false_positive_count(&self, rng: &mut impl Rng) -> u64 {
        Poisson::new(self.false_positives).map_or(0, |p| p.sample(rng) as u64)
    }

    /// Ghost detections in the field of view: cones and drums on the ground, sometimes a car.
    pub fn false_positives_3d(&self, rng: &mut impl Rng, camera: &Camera) -> Vec<Detection3d> {
        (0..self.false_positive_count(rng))
            .map(|_| {
                let class = match rng.random_range(0..10) {
                    0 => Class::Car,
                    1..=5 => Class::Cone,
                    _ => Class::Drum,
                };
                let range = rng.random_range(8.0..40.0);
                let bearing = rng.random_range(-0.8..0.8) * camera.half_fov();
                let [l, w, h] = class.size().map(|v| v * (1.0 + gauss(rng, self.size_sigma)));
                let bbox = Box3d {
                    x: camera.mount_forward + range * f64::cos(bearing),
                    y: range * f64::sin(bearing),
                    z: h / 2.0,
                    yaw: rng.random_range(-PI..PI),
                    l,
                    w,
                    h,
                };
                Detection3d {
                    class: class as u16,
                    bbox,
                    score: rng.random_range(0.1..0.5),
                    position_covariance: Some(self.reported_covariance(range, bearing)),
                }
            })
            .collect()
    }

    /// Ghost image boxes.
    pub fn false_positives_2d(&self, rng: &mut impl Rng, camera: &Camera) -> Vec<Detection2d> {
        (0..self.false_positive_count(rng))
            .filter_map(|_| {
                let (w, h) = (rng.random_range(12.0..60.0), rng.random_range(20.0..90.0));
                let x = rng.random_range(0.0..camera.width - w);
                let y = rng.random_range(camera.height / 3.0..camera.height - h);
                let bbox = Box2d::new(x, y, w, h).ok()?;
                Some(Detection2d { class: Class::Cone, bbox, score: rng.random_range(0.1..0.5) })
            })
            .collect()
    }
}

/// One GNSS fix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssSample {
    /// Time of the fix, seconds from the start.
    pub t_fix: f64,
    /// Time it reached the logger (fix time + receiver latency).
    pub t_receive: f64,
    /// Measured position (east, north, up), metres.
    pub enu: [f64; 3],
    /// Horizontal error σ in force at this fix, metres (the truth).
    pub sigma: f64,
    /// The horizontal σ the receiver reports (as HDOP × 2.5 m): the truth times the
    /// receiver's own misjudgement.
    pub reported_sigma: f64,
    /// Whether a multipath jump corrupts it.
    pub multipath: bool,
    /// Measured ground speed, m/s.
    pub speed: f64,
    /// Course over ground, degrees clockwise from north.
    pub course_deg: f64,
}

/// The GNSS error model: a Gauss–Markov horizontal error whose σ wanders between
/// `sigma_range`, occasional multipath jumps and outages, and an accuracy the receiver
/// reports only roughly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GnssModel {
    /// Smallest and largest σ, metres.
    pub sigma_range: (f64, f64),
    /// Correlation time of the error, seconds.
    pub correlation_s: f64,
    /// Receiver latency, seconds.
    pub latency_s: f64,
    /// Probability per fix that a multipath episode starts.
    pub multipath_rate: f64,
    /// Size of a multipath jump, metres (uniform in this range).
    pub multipath_jump: (f64, f64),
    /// Duration of an episode, seconds (uniform).
    pub multipath_duration: (f64, f64),
    /// The reported σ is the true σ times this factor (1: a receiver that knows its error).
    pub reported_sigma_factor: f64,
    /// σ of the log of the reported σ's fix-to-fix jitter (0: none).
    pub reported_jitter: f64,
    /// Mean outages per minute (0: none); no fix is reported during one.
    pub outages_per_min: f64,
    /// Length of an outage, seconds (uniform).
    pub outage_s: (f64, f64),
}

impl Default for GnssModel {
    fn default() -> Self {
        GnssModel {
            sigma_range: (3.0, 10.0),
            correlation_s: 15.0,
            latency_s: 0.08,
            multipath_rate: 0.015,
            multipath_jump: (15.0, 40.0),
            multipath_duration: (1.0, 3.0),
            reported_sigma_factor: 1.0,
            reported_jitter: 0.0,
            outages_per_min: 0.0,
            outage_s: (5.0, 30.0),
        }
    }
}

impl GnssModel {
    /// A good receiver: σ 1–2 m, errors correlated over 2 s, no multipath.
    pub fn good() -> Self {
        GnssModel { sigma_range: (1.0, 2.0), correlation_s: 2.0, multipath_rate: 0.0, ..GnssModel::default() }
    }

    /// Fixes at the given ego states (in time order); none inside an outage.
    pub fn fixes(&self, rng: &mut impl Rng, truth: &[EgoState]) -> Vec<GnssSample> {
        let (lo, hi) = self.sigma_range;
        let phase = rng.random_range(0.0..2.0 * PI);
        let mut error = [0.0f64; 3];
        let mut previous_t: Option<f64> = None;
        let mut episode: Option<(f64, [f64; 2])> = None; // (end time, offset)
        let mut outage_until: Option<f64> = None;
        let mut out = Vec::with_capacity(truth.len());
        for ego in truth {
            let sigma = lo + (hi - lo) * 0.5 * (1.0 + (2.0 * PI * ego.t / 50.0 + phase).sin());
            let dt = previous_t.map_or(0.0, |p| ego.t - p);
            let phi = previous_t.map_or(0.0, |p| (-(ego.t - p) / self.correlation_s).exp());
            let fresh = (1.0 - phi * phi).sqrt();
            // σ per horizontal axis is σ/√2 so that the horizontal RMS is σ.
            for (axis, e) in error.iter_mut().enumerate() {
                let axis_sigma = if axis == 2 { 1.5 * sigma } else { sigma / 2f64.sqrt() };
                *e = phi * *e + fresh * gauss(rng, axis_sigma);
            }
            previous_t = Some(ego.t);
            if episode.is_some_and(|(end, _)| ego.t >= end) {
                episode = None;
            }
            if episode.is_none() && rng.random::<f64>() < self.multipath_rate {
                let size = rng.random_range(self.multipath_jump.0..self.multipath_jump.1);
                let direction = rng.random_range(0.0..2.0 * PI);
                let end = ego.t + rng.random_range(self.multipath_duration.0..self.multipath_duration.1);
                episode = Some((end, [size * direction.cos(), size * direction.sin()]));
            }
            let jump = episode.map_or([0.0; 2], |(_, o)| o);
            let speed = (ego.speed + gauss(rng, 0.1)).max(0.0);
            let course_deg = (90.0 - ego.heading.to_degrees() + gauss(rng, 0.5)).rem_euclid(360.0);
            let mut reported_sigma = sigma * self.reported_sigma_factor;
            if self.reported_jitter > 0.0 {
                reported_sigma *= gauss(rng, self.reported_jitter).exp();
            }
            if self.outages_per_min > 0.0 {
                if outage_until.is_some_and(|until| ego.t >= until) {
                    outage_until = None;
                }
                if outage_until.is_none() && rng.random::<f64>() < self.outages_per_min * dt / 60.0 {
                    let (a, b) = self.outage_s;
                    outage_until = Some(ego.t + rng.random_range(a..b));
                }
                if outage_until.is_some() {
                    continue;
                }
            }
            out.push(GnssSample {
                t_fix: ego.t,
                t_receive: ego.t + self.latency_s,
                enu: [ego.x + error[0] + jump[0], ego.y + error[1] + jump[1], error[2]],
                sigma,
                reported_sigma,
                multipath: episode.is_some(),
                speed,
                course_deg,
            });
        }
        out
    }
}

/// The wheel-speed signal on the vehicle bus.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WheelModel {
    /// Reported / true speed (the tyres' rolling radius against the nominal one).
    pub scale: f64,
    /// Noise σ, m/s.
    pub sigma: f64,
    /// How late each sample is: it reports the speed this long before its stamp, s.
    pub latency_s: f64,
}

impl Default for WheelModel {
    fn default() -> Self {
        WheelModel { scale: 0.99, sigma: 0.03, latency_s: 0.0 }
    }
}

/// Wheel speed as the vehicle bus reports it: a tyre-radius scale bias, latency, noise, and
/// the 0.01 km/h resolution of a typical CAN signal. Returns (t, m/s).
pub fn wheel_speed(rng: &mut impl Rng, truth: &[EgoState], model: &WheelModel) -> Vec<(f64, f64)> {
    truth
        .iter()
        .map(|ego| {
            let speed = if model.latency_s > 0.0 { speed_at(truth, ego.t - model.latency_s) } else { ego.speed };
            let kmh = ((speed * model.scale + gauss(rng, model.sigma)).max(0.0) * 3.6 * 100.0).round() / 100.0;
            (ego.t, kmh / 3.6)
        })
        .collect()
}

/// The true speed at `t`, linear between the states (the first one before them).
fn speed_at(truth: &[EgoState], t: f64) -> f64 {
    let k = truth.partition_point(|e| e.t <= t);
    match (k.checked_sub(1).and_then(|i| truth.get(i)), truth.get(k)) {
        (Some(a), Some(b)) if b.t > a.t => a.speed + (b.speed - a.speed) * (t - a.t) / (b.t - a.t),
        (Some(a), _) => a.speed,
        (None, Some(b)) => b.speed,
        (None, None) => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ego() -> EgoState {
        EgoState { t: 0.0, s: 0.0, d: 0.0, x: 10.0, y: 5.0, heading: PI / 2.0, speed: 10.0 }
    }

    #[test]
    fn ego_frame_round_trip() {
        let b = Box3d { x: 12.0, y: 25.0, z: 0.5, yaw: 0.3, l: 1.0, w: 1.0, h: 1.0 };
        let local = to_ego(&ego(), &b);
        // Heading north: 20 m ahead, 2 m to the right.
        assert!((local.x - 20.0).abs() < 1e-12 && (local.y + 2.0).abs() < 1e-12, "{local:?}");
        let back = to_world(&ego(), &local);
        assert!((back.x - b.x).abs() < 1e-12 && (back.y - b.y).abs() < 1e-12 && (back.yaw - b.yaw).abs() < 1e-12);
    }

    #[test]
    fn covariance_turns_with_the_ray() {
        // 1 m² along x turned by 90° lies along y.
        let c = rotate_covariance([1.0, 0.0, 0.01], PI / 2.0);
        assert!((c[0] - 0.01).abs() < 1e-12 && c[1].abs() < 1e-12 && (c[2] - 1.0).abs() < 1e-12, "{c:?}");
        // At 45° the two axes share it.
        let c = rotate_covariance([1.0, 0.0, 0.0], PI / 4.0);
        assert!((c[0] - 0.5).abs() < 1e-12 && (c[1] - 0.5).abs() < 1e-12 && (c[2] - 0.5).abs() < 1e-12, "{c:?}");
    }

    #[test]
    fn a_box_straight_ahead_projects_to_the_image_centre_column() {
        let camera = Camera::default();
        let b = Box3d { x: 21.8, y: 0.0, z: 1.3, yaw: 0.0, l: 0.0, w: 2.0, h: 2.0 };
        let (image, visibility) = camera.project(&b).expect("visible");
        // 20 m from the camera, 2 m wide: 100 px, centred.
        assert!((image.x - 590.0).abs() < 1e-9 && (image.w - 100.0).abs() < 1e-9 && (image.h - 100.0).abs() < 1e-9);
        assert_eq!(visibility, 1.0);
        assert!(camera.project(&Box3d { x: 1.0, ..b }).is_none(), "behind the camera");
        let (_, half) = camera.project(&Box3d { y: 6.4 * 2.0, ..b }).expect("on the edge");
        assert!((half - 0.5).abs() < 1e-9, "{half}");
    }
}
