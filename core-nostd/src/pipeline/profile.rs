//! The work-zone profile: the object classes a dashcam meets in a work zone, their sizes,
//! and the tracker settings measured on generated work zones (`docs/tracking.md`). One
//! table, used on the device (the MCU example), by `dash2sim record` and by the scenario
//! generator, so that every side tracks with the same priors.

use super::{ClassMeta, PipelineConfig, SpeedSource, Trackers};
use crate::anchor::{AnchorConfig, AnchorMode};
use crate::class::{Class, ARROW_BOARD, BARRICADE, CAR, CONE, DRUM, SIGN, TRUCK};
use crate::geo::Geodetic;
use crate::score::AgentKind;
use crate::track2d::TrackerConfig;
use crate::track3d::{Association, ClassConfig, Config3d};

/// A class of the profile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassProfile {
    /// Lower-case name as files and logs write it.
    pub name: &'static str,
    /// Its code in `Track3d` records (`docs/binlog.md`).
    pub code: i64,
    /// What kind of road user it is for the score.
    pub kind: AgentKind,
    /// Nominal size (length along the heading, width, height), m.
    pub size: [f64; 3],
    /// Placed once, never moves.
    pub is_static: bool,
    /// Its heading can be told from its shape (cones and drums are round).
    pub has_heading: bool,
}

/// The profile of a class of the class table ([`crate::class`]: its name, code and kind of
/// road user).
const fn class(c: Class, size: [f64; 3], is_static: bool, has_heading: bool) -> ClassProfile {
    ClassProfile { name: c.name, code: c.code, kind: c.kind, size, is_static, has_heading }
}

/// The classes, by tracker class id.
pub const WORK_ZONE: [ClassProfile; 7] = [
    class(CAR, [4.6, 1.9, 1.5], false, true),
    class(TRUCK, [9.0, 2.5, 3.4], false, true),
    class(CONE, [0.36, 0.36, 0.71], true, false),
    class(DRUM, [0.58, 0.58, 1.0], true, false),
    class(BARRICADE, [1.8, 0.4, 1.5], true, true),
    class(ARROW_BOARD, [3.6, 2.2, 3.2], true, true),
    class(SIGN, [0.15, 1.2, 2.2], true, true),
];

/// The tracker class id of a class name.
pub fn class_id(name: &str) -> Option<u16> {
    WORK_ZONE.iter().position(|c| c.name == name).and_then(|i| u16::try_from(i).ok())
}

/// Log codes and road-user kinds of the classes.
pub static WORK_ZONE_META: [ClassMeta; 7] = {
    let mut out = [ClassMeta { code: 0, kind: AgentKind::Object }; 7];
    let mut i = 0;
    while i < out.len() {
        out[i] = ClassMeta { code: WORK_ZONE[i].code, kind: WORK_ZONE[i].kind };
        i += 1;
    }
    out
};

/// [`WORK_ZONE_META`], as a value.
pub fn work_zone_meta() -> [ClassMeta; 7] {
    WORK_ZONE_META
}

/// The tracker's settings for one class: the priors allow ±30 % on the nominal size and
/// 0.3 m off the ground; R is the detector's error at about 25 m (detections carry their own
/// position covariance, which replaces it for x and y); static classes get a process noise
/// near zero and a prior that they stand still (velocity σ 0.1 m/frame), vehicles
/// AB3DMOT's velocity noise and an unknown initial velocity.
pub const fn class_config(c: &ClassProfile) -> ClassConfig {
    let [l, w, h] = c.size;
    let yaw_var = if c.has_heading { 0.01 } else { 1e4 };
    let (association, process_noise, initial_velocity_variance) = if c.is_static {
        (Association::Distance(2.0), [1e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4, 1e-4], 0.01)
    } else {
        (Association::Giou(-0.2), [0.05, 0.05, 0.01, 0.01, 1e-3, 1e-3, 1e-3, 0.01, 0.01, 1e-4], 1e4)
    };
    ClassConfig {
        association,
        min_size: [0.7 * l, 0.7 * w, 0.7 * h],
        max_size: [1.3 * l, 1.3 * w, 1.3 * h],
        max_ground_offset: 0.3,
        process_noise,
        measurement_noise: [
            0.25,
            0.25,
            0.0025,
            yaw_var,
            (0.04 * l) * (0.04 * l),
            (0.04 * w) * (0.04 * w),
            (0.04 * h) * (0.04 * h),
        ],
        initial_velocity_variance,
    }
}

/// The tracker's settings of every class ([`class_config`] of [`WORK_ZONE`]), by class id.
pub static WORK_ZONE_CLASSES: [ClassConfig; 7] = {
    let mut out = [class_config(&WORK_ZONE[0]); 7];
    let mut i = 1;
    while i < out.len() {
        out[i] = class_config(&WORK_ZONE[i]);
        i += 1;
    }
    out
};

/// [`WORK_ZONE_CLASSES`], as a value.
pub fn work_zone_classes() -> [ClassConfig; 7] {
    WORK_ZONE_CLASSES
}

/// AB3DMOT's min_hits 3, max_age 4 frames (AB3DMOT: 2; at 10 Hz and 60 % detection
/// probability at range, 2 fragments tracks), ground at z = 0, static below 0.3 m/frame.
pub const fn work_zone_tracker(classes: &[ClassConfig]) -> Config3d<'_> {
    Config3d { classes, min_hits: 3, max_age: 4, ground_z: 0.0, static_speed: 0.3 }
}

/// The work-zone trackers: [`WORK_ZONE_CLASSES`] with [`work_zone_tracker`]'s settings
/// and ByteTrack's for the 2D tracker. Const, so that on a microcontroller they live in a
/// `static` (a `static_cell::ConstStaticCell`) and are never built on the stack.
pub const fn work_zone_trackers<const T3: usize, const T2: usize>() -> Trackers<'static, T3, T2> {
    Trackers::new(work_zone_tracker(&WORK_ZONE_CLASSES), TrackerConfig::BYTETRACK)
}

/// A dashcam in work zones: anchoring with a gravity-aligned VO frame (VIO or a levelled
/// VO), wheel speed from J1939 CCVS1, the classes of [`WORK_ZONE`], the rest
/// [`PipelineConfig::new`]'s defaults. `dash2sim record` and the MCU example start here
/// (with [`work_zone_trackers`]).
pub fn work_zone_pipeline(origin: Geodetic, meta: &[ClassMeta]) -> PipelineConfig<'_> {
    PipelineConfig {
        anchor: AnchorConfig { mode: AnchorMode::GravityAligned, ..AnchorConfig::default() },
        speed: Some(SpeedSource::Ccvs1),
        ..PipelineConfig::new(origin, meta)
    }
}
