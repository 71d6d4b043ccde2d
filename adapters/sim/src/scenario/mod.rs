//! Deterministic work-zone drives: the ground truth the trackers, the anchoring, the demo
//! and the benchmarks are judged against.
//!
//! A scenario is a two-lane-each-way road (a straight, a 38° left bend of radius 300 m,
//! a long straight) whose right lane is closed by a work zone: signs ahead on the shoulder, drums
//! along a 50 m taper, an arrow board and barricades in the closed lane, cones along the
//! closure and the end taper. The ego cruises, brakes to the zone speed, changes into the
//! open lane before the taper, passes the closure and changes back; other vehicles follow
//! the road (one truck merges ahead of the taper; oncoming traffic passes). Every random
//! choice comes from one seed (ChaCha8, one stream per sensor), so a seed names a scenario.
//!
//! Sensor streams: frames at 10 Hz with 3D detections in the ego frame and 2D detections
//! in the image ([`sensors::DetectorModel`]), gravity-aligned VO with unknown, wandering
//! scale and heading, re-initialised now and then ([`vo::VoModel`]), GNSS at 5 Hz
//! ([`sensors::GnssModel`]), wheel speed at 50 Hz ([`sensors::WheelModel`]), a MEMS IMU at
//! 100–104 Hz in the camera's housing ([`imu::ImuModel`]). How far each is from ideal is the
//! drive's sensor profile ([`profile::Profile`]).

pub mod actors;
pub mod command;
pub mod corpus;
pub mod evaluate;
pub mod imu;
pub mod judge;
pub mod profile;
#[cfg(feature = "bridge")]
pub mod publish;
pub mod road;
pub mod sensors;
pub mod street;
pub mod vo;
pub mod write;

use dash2sim_core::track3d::{ClassConfig, Config3d, Detection3d};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use actors::{lay_out_work_zone, Class, EgoPlan, EgoState, ObjectState, Swerve, Tailgate, Vehicle, WorkZone, ZonePlan};
use dash2sim_linux::trajectory::Trajectory;
use profile::{Profile, Receiver, StreetAnchorModel};
use road::{Road, RoadPose, Segment};
use sensors::{observable, Camera, Detection2d, DetectorModel, GnssModel, GnssSample, Object2d, WheelModel};
use vo::{VoModel, VoTrack};

/// A zero-mean Gaussian sample with standard deviation `sigma`.
pub(crate) fn gauss(rng: &mut impl Rng, sigma: f64) -> f64 {
    let z: f64 = StandardNormal.sample(rng);
    sigma * z
}

/// Everything that shapes a scenario.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScenarioConfig {
    /// The seed every random choice derives from.
    pub seed: u64,
    /// Length of the drive, seconds.
    pub duration_s: f64,
    /// Camera frame rate, Hz.
    pub frame_rate_hz: f64,
    /// GNSS fixes per second (a divisor of the frame rate).
    pub gnss_rate_hz: f64,
    /// Wheel-speed samples per second.
    pub speed_rate_hz: f64,
    /// Geodetic origin of the local ENU frame: latitude, longitude (degrees), height (m).
    pub origin: [f64; 3],
    /// The camera.
    pub camera: Camera,
    /// The object detector's errors.
    pub detector: DetectorModel,
    /// The GNSS receiver's errors.
    pub gnss: GnssModel,
    /// How VO sees the motion.
    pub vo: VoModel,
    /// The wheel-speed signal.
    pub wheel: WheelModel,
    /// Street-imagery anchors, when finishing is given them.
    pub anchors: StreetAnchorModel,
    /// The inertial sensor in the camera's housing.
    pub imu: imu::ImuModel,
    /// How the ego is driven through the work zone.
    pub driver: Driver,
    /// The sensor profile the models above were drawn from (a label: generation reads the
    /// models).
    pub profile: Profile,
    /// The receiver the GNSS model above belongs to (a label, as `profile`).
    pub receiver: Receiver,
}

/// How the ego is driven: carefully, or badly in one of the ways a verifier must catch.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Driver {
    /// Changes into the open lane well before the taper (the drives of the Dash2Sim
    /// corpus: "the driver completed each route without any incidents").
    #[default]
    Careful,
    /// Changes lanes only once the taper has begun and clips its drums.
    Careless,
    /// Drifts off the carriageway onto the shoulder before the work zone.
    Shoulder,
    /// Swerves across the divider into the oncoming lane and back.
    Oncoming,
    /// Keeps the careful driver's pace on a road signed 60 km/h.
    Speeding,
    /// Closes on a slower vehicle ahead and brakes only at the last moment, stopping a
    /// metre behind it (time to collision below nuPlan's 0.95 s, without contact).
    Tailgating,
    /// Brakes for the zone at 5.5 m/s² and pulls away at 3.5 m/s².
    Harsh,
    /// Careful, on the edge: passes the closure's drums and cones 0.1–0.3 m clear and
    /// brakes at 3 m/s² (its jerk limited); every metric holds.
    KnifeEdge,
}

