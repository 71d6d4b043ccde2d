//! The bridge's message types: `#[repr(C)]`, self-contained, defined once for the camera
//! process and the logger. Every message starts with [`LAYOUT_VERSION`]; change it whenever
//! a layout here changes. Times are the device clock (µs); `sequence` is the frame number.

use iceoryx2::prelude::ZeroCopySend;

/// The message layout this build writes and reads.
pub const LAYOUT_VERSION: u32 = 1;
/// Detections a message carries at most (the pipeline's per-frame capacity).
pub const MAX_DETECTIONS: usize = 64;

/// A camera frame's metadata.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
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
    /// Zero.
    pub reserved: u32,
}

/// The VO pose of a frame: camera → VO frame, unknown scale.
#[derive(Clone, Copy, Debug, Default, PartialEq, ZeroCopySend)]
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
