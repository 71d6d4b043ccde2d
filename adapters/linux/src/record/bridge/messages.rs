//! The bridge's message types: `#[repr(C)]`, self-contained, defined once for the camera
//! process and the logger. Every message starts with [`LAYOUT_VERSION`]; change it whenever
//! a layout here changes. Times are the device clock (µs); `sequence` is the frame number.
//!
//! Camera processes in C and Python publish the same messages (`adapters/camera-c`,
//! `dash2sim.camera`): each type carries a fixed iceoryx2 type name (`dash2sim::…`, not
//! Rust's module path, which other languages cannot know), and [`layouts`] reports every
//! field's offset and size so that their definitions are checked against these.

use iceoryx2::prelude::ZeroCopySend;
use serde::Serialize;

/// The message layout this build writes and reads.
pub const LAYOUT_VERSION: u32 = 1;
/// Detections a message carries at most (the pipeline's per-frame capacity).
pub const MAX_DETECTIONS: usize = 64;

/// A camera frame's metadata.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::FrameMetaMsg")]
#[repr(C)]
pub struct FrameMetaMsg {
    /// [`LAYOUT_VERSION`].
    pub version: u32,
    /// Exposure time, µs.
    pub exposure_us: u32,
    /// Frame number.
    pub sequence: u64,
    /// Capture time, device clock, µs.
    pub device_time_us: i64,
    /// Bytes of the image published with this frame on the image service (0: none).
    pub image_bytes: u32,
    /// The IMU samples this publisher had sent when it sent this frame ([`ImuMsg`]'s
    /// numbering, wrapping): the logger holds the frame until that sample is in (issue #57).
    /// In what was the reserved field, so the layout and its version are unchanged; an older
    /// publisher's 0 reads as "not said".
    pub imu_published: u32,
}

/// The VO pose of a frame: camera → VO frame, unknown scale.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::VoPoseMsg")]
#[repr(C)]
pub struct VoPoseMsg {
    /// [`LAYOUT_VERSION`].
    pub version: u32,
    /// VO session: 0 from the start, one more each time the VO re-initialises (a new
    /// origin, orientation and scale). Publishers that predate it send 0 (the field was
    /// reserved, zero), so the layout is unchanged.
    pub session: u32,
    /// Frame number.
    pub sequence: u64,
    /// Capture time, device clock, µs.
    pub device_time_us: i64,
    /// Camera position in the VO frame.
    pub position: [f64; 3],
    /// Camera → VO rotation, row-major.
    pub rotation: [f64; 9],
}

/// One 3D detection in the camera frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::Detection3dItem")]
#[repr(C)]
pub struct Detection3dItem {
    /// Class id (the work-zone profile's).
    pub class: u16,
    /// Zero.
    pub reserved: u16,
    /// Score in [0, 1].
    pub score: f32,
    /// Centre x, y, z, heading, length, width, height (m, rad).
    pub bbox: [f32; 7],
    /// Covariance of the horizontal centre xx, xy, yy (m²; all zero: none).
    pub covariance: [f32; 3],
}

/// The 3D detections of a frame.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::Detections3dMsg")]
#[repr(C)]
pub struct Detections3dMsg {
    /// [`LAYOUT_VERSION`].
    pub version: u32,
    /// Detections in `items`.
    pub count: u32,
    /// Frame number.
    pub sequence: u64,
    /// Capture time, device clock, µs.
    pub device_time_us: i64,
    /// The first `count` are the detections.
    pub items: [Detection3dItem; MAX_DETECTIONS],
}

/// One 2D detection.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::Detection2dItem")]
#[repr(C)]
pub struct Detection2dItem {
    /// Class id.
    pub class: u16,
    /// Zero.
    pub reserved: u16,
    /// Score in [0, 1].
    pub score: f32,
    /// Left, top, width, height, pixels.
    pub bbox: [f32; 4],
}