/// What the truth of a drive must score: the nuPlan metric a bad driver fails.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Expectation {
    /// Every metric holds and the drive verifies.
    Verifies,
    /// This metric (nuPlan's name) is below 1 and the drive is rejected.
    Fails(&'static str),
}

impl Driver {
    /// Every driver, careful first.
    pub const ALL: [Driver; 8] = [
        Driver::Careful,
        Driver::Careless,
        Driver::Shoulder,
        Driver::Oncoming,
        Driver::Speeding,
        Driver::Tailgating,
        Driver::Harsh,
        Driver::KnifeEdge,
    ];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Driver::Careful => "careful",
            Driver::Careless => "careless",
            Driver::Shoulder => "shoulder",
            Driver::Oncoming => "oncoming",
            Driver::Speeding => "speeding",
            Driver::Tailgating => "tailgating",
            Driver::Harsh => "harsh",
            Driver::KnifeEdge => "knife-edge",
        }
    }

    /// The driver named `name` ([`Driver::name`]).
    pub fn from_name(name: &str) -> Option<Driver> {
        Driver::ALL.into_iter().find(|d| d.name() == name)
    }

    /// What the drive's truth must score.
    pub fn expectation(self) -> Expectation {
        match self {
            Driver::Careful | Driver::KnifeEdge => Expectation::Verifies,
            Driver::Careless => Expectation::Fails("no_at_fault_collisions"),
            Driver::Shoulder => Expectation::Fails("drivable_area_compliance"),
            Driver::Oncoming => Expectation::Fails("driving_direction_compliance"),
            Driver::Speeding => Expectation::Fails("speed_limit_compliance"),
            Driver::Tailgating => Expectation::Fails("time_to_collision_within_bound"),
            Driver::Harsh => Expectation::Fails("ego_is_comfortable"),
        }
    }

    /// Whether its drives should verify.
    pub fn is_careful(self) -> bool {
        self.expectation() == Expectation::Verifies
    }
}

/// A driver is written by its name ([`Driver::name`]), as a summary names it.
impl serde::Serialize for Driver {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

/// Which drivers a command drives each seed with: `careful`, `careless`, any other kind,
/// `both` (careful and careless) or `all` ([`Driver::ALL`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Drivers {
    /// One kind.
    One(Driver),
    /// Careful and careless.
    Both,
    /// Every kind.
    All,
}

impl Drivers {
    /// The drivers, careful first.
    pub fn list(self) -> &'static [Driver] {
        match self {
            Drivers::One(d) => Driver::ALL.iter().position(|k| *k == d).map_or(&[], |k| &Driver::ALL[k..=k]),
            Drivers::Both => &Driver::ALL[..2],
            Drivers::All => &Driver::ALL,
        }
    }

    /// `KIND`, `both` or `all` ([`Driver::name`]).
    pub fn parse(text: &str) -> Result<Self, String> {
        match text {
            "both" => Ok(Drivers::Both),
            "all" => Ok(Drivers::All),
            _ => Driver::from_name(text).map(Drivers::One).ok_or_else(|| {
                let kinds: Vec<&str> = Driver::ALL.iter().map(|d| d.name()).collect();
                format!("`{text}` is not a driver: give one of {}, both or all", kinds.join(", "))
            }),
        }
    }
}

impl Default for ScenarioConfig {
    /// Seed 1, 40 s, the ideal profile with a phone-grade receiver: the generator as it was
    /// before sensor profiles. [`ScenarioConfig::drive`] makes the other profiles.
    fn default() -> Self {
        ScenarioConfig {
            seed: 1,
            duration_s: 40.0,
            frame_rate_hz: 10.0,
            gnss_rate_hz: 5.0,
            speed_rate_hz: 50.0,
            // A ring road north of Helsinki; the road itself is synthetic.
            origin: [60.2711, 24.8572, 20.0],
            camera: Camera::default(),
            detector: DetectorModel::default(),
            gnss: GnssModel::default(),
            vo: VoModel { translation_noise: 0.01, ..VoModel::gravity_aligned() },
            wheel: WheelModel::default(),
            anchors: StreetAnchorModel::default(),
            imu: imu::ImuModel::ideal(),
            driver: Driver::Careful,
            profile: Profile::Ideal,
            receiver: Receiver::Phone,
        }
    }
}

/// One camera frame: the truth and what the detectors reported.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Frame number, from 1 (MOTChallenge convention).
    pub index: u32,
    /// The ego vehicle.
    pub ego: EgoState,
    /// Every object on the road, world frame.
    pub objects: Vec<ObjectState>,
    /// Ids of the objects the detector could see (in range, ≥ 30 % in the image).
    pub visible: Vec<u32>,
    /// 3D detections in the ego frame (x forward, y left, z up) as the device places them:
    /// measured by the real camera, moved through the nominal mount (so a mount error shows);
    /// misses and ghosts included.
    pub detections_3d: Vec<Detection3d>,
    /// 2D detections in the image.
    pub detections_2d: Vec<Detection2d>,
    /// True image boxes of the visible objects.
    pub objects_2d: Vec<Object2d>,
}

impl Frame {
    /// The ground truth of object `id` in this frame.
    pub fn object(&self, id: u32) -> Option<&ObjectState> {
        self.objects.iter().find(|o| o.id == id)
    }
}

/// A generated drive.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// What it was generated from.
    pub config: ScenarioConfig,
    /// The road.
    pub road: Road,
    /// Where the work zones are: one per section of the road, in order.
    pub zones: Vec<WorkZone>,
    /// Camera frames.
    pub frames: Vec<Frame>,
    /// VO poses of the camera (unknown scale, drifting; none while tracking is lost) and
    /// the truth behind each.
    pub vo: VoTrack,
    /// GNSS fixes.
    pub gnss: Vec<GnssSample>,
    /// Wheel speed, (t, m/s).
    pub speed: Vec<(f64, f64)>,
    /// The IMU's samples, (device time s, sample on the sensor's axes).
    pub imu: Vec<(f64, dash2sim_core::imu::ImuSample)>,
}

/// Independent random streams, so that changing one sensor model leaves the others' draws alone.
#[derive(Clone, Copy, Debug)]
enum Stream {
    Layout = 1,
    Detector = 2,
    Gnss = 3,
    Wheel = 4,
    Vo = 5,
    // 6 is the profile's per-drive draws (`profile::PROFILE_STREAM`).
    Imu = 7,
    Driver = 8,
}

fn rng(seed: u64, stream: Stream) -> ChaCha8Rng {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream as u64);
    rng
}

/// The tracker settings for these classes: the core's work-zone profile
/// ([`dash2sim_core::pipeline::profile::work_zone_classes`]).
pub fn tracker_classes() -> [ClassConfig; 7] {
    dash2sim_core::pipeline::profile::work_zone_classes()
}

/// The tracker settings used on these scenarios: the core's work-zone profile — AB3DMOT's
/// min_hits 3, max_age 4 frames (AB3DMOT: 2; docs/tracking.md has both), ground at z = 0,
/// static below 0.3 m/frame (3 m/s).
pub fn tracker_config(classes: &[ClassConfig]) -> Config3d<'_> {
    dash2sim_core::pipeline::profile::work_zone_tracker(classes)
}

/// Length of one section of the road: a straight, a bend, a long straight with a work zone.
pub const SECTION_M: f64 = 1150.0;

/// Where the ego starts, s.
const EGO_S0: f64 = 20.0;

/// Objects of a section after the first are in a frame while the ego is this close to the
/// section (so that a long drive's truth stays a few sections' worth of objects a frame).
const SECTION_VIEW_M: f64 = 300.0;

/// Sections a drive of `duration_s` seconds needs (the ego cruises at 22 m/s at most).
pub fn sections_for(duration_s: f64) -> usize {
    ((EGO_S0 + 22.0 * duration_s) / SECTION_M).ceil().max(1.0) as usize
}

/// The road's speed limit, m/s: 80 km/h.
const SPEED_LIMIT: f64 = 80.0 / 3.6;
/// The speeding driver's road is signed 60 km/h; it keeps the careful pace.
const SPEEDING_LIMIT: f64 = 60.0 / 3.6;

/// The road of `sections` sections: each a 150 m straight, a 38° bend of radius 300 m (200 m;
/// left, then right, in turn) and an 800 m straight.
fn road(sections: usize, heading: f64, speed_limit: f64) -> Road {
    let segments = (0..sections)
        .flat_map(|k| {
            let curvature = if k % 2 == 0 { 1.0 / 300.0 } else { -1.0 / 300.0 };
            [Segment::Straight(150.0), Segment::Arc(200.0, curvature), Segment::Straight(800.0)]
        })
        .collect();
    Road {
        segments,
        start: RoadPose { x: 0.0, y: 0.0, heading, curvature: 0.0 },
        lane_width: 3.5,
        lanes_forward: 2,
        lanes_backward: 2,
        speed_limit,
    }
}

/// Section `k`'s work zone: its taper 400 m into the section, ±15 m.
fn zone_of(section: usize, layout: &mut ChaCha8Rng) -> WorkZone {
    WorkZone {
        taper_start: section as f64 * SECTION_M + 400.0 + layout.random_range(-15.0..15.0),
        taper_length: 50.0,
        closure_length: 120.0,
        end_taper_length: 20.0,
    }
}