/// The 2D detections of a frame.
#[derive(Clone, Copy, Debug, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::Detections2dMsg")]
#[repr(C)]
pub struct Detections2dMsg {
    /// [`LAYOUT_VERSION`].
    pub version: u32,
    /// Detections in `items`.
    pub count: u32,
    /// Frame number.
    pub sequence: u64,
    /// Capture time, device clock, µs.
    pub device_time_us: i64,
    /// The first `count` are the detections.
    pub items: [Detection2dItem; MAX_DETECTIONS],
}

/// "Keep the file being recorded": the camera process marks the moment (its user pressed the
/// dashcam's button, or its detector saw something worth keeping); the logger protects the
/// log file being written from loop recording's deletions.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::KeepMsg")]
#[repr(C)]
pub struct KeepMsg {
    /// [`LAYOUT_VERSION`].
    pub version: u32,
    /// Zero.
    pub reserved: u32,
    /// When, device clock, µs.
    pub device_time_us: i64,
}

/// One sample of the camera's inertial sensor (dashcam SoCs read it beside the image
/// sensor), on the sensor's own axes; `dash2sim record --imu-mount` gives their rotation
/// to the camera. One message per sample: at 100–400 Hz a batch would save little and
/// cost every publisher a buffer.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
#[type_name("dash2sim::ImuMsg")]
#[repr(C)]
pub struct ImuMsg {
    /// [`LAYOUT_VERSION`].
    pub version: u32,
    /// The samples this publisher has sent, this one included (1, 2, …): a gap tells the
    /// logger how many it missed. In what was the reserved field, so the layout and its
    /// version are unchanged; an older publisher's 0 reads as "not numbered".
    pub sequence: u32,
    /// Sample time, device clock, µs (the sensor's own time stamp mapped to it, when it
    /// has one).
    pub device_time_us: i64,
    /// Angular rate about the sensor's x, y, z, rad/s.
    pub gyro: [f32; 3],
    /// Specific force along the sensor's x, y, z, m/s² (at rest, +9.81 along "up").
    pub accel: [f32; 3],
}

/// A message type as another language must declare it: its iceoryx2 type name, size,
/// alignment and fields in order.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Layout {
    /// The iceoryx2 type name.
    pub type_name: &'static str,
    /// Bytes.
    pub size: usize,
    /// Bytes.
    pub align: usize,
    /// Name, offset and size of each field, in order.
    pub fields: Vec<(&'static str, usize, usize)>,
}

/// The field `$f` of `$t`: name, offset, size.
macro_rules! field {
    ($t:ty, $f:ident) => {
        (stringify!($f), core::mem::offset_of!($t, $f), {
            fn size_of_field<F>(_: fn(&$t) -> &F) -> usize {
                core::mem::size_of::<F>()
            }
            size_of_field(|m: &$t| &m.$f)
        })
    };
}

/// The layout of `$t` with its fields `$f…`.
macro_rules! layout {
    ($t:ty, $($f:ident),+) => {
        Layout {
            // The `type_name` attribute's value (the derive's accessor is an `unsafe fn`;
            // `dash2sim-camera`'s tests compare the two).
            type_name: concat!("dash2sim::", stringify!($t)),
            size: core::mem::size_of::<$t>(),
            align: core::mem::align_of::<$t>(),
            fields: vec![$(field!($t, $f)),+],
        }
    };
}

/// Every message type's layout, with [`LAYOUT_VERSION`] and [`MAX_DETECTIONS`]: what the C
/// header and the Python structures are checked against.
pub fn layouts() -> Vec<Layout> {
    vec![
        layout!(FrameMetaMsg, version, exposure_us, sequence, device_time_us, image_bytes, imu_published),
        layout!(VoPoseMsg, version, session, sequence, device_time_us, position, rotation),
        layout!(Detection3dItem, class, reserved, score, bbox, covariance),
        layout!(Detections3dMsg, version, count, sequence, device_time_us, items),
        layout!(Detection2dItem, class, reserved, score, bbox),
        layout!(Detections2dMsg, version, count, sequence, device_time_us, items),
        layout!(KeepMsg, version, reserved, device_time_us),
        layout!(ImuMsg, version, sequence, device_time_us, gyro, accel),
    ]
}