/// What the ego does at `zone`.
fn zone_plan(zone: &WorkZone, driver: Driver) -> ZonePlan {
    ZonePlan {
        changes: [
            match driver {
                Driver::Careless => (zone.taper_start - 5.0, zone.taper_start + 35.0),
                _ => (zone.taper_start - 130.0, zone.taper_start - 70.0),
            },
            (zone.end() + 30.0, zone.end() + 100.0),
        ],
        slow: (zone.taper_start - 100.0, zone.end() + 10.0),
    }
}

/// How `driver` drives a road with these zones.
fn ego_plan(road: &Road, zones: &[WorkZone], driver: Driver) -> EgoPlan {
    let careful = EgoPlan {
        s0: EGO_S0,
        cruise_speed: 22.0,
        zone_speed: 15.0,
        max_accel: 1.5,
        max_brake: 1.5,
        max_jerk: None,
        lanes: (road.forward_lane(1), road.forward_lane(0)),
        zones: zones.iter().map(|z| zone_plan(z, driver)).collect(),
        swerve: None,
        tailgate: None,
    };
    let closed = road.forward_lane(0);
    match driver {
        Driver::Careful | Driver::Careless | Driver::Speeding | Driver::Tailgating => careful,
        // Two metres right of the outer lane: the right-hand corners well over the edge,
        // ahead of the first sign.
        Driver::Shoulder => EgoPlan {
            swerve: Some(Swerve {
                out: (EGO_S0 + 20.0, EGO_S0 + 70.0),
                back: (EGO_S0 + 110.0, EGO_S0 + 160.0),
                offset: -2.0,
            }),
            ..careful
        },
        // Across both forward lanes into the oncoming lane by the divider, ahead of the
        // oncoming traffic, and back.
        Driver::Oncoming => EgoPlan {
            swerve: Some(Swerve {
                out: (EGO_S0 + 10.0, EGO_S0 + 90.0),
                back: (EGO_S0 + 130.0, EGO_S0 + 210.0),
                offset: road.backward_lane(1) - closed,
            }),
            ..careful
        },
        Driver::Harsh => EgoPlan { max_accel: 3.5, max_brake: 5.5, ..careful },
        Driver::KnifeEdge => EgoPlan { max_brake: 3.0, max_jerk: Some(2.0), ..careful },
    }
}

/// The farthest any object of `zone`'s closure reaches towards the open lane: the largest
/// lateral offset (d) of a box's edge among `statics` from the taper to the end of the
/// closure. The zone lies on a straight, so d is the box's distance across the road.
fn closure_reach(road: &Road, zone: &WorkZone, statics: &[ObjectState]) -> f64 {
    let start = road.pose(zone.taper_start);
    let (sin, cos) = start.heading.sin_cos();
    statics
        .iter()
        .filter_map(|o| {
            let (dx, dy) = (o.bbox.x - start.x, o.bbox.y - start.y);
            let along = dx * cos + dy * sin;
            (-1.0..=zone.closure_end() - zone.taper_start).contains(&along).then(|| {
                let turn = o.bbox.yaw - start.heading;
                let half = (o.bbox.l / 2.0 * turn.sin()).abs() + (o.bbox.w / 2.0 * turn.cos()).abs();
                -dx * sin + dy * cos + half
            })
        })
        .fold(f64::NEG_INFINITY, f64::max)
}

/// The slower car the tailgating driver closes on: 30 m ahead of it in its lane when it
/// reaches the section's start (time `arrival`), at 17 m/s, changing into the open lane as the
/// ego does. No random draws: the other drivers' drives stay as they were.
fn slow_lead(
    road: &Road,
    zone: &WorkZone,
    offset: f64,
    arrival: f64,
    s_range: (f64, f64),
    next_id: &mut u32,
) -> Vehicle {
    let speed = 17.0;
    let change = (zone.taper_start - 130.0, zone.taper_start - 70.0, road.forward_lane(1));
    let lead = Vehicle {
        id: *next_id,
        class: Class::Car,
        s0: EGO_S0 + 30.0 + offset - speed * arrival,
        speed,
        d: road.forward_lane(0),
        lane_change: Some(change),
        s_range,
    };
    *next_id += 1;
    lead
}

/// The traffic of a section whose zone is `zone`, the ego reaching the section's start at
/// time `arrival` (0 for the first): the same traffic in the same places around the ego as
/// the first section's at the start; for the tailgating `driver`, last, the slower car it
/// closes on ([`slow_lead`]). Every vehicle stays within `s_range`.
#[allow(clippy::too_many_arguments)] // a section's place, time, range and driver, and the draws
fn traffic(
    road: &Road,
    zone: &WorkZone,
    offset: f64,
    arrival: f64,
    s_range: (f64, f64),
    driver: Driver,
    layout: &mut ChaCha8Rng,
    next_id: &mut u32,
) -> Vec<Vehicle> {
    let (open, closed) = (road.forward_lane(1), road.forward_lane(0));
    let mut vehicles = Vec::new();
    let mut vehicle = |class, s0: f64, speed: f64, d, lane_change, layout: &mut ChaCha8Rng| {
        let jitter_s = layout.random_range(-8.0..8.0);
        let jitter_v = layout.random_range(-0.8..0.8);
        let speed: f64 = speed + jitter_v;
        let s0 = s0 + jitter_s + offset - speed * arrival;
        vehicles.push(Vehicle { id: *next_id, class, s0, speed, d, lane_change, s_range });
        *next_id += 1;
    };
    vehicle(Class::Car, EGO_S0 + 50.0, 20.5, open, None, layout);
    let merge = Some((zone.taper_start - 90.0, zone.taper_start - 40.0, open));
    vehicle(Class::Truck, EGO_S0 + 150.0, 16.0, closed, merge, layout);
    vehicle(Class::Car, 420.0, 19.0, open, None, layout);
    for (k, (class, s0, speed)) in [
        (Class::Car, 300.0, -19.0),
        (Class::Car, 520.0, -21.0),
        (Class::Truck, 650.0, -17.0),
        (Class::Car, 760.0, -20.0),
        (Class::Car, 900.0, -22.0),
    ]
    .into_iter()
    .enumerate()
    {
        let d = road.backward_lane(if k % 2 == 0 { 0 } else { 1 });
        vehicle(class, s0, speed, d, None, layout);
    }
    if driver == Driver::Tailgating {
        vehicles.push(slow_lead(road, zone, offset, arrival, s_range, next_id));
    }
    vehicles
}

/// Generate the scenario named by `config`.
///
/// The road has as many sections as the drive needs ([`sections_for`]); a drive of up to
/// 50 s has one, as it always had. The first section's layout and traffic are drawn first, so
/// a longer drive starts as a shorter one of the same seed does.
pub fn generate(config: &ScenarioConfig) -> Scenario {
    let driver = config.driver;
    let mut layout = rng(config.seed, Stream::Layout);
    let sections = sections_for(config.duration_s);
    let speed_limit = if driver == Driver::Speeding { SPEEDING_LIMIT } else { SPEED_LIMIT };
    let road = road(sections, layout.random_range(-3.1..3.1), speed_limit);
    let mut zones = vec![zone_of(0, &mut layout)];
    let mut next_id = 1;
    // Each section's statics and traffic, with the s-range in which the ego sees them.
    let mut objects_by_section: Vec<(Vec<ObjectState>, Vec<Vehicle>)> = Vec::new();
    let statics = lay_out_work_zone(&road, &zones[0], &mut layout, &mut next_id);
    let first_range = (f64::NEG_INFINITY, SECTION_M + 200.0);
    let vehicles = traffic(&road, &zones[0], 0.0, 0.0, first_range, driver, &mut layout, &mut next_id);
    objects_by_section.push((statics, vehicles));
    for k in 1..sections {
        zones.push(zone_of(k, &mut layout));
    }
    let mut plan = ego_plan(&road, &zones, driver);
    if sections > 1 {
        // When the ego reaches each section's start (its traffic is placed around it then).
        let path = plan.drive(&road, config.duration_s, 10.0);
        for (k, zone) in zones.iter().enumerate().skip(1) {
            let start = k as f64 * SECTION_M;
            let statics = lay_out_work_zone(&road, zone, &mut layout, &mut next_id);
            let arrival = path.iter().find(|e| e.s >= EGO_S0 + start).map(|e| e.t);
            let vehicles = match arrival {
                Some(t) => {
                    let range = (start - 200.0, start + SECTION_M + 200.0);
                    traffic(&road, zone, start, t, range, driver, &mut layout, &mut next_id)
                }
                None => Vec::new(),
            };
            objects_by_section.push((statics, vehicles));
        }
    }
    match driver {
        Driver::Tailgating => {
            let leads = objects_by_section.iter().filter_map(|(_, vehicles)| vehicles.last().copied()).collect();
            plan.tailgate = Some(Tailgate { leads, gap: 1.0, brake: 3.0 });
        }
        Driver::KnifeEdge => {
            let clearance = rng(config.seed, Stream::Driver).random_range(0.1..0.3);
            let reach = zones
                .iter()
                .zip(&objects_by_section)
                .map(|(zone, (statics, _))| closure_reach(&road, zone, statics))
                .fold(f64::NEG_INFINITY, f64::max);
            plan.lanes.0 = reach + clearance + dash2sim_core::obb::PACIFICA.width / 2.0;
        }
        _ => {}
    }

    let egos = plan.drive(&road, config.duration_s, config.frame_rate_hz);
    let mut detector = rng(config.seed, Stream::Detector);
    let camera = &config.camera;
    let model = &config.detector;
    let frames = egos
        .iter()
        .enumerate()
        .map(|(k, ego)| {
            let objects: Vec<ObjectState> = objects_by_section
                .iter()
                .enumerate()
                .filter(|(k, _)| {
                    let start = *k as f64 * SECTION_M;
                    *k == 0 || (start - SECTION_VIEW_M..start + SECTION_M + SECTION_VIEW_M).contains(&ego.s)
                })
                .flat_map(|(_, (statics, vehicles))| {
                    statics.iter().copied().chain(vehicles.iter().filter_map(|v| v.state(&road, ego.t)))
                })
                .collect();
            let (mut visible, mut detections_3d, mut detections_2d, mut objects_2d) =
                (Vec::new(), Vec::new(), Vec::new(), Vec::new());
            let seen: Vec<_> =
                objects.iter().filter_map(|o| observable(camera, ego, o).map(|seen| (o, seen))).collect();
            let occluded = if model.occlusion {
                sensors::occlusion(
                    &seen.iter().map(|(_, (local, image, _))| (*image, local.x.hypot(local.y))).collect::<Vec<_>>(),
                )
            } else {
                vec![0.0; seen.len()]
            };
            for ((object, (local, image, visibility)), occluded) in seen.into_iter().zip(occluded) {
                visible.push(object.id);
                objects_2d.push(Object2d { id: object.id, class: object.class, bbox: image, visibility });
                detections_3d.extend(model.detect_3d(&mut detector, camera, object.class, &local, occluded));
                let range = local.x.hypot(local.y);
                detections_2d.extend(model.detect_2d(&mut detector, camera, object.class, range, &image, occluded));
            }
            detections_3d.extend(model.false_positives_3d(&mut detector, camera));
            detections_2d.extend(model.false_positives_2d(&mut detector, camera));
            let index = u32::try_from(k + 1).unwrap_or(u32::MAX);
            Frame { index, ego: *ego, objects, visible, detections_3d, detections_2d, objects_2d }
        })
        .collect();

    // The dashcam (camera and GNSS receiver in one housing) rides ahead of and above the
    // rear axle, where it really is: VO follows the camera, the fixes describe the camera's
    // position.
    let camera_truth = camera_trajectory(&egos, camera);
    let vo = config.vo.generate(&camera_truth, &mut rng(config.seed, Stream::Vo));
    let frames_per_fix = (config.frame_rate_hz / config.gnss_rate_hz).round().max(1.0) as usize;
    let [forward, left, up] = camera.true_mount().position;
    let fix_states: Vec<EgoState> = egos
        .iter()
        .step_by(frames_per_fix)
        .map(|e| EgoState {
            x: e.x + (forward * e.heading.cos() - left * e.heading.sin()),
            y: e.y + (forward * e.heading.sin() + left * e.heading.cos()),
            ..*e
        })
        .collect();
    let mut gnss = config.gnss.fixes(&mut rng(config.seed, Stream::Gnss), &fix_states);
    for fix in &mut gnss {
        fix.enu[2] += up;
    }
    let wheel_states = plan.drive(&road, config.duration_s, config.speed_rate_hz);
    let speed = sensors::wheel_speed(&mut rng(config.seed, Stream::Wheel), &wheel_states, &config.wheel);
    let imu_states = plan.drive(&road, config.duration_s, config.imu.rate_hz);
    let imu = config.imu.samples(&mut rng(config.seed, Stream::Imu), &imu_states, camera);
    Scenario { config: *config, road, zones, frames, vo, gnss, speed, imu }
}

/// The real camera's poses (ENU; camera axes x forward, y left, z up), through its real
/// mount.
pub fn camera_trajectory(egos: &[EgoState], camera: &Camera) -> Trajectory {
    let mut out = ego_trajectory(egos);
    let mount = camera.true_mount();
    let (position, rotation) = (dash2sim_core::nalgebra::Vector3::from(mount.position), mount.rotation());
    // A mount without a turn leaves the rotation untouched (the ideal profile's VO then stays
    // bit for bit what it was before mount errors existed).
    let turned = camera.mount_error.yaw != 0.0 || camera.mount_error.pitch != 0.0;
    for pose in &mut out.poses {
        pose.translation += pose.rotation * position;
        if turned {
            pose.rotation *= rotation;
        }
    }
    out
}

/// The ego poses as a trajectory (ENU, heading about the vertical).
pub fn ego_trajectory(egos: &[EgoState]) -> Trajectory {
    let mut truth = Trajectory::default();
    for ego in egos {
        truth.stamps.push(ego.t);
        truth.poses.push(dash2sim_core::sim3::Pose {
            rotation: dash2sim_core::sim3::rotation_z(ego.heading),
            translation: dash2sim_core::nalgebra::Vector3::new(ego.x, ego.y, 0.0),
        });
    }
    truth
}

impl Scenario {
    /// The ego truth of every frame.
    pub fn ego_trajectory(&self) -> Trajectory {
        ego_trajectory(&self.frames.iter().map(|f| f.ego).collect::<Vec<_>>())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_scenario_and_another_seed_another() {
        let config = ScenarioConfig { duration_s: 5.0, ..ScenarioConfig::default() };
        let (a, b) = (generate(&config), generate(&config));
        assert_eq!(a.frames, b.frames);
        assert_eq!(a.gnss, b.gnss);
        assert_eq!(a.speed, b.speed);
        let c = generate(&ScenarioConfig { seed: 2, ..config });
        assert_ne!(a.frames[0].detections_3d, c.frames[0].detections_3d);
    }

    #[test]
    fn a_ten_minute_drive_passes_a_work_zone_in_every_section_calmly_and_in_the_open_lane() {
        let s = generate(&ScenarioConfig { seed: 5, duration_s: 600.0, ..ScenarioConfig::default() });
        assert_eq!(s.frames.len(), 6001);
        assert_eq!((s.zones.len(), sections_for(600.0)), (12, 12));
        let egos: Vec<EgoState> = s.frames.iter().map(|f| f.ego).collect();
        let last = egos.last().expect("frames");
        assert!(last.s > 9.0 * SECTION_M && last.s < s.road.length(), "the ego ends at s = {}", last.s);
        let line = s.road.right_edge() + s.road.lane_width;
        let mut passed = 0;
        for zone in s.zones.iter().filter(|z| z.end() < last.s) {
            passed += 1;
            for e in egos.iter().filter(|e| (zone.taper_start..zone.closure_end()).contains(&e.s)) {
                assert!(e.d - 0.95 > line, "ego at d = {} beside the closure at {}", e.d, zone.taper_start);
            }
        }
        assert!(passed >= 9, "{passed} zones passed");
        // Accelerations of the ego's motion (from its positions: the speed a state reports is
        // sampled over one 10 ms step, which at a bend's onset can straddle it).
        let speeds: Vec<f64> =
            egos.windows(2).map(|w| (w[1].x - w[0].x).hypot(w[1].y - w[0].y) / (w[1].t - w[0].t)).collect();
        for (k, w) in speeds.windows(3).enumerate() {
            let a_long = (w[2] - w[0]) / 0.2;
            assert!(a_long.abs() <= 1.6, "t {}: {a_long} m/s²", egos[k + 1].t);
        }
        // Every section's traffic and zone are seen, and nobody comes too close: a vehicle the
        // ego overtakes on a ten-minute drive is in the other lane.
        for f in s.frames.iter().step_by(5) {
            let (c, sn) = (f.ego.heading.cos(), f.ego.heading.sin());
            for o in f.objects.iter().filter(|o| !o.is_static()) {
                let (dx, dy) = (o.bbox.x - f.ego.x, o.bbox.y - f.ego.y);
                let (gap, lateral) = (dx.hypot(dy), -sn * dx + c * dy);
                let same_way = o.velocity[0] * c + o.velocity[1] * sn > 0.0;
                let clear = if same_way { gap > 12.0 || lateral.abs() > 2.5 } else { gap > 3.0 };
                assert!(clear, "frame {}: {gap} m to {} ({lateral} m to the side)", f.index, o.id);
            }
        }
        let seen: std::collections::BTreeSet<u32> = s.frames.iter().flat_map(|f| f.visible.iter().copied()).collect();
        assert!(seen.len() > 9 * 30, "{} objects seen", seen.len());
        // A section's objects are in the truth only near it: a long drive's truth stays small.
        assert!(
            s.frames.iter().all(|f| f.objects.len() < 3 * 45),
            "{}",
            s.frames.iter().map(|f| f.objects.len()).max().unwrap_or(0)
        );
    }

    #[test]
    fn a_drive_of_up_to_fifty_seconds_has_the_one_section_road_it_always_had() {
        assert_eq!(sections_for(50.0), 1);
        assert_eq!(sections_for(51.0), 1);
        assert_eq!(sections_for(60.0), 2);
        let short = generate(&ScenarioConfig { duration_s: 20.0, ..ScenarioConfig::default() });
        let long = generate(&ScenarioConfig { duration_s: 120.0, ..ScenarioConfig::default() });
        assert_eq!(short.zones[0], long.zones[0], "the first section is drawn first");
        assert_eq!(short.frames[..200], long.frames[..200], "a longer drive starts as the shorter one");
    }

    #[test]
    fn the_drive_is_plausible_and_passes_the_closure_in_the_open_lane() {
        for seed in 1..=4 {
            let s = generate(&ScenarioConfig { seed, ..ScenarioConfig::default() });
            let egos: Vec<EgoState> = s.frames.iter().map(|f| f.ego).collect();
            // Longitudinal and lateral accelerations of a calm driver (nuPlan's comfort
            // bounds are 4.89 m/s² lateral, −4.05…2.40 m/s² longitudinal).
            for w in egos.windows(3) {
                let dt = w[1].t - w[0].t;
                let a_long = (w[2].speed - w[0].speed) / (2.0 * dt);
                let yaw_rate = road::wrap(w[2].heading - w[0].heading) / (2.0 * dt);
                assert!(a_long.abs() <= 1.6, "seed {seed} t {}: {a_long} m/s²", w[1].t);
                assert!(
                    (yaw_rate * w[1].speed).abs() < 3.0,
                    "seed {seed} t {}: lateral {}",
                    w[1].t,
                    yaw_rate * w[1].speed
                );
            }
            // Alongside the cones the ego's right side stays clear of the cone line.
            let line = s.road.right_edge() + s.road.lane_width;
            let zone = &s.zones[0];
            for e in egos.iter().filter(|e| (zone.taper_start..zone.closure_end()).contains(&e.s)) {
                assert!(e.d - 0.95 > line, "seed {seed}: ego at d = {} beside the closure", e.d);
            }
            assert!(egos.iter().any(|e| e.s > zone.end()), "seed {seed}: the drive ends before the zone does");
            // Nobody drives into the ego; vehicles ahead in its direction keep their distance.
            for f in &s.frames {
                for o in f.objects.iter().filter(|o| !o.is_static()) {
                    let gap = (o.bbox.x - f.ego.x).hypot(o.bbox.y - f.ego.y);
                    let same_way = o.velocity[0] * f.ego.heading.cos() + o.velocity[1] * f.ego.heading.sin() > 0.0;
                    assert!(
                        gap > if same_way { 12.0 } else { 3.0 },
                        "seed {seed} frame {}: {gap} m to {}",
                        f.index,
                        o.id
                    );
                }
            }
            // Every class of the zone is seen, and some detections are flipped.
            let seen: std::collections::BTreeSet<Class> = s
                .frames
                .iter()
                .flat_map(|f| f.visible.iter().filter_map(|&id| f.object(id)).map(|o| o.class))
                .collect();
            assert_eq!(seen.len(), Class::ALL.len(), "seed {seed}: {seen:?}");
            assert!(s.gnss.iter().any(|g| g.multipath) || seed != 1, "seed 1 has a multipath episode");
        }
    }

    /// The least gap across the road between the ego's side and the closure's objects it
    /// passes (the zone is on a straight), m.
    fn closure_clearance(s: &Scenario) -> f64 {
        let zone = &s.zones[0];
        let start = s.road.pose(zone.taper_start);
        let (sin, cos) = start.heading.sin_cos();
        let half_width = dash2sim_core::obb::PACIFICA.width / 2.0;
        let statics: Vec<&ObjectState> = s.frames[0].objects.iter().filter(|o| o.is_static()).collect();
        let mut least = f64::INFINITY;
        for e in s.frames.iter().map(|f| f.ego).filter(|e| (zone.taper_start - 10.0..zone.closure_end()).contains(&e.s))
        {
            let (front, rear) = (e.s + dash2sim_core::obb::PACIFICA.front, e.s - dash2sim_core::obb::PACIFICA.rear);
            for o in &statics {
                let (dx, dy) = (o.bbox.x - start.x, o.bbox.y - start.y);
                let (along, across) = (zone.taper_start + dx * cos + dy * sin, -dx * sin + dy * cos);
                let turn = o.bbox.yaw - start.heading;
                let half_along = (o.bbox.l / 2.0 * turn.cos()).abs() + (o.bbox.w / 2.0 * turn.sin()).abs();
                let half_across = (o.bbox.l / 2.0 * turn.sin()).abs() + (o.bbox.w / 2.0 * turn.cos()).abs();
                if along + half_along >= rear && along - half_along <= front {
                    least = least.min((e.d - half_width) - (across + half_across));
                }
            }
        }
        least
    }

    #[test]
    fn the_knife_edge_driver_passes_the_closure_a_hand_breadth_clear_and_the_careful_one_wider() {
        for seed in 1..=8 {
            let drive = |driver| generate(&ScenarioConfig { seed, driver, ..ScenarioConfig::default() });
            let (edge, careful) =
                (closure_clearance(&drive(Driver::KnifeEdge)), closure_clearance(&drive(Driver::Careful)));
            assert!((0.1 - 1e-6..=0.3 + 1e-6).contains(&edge), "seed {seed}: {edge} m clear");
            assert!(careful > edge, "seed {seed}: careful {careful} m, knife-edge {edge} m");
        }
    }
}
