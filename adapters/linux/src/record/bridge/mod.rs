//! The shared-memory bridge between the camera process and the logger (iceoryx2).
//!
//! On a dashcam the camera process (video, VO, detectors) and the logger are separate
//! processes. The camera process publishes, per frame, its metadata (and optionally the
//! image, zero-copy), the VO pose and the 3D and 2D detections, and, per sample, its IMU's
//! readings, on iceoryx2 publish-subscribe services under one prefix (default
//! [`DEFAULT_PREFIX`]: `frame`, `vo`, `detections3d`, `detections2d`, `imu`, and `keep` for
//! its "keep this file" marks); the logger
//! subscribes and feeds the on-device pipeline. The message types ([`messages`]) are
//! `#[repr(C)]` and defined once here for both sides; iceoryx2 refuses to connect two sides
//! whose payload types differ in name, size or alignment, and every message carries
//! [`messages::LAYOUT_VERSION`], which the subscriber checks, so that a publisher built from
//! another layout is refused with a message rather than misread.
//!
//! ```no_run
//! use dash2sim_core::time::Timestamp;
//! use dash2sim_linux::record::bridge::CameraPublisher;
//! # fn main() -> Result<(), dash2sim_linux::record::bridge::BridgeError> {
//! let camera = CameraPublisher::new(dash2sim_linux::record::bridge::DEFAULT_PREFIX, false)?;
//! # let (t, pose, boxes3d, boxes2d) = (Timestamp::ZERO, dash2sim_core::sim3::Pose::identity(), [], []);
//! // per frame, in this order:
//! camera.frame(42, t, 8_000, None)?;
//! camera.vo(42, t, &pose, 0)?;
//! camera.detections3d(42, t, &boxes3d)?;
//! camera.detections2d(42, t, &boxes2d)?;
//! # Ok(()) }
//! ```

pub mod merge;
pub mod messages;
pub mod sequence;

use dash2sim_core::box2d::Box2d;
use dash2sim_core::box3d::Box3d;
use dash2sim_core::imu::ImuSample;
use dash2sim_core::nalgebra::{Matrix3, Vector3};
use dash2sim_core::pipeline::ImageDetection;
use dash2sim_core::sim3::Pose;
use dash2sim_core::time::Timestamp;
use dash2sim_core::track2d::Detection;
use dash2sim_core::track3d::Detection3d;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;

use messages::{
    Detection2dItem, Detection3dItem, Detections2dMsg, Detections3dMsg, FrameMetaMsg, ImuMsg, KeepMsg, VoPoseMsg,
    LAYOUT_VERSION, MAX_DETECTIONS,
};
use sequence::{Service, ServiceCounts};

/// The services' prefix unless told otherwise.
pub const DEFAULT_PREFIX: &str = "dash2sim/camera";
/// The largest image the image service carries: 1920 × 1080 × 3 bytes.
pub const MAX_IMAGE_BYTES: usize = 1920 * 1080 * 3;
/// Samples a subscriber keeps per service before the oldest is overwritten (3.2 s at 20 Hz).
pub const SUBSCRIBER_BUFFER: usize = 64;
/// Samples the IMU service keeps (2.56 s at 400 Hz, the same time as the others at 100 Hz).
pub const IMU_SUBSCRIBER_BUFFER: usize = 1024;

/// What went wrong on the bridge.
#[derive(Debug)]
pub enum BridgeError {
    /// iceoryx2 refused (creating, opening, loaning, sending or receiving); the text says what.
    Iceoryx(String),
    /// A message of another layout version arrived.
    Layout {
        /// The service.
        service: &'static str,
        /// The version in the message.
        found: u32,
    },
}

impl std::fmt::Display for BridgeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BridgeError::Iceoryx(e) => write!(f, "shared memory: {e}"),
            BridgeError::Layout { service, found } => write!(
                f,
                "{service}: the publisher sends message layout {found}, this logger reads layout {LAYOUT_VERSION} — rebuild the camera process against this dash2sim"
            ),
        }
    }
}

impl std::error::Error for BridgeError {}

fn iox(what: &str) -> impl Fn(&dyn std::fmt::Debug) -> BridgeError + '_ {
    move |e| BridgeError::Iceoryx(format!("{what}: {e:?}"))
}

fn service_name(prefix: &str, leaf: &str) -> Result<ServiceName, BridgeError> {
    let name = format!("{prefix}/{leaf}");
    ServiceName::new(&name).map_err(|e| BridgeError::Iceoryx(format!("service name {name:?}: {e:?}")))
}

/// Opens (or creates) the service `prefix/leaf` for messages of type `T`.
macro_rules! service {
    ($node:expr, $prefix:expr, $leaf:literal, $t:ty) => {
        service!($node, $prefix, $leaf, $t, SUBSCRIBER_BUFFER)
    };
    ($node:expr, $prefix:expr, $leaf:literal, $t:ty, $buffer:expr) => {
        $node
            .service_builder(&service_name($prefix, $leaf)?)
            .publish_subscribe::<$t>()
            .subscriber_max_buffer_size($buffer)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| {
                BridgeError::Iceoryx(format!(
                    "{}/{}: {e:?} (a publisher or logger of another dash2sim message layout?)",
                    $prefix, $leaf
                ))
            })?
    };
}

/// How long opening a service waits for another process still creating it (iceoryx2's
/// default is 1 s). A logger starved of CPU — a dashcam's busy processor, the recorder at
/// low priority — can take longer than that between the steps of creating its services:
/// the camera process's open then failed with `HangsInCreation` where it should have
/// waited (issue #57).
pub const CREATION_TIMEOUT: core::time::Duration = core::time::Duration::from_secs(10);

/// Which side of the bridge a node is on: who clears away the resources of a camera process
/// that died.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Side {
    /// A camera process (its publishers, its wait for the logger) or a subscriber beside
    /// the logger: it leaves a dead camera process's publishers alone. iceoryx2's default is to remove every dead node's resources when a
    /// node is created, a service opened or a node dropped — so a camera process restarted
    /// after a crash removed its predecessor's publishers, and with them whatever the
    /// predecessor had published that a logger starved of CPU had not yet connected to and
    /// drained: lost without a trace (issue #57).
    Camera,
    /// The logger: it removes dead nodes' resources once it has drained them
    /// ([`CameraSubscriber::receive`], at most every [`CLEAR_DEAD_EVERY`]).
    Logger,
}

/// How often the logger clears away the resources of camera processes that died, once
/// drained.
pub const CLEAR_DEAD_EVERY: std::time::Duration = std::time::Duration::from_secs(1);

/// A node of this process on `side`, its creation timeout [`CREATION_TIMEOUT`].
fn node(side: Side) -> Result<Node<ipc::Service>, BridgeError> {
    let mut config = Config::global_config().clone();
    config.global.creation_timeout = CREATION_TIMEOUT;
    if side == Side::Camera {
        config.global.node.cleanup_dead_nodes_on_creation = false;
        config.global.node.cleanup_dead_nodes_on_destruction = false;
        config.global.service.cleanup_dead_nodes_on_open = false;
    }
    NodeBuilder::new().config(&config).create::<ipc::Service>().map_err(|e| iox("node")(&e))
}

/// A publisher on `service`. When the service already has its most publishers — those of
/// camera processes that died, left for a logger to drain, and no logger clearing them — the
/// dead ones are removed and the publisher made again.
fn publisher<T: std::fmt::Debug + ZeroCopySend>(
    service: &iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>,
    what: &str,
) -> Result<Publisher<ipc::Service, T, ()>, BridgeError> {
    use iceoryx2::port::publisher::PublisherCreateError;
    use iceoryx2::service::port_factory::PortFactory as _;
    match service.publisher_builder().create() {
        Err(PublisherCreateError::ExceedsMaxSupportedPublishers) => {
            service.try_cleanup_dead_nodes();
            service.publisher_builder().create()
        }
        created => created,
    }
    .map_err(|e| iox(what)(&e))
}

fn micros(t: Timestamp) -> i64 {
    t.micros()
}

/// The device clock the camera process and the logger share: `CLOCK_MONOTONIC`, the same
/// value in every process of the machine (unlike `std::time::Instant`, whose origin is not
/// exposed).
pub fn device_now() -> Timestamp {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
    Timestamp::from_micros(t.tv_sec.saturating_mul(1_000_000).saturating_add(t.tv_nsec / 1_000))
}

/// The camera process's side: a publisher per service.
#[derive(Debug)]
pub struct CameraPublisher {
    _node: Node<ipc::Service>,
    frame: Publisher<ipc::Service, FrameMetaMsg, ()>,
    vo: Publisher<ipc::Service, VoPoseMsg, ()>,
    detections3d: Publisher<ipc::Service, Detections3dMsg, ()>,
    detections2d: Publisher<ipc::Service, Detections2dMsg, ()>,
    keep: Publisher<ipc::Service, KeepMsg, ()>,
    imu: Publisher<ipc::Service, ImuMsg, ()>,
    /// IMU samples sent (they are numbered: [`ImuMsg::sequence`]).
    imu_sent: std::sync::atomic::AtomicU32,
    image: Option<Publisher<ipc::Service, [u8], ()>>,
}

impl CameraPublisher {
    /// Publishers on the services under `prefix`; `images` adds the image service.
    pub fn new(prefix: &str, images: bool) -> Result<Self, BridgeError> {
        set_log_level_from_env_or(LogLevel::Error);
        let node = node(Side::Camera)?;
        let frame = publisher(&service!(node, prefix, "frame", FrameMetaMsg), "frame publisher")?;
        let vo = publisher(&service!(node, prefix, "vo", VoPoseMsg), "vo publisher")?;
        let detections3d =
            publisher(&service!(node, prefix, "detections3d", Detections3dMsg), "detections3d publisher")?;
        let detections2d =
            publisher(&service!(node, prefix, "detections2d", Detections2dMsg), "detections2d publisher")?;
        let keep = publisher(&service!(node, prefix, "keep", KeepMsg), "keep publisher")?;
        let imu = publisher(&service!(node, prefix, "imu", ImuMsg, IMU_SUBSCRIBER_BUFFER), "imu publisher")?;
        let image = if images {
            let service = node
                .service_builder(&service_name(prefix, "image")?)
                .publish_subscribe::<[u8]>()
                .subscriber_max_buffer_size(2)
                .enable_safe_overflow(true)
                .open_or_create()
                .map_err(|e| iox("image service")(&e))?;
            Some(
                service
                    .publisher_builder()
                    .initial_max_slice_len(MAX_IMAGE_BYTES)
                    .create()
                    .map_err(|e| iox("image publisher")(&e))?,
            )
        } else {
            None
        };
        Ok(CameraPublisher {
            _node: node,
            frame,
            vo,
            detections3d,
            detections2d,
            keep,
            imu,
            imu_sent: std::sync::atomic::AtomicU32::new(0),
            image,
        })
    }

    /// A frame's metadata and, when the image service is on, its image (copied once, into
    /// shared memory: the subscriber reads it where it lies). [`CameraPublisher::loan_image`]
    /// lets a camera write the image there itself.
    pub fn frame(
        &self,
        sequence: u64,
        t: Timestamp,
        exposure_us: u32,
        image: Option<&[u8]>,
    ) -> Result<(), BridgeError> {
        let image = match image.filter(|_| self.image.is_some()) {
            Some(bytes) => {
                let n = bytes.len().min(MAX_IMAGE_BYTES);
                let mut loan = self.loan_image(n)?;
                loan.bytes_mut().copy_from_slice(&bytes[..n]);
                Some(loan)
            }
            None => None,
        };
        let message = FrameMetaMsg {
            version: LAYOUT_VERSION,
            exposure_us,
            sequence,
            device_time_us: micros(t),
            image_bytes: 0,
            imu_published: 0,
        };
        self.send_frame(message, image)
    }

    /// Shared memory for the next frame's image, `bytes` long (at most [`MAX_IMAGE_BYTES`];
    /// iceoryx2 zeroes it): write the image into [`ImageLoan::bytes_mut`] and hand it to
    /// [`CameraPublisher::send_frame`]. An error when the image service is off.
    pub fn loan_image(&self, bytes: usize) -> Result<ImageLoan, BridgeError> {
        let Some(publisher) = &self.image else {
            return Err(BridgeError::Iceoryx("image loan: the publisher was opened without the image service".into()));
        };
        if bytes > MAX_IMAGE_BYTES {
            return Err(BridgeError::Iceoryx(format!("image of {bytes} bytes: at most {MAX_IMAGE_BYTES}")));
        }
        Ok(ImageLoan(publisher.loan_slice(bytes).map_err(|e| iox("image loan")(&e))?))
    }

    /// A frame's metadata as it is, stamped with [`LAYOUT_VERSION`], after its image when there
    /// is one (`image_bytes` is then the image's length). The C ABI publishes through this.
    pub fn send_frame(&self, mut message: FrameMetaMsg, image: Option<ImageLoan>) -> Result<(), BridgeError> {
        message.version = LAYOUT_VERSION;
        message.imu_published = self.imu_sent.load(std::sync::atomic::Ordering::Relaxed);
        message.image_bytes = 0;
        if let Some(ImageLoan(sample)) = image {
            message.image_bytes = sample.payload().len() as u32;
            sample.send().map_err(|e| iox("image send")(&e))?;
        }
        let sample = self.frame.loan_uninit().map_err(|e| iox("frame loan")(&e))?;
        sample.write_payload(message).send().map_err(|e| iox("frame send")(&e))?;
        Ok(())
    }

    /// The VO pose of frame `sequence` (camera → VO frame) in VO session `session` (0 until
    /// the VO first re-initialises).
    pub fn vo(&self, sequence: u64, t: Timestamp, pose: &Pose, session: u32) -> Result<(), BridgeError> {
        let mut rotation = [0.0; 9];
        for (k, r) in rotation.iter_mut().enumerate() {
            *r = pose.rotation[(k / 3, k % 3)];
        }
        self.send_vo(VoPoseMsg {
            version: LAYOUT_VERSION,
            session,
            sequence,
            device_time_us: micros(t),
            position: [pose.translation.x, pose.translation.y, pose.translation.z],
            rotation,
        })
    }

    /// A VO pose message as it is, stamped with [`LAYOUT_VERSION`].
    pub fn send_vo(&self, mut message: VoPoseMsg) -> Result<(), BridgeError> {
        message.version = LAYOUT_VERSION;
        let sample = self.vo.loan_uninit().map_err(|e| iox("vo loan")(&e))?;
        sample.write_payload(message).send().map_err(|e| iox("vo send")(&e))?;
        Ok(())
    }

    /// The 3D detections of frame `sequence` in the camera frame (at most
    /// [`MAX_DETECTIONS`]; more is an error, so that none is lost silently).
    pub fn detections3d(&self, sequence: u64, t: Timestamp, detections: &[Detection3d]) -> Result<(), BridgeError> {
        let items: Vec<Detection3dItem> = detections
            .iter()
            .map(|d| {
                let b = &d.bbox;
                Detection3dItem {
                    class: d.class,
                    reserved: 0,
                    score: d.score as f32,
                    bbox: [b.x, b.y, b.z, b.yaw, b.l, b.w, b.h].map(|v| v as f32),
                    covariance: d.position_covariance.unwrap_or([0.0; 3]).map(|v| v as f32),
                }
            })
            .collect();
        self.send_detections3d(sequence, micros(t), &items)
    }

    /// 3D detections as their message items (at most [`MAX_DETECTIONS`]).
    pub fn send_detections3d(
        &self,
        sequence: u64,
        device_time_us: i64,
        detections: &[Detection3dItem],
    ) -> Result<(), BridgeError> {
        if detections.len() > MAX_DETECTIONS {
            return Err(BridgeError::Iceoryx(format!("{} 3D detections: at most {MAX_DETECTIONS}", detections.len())));
        }
        let mut message = Detections3dMsg {
            version: LAYOUT_VERSION,
            count: detections.len() as u32,
            sequence,
            device_time_us,
            items: [Detection3dItem::default(); MAX_DETECTIONS],
        };
        message.items[..detections.len()].copy_from_slice(detections);
        let sample = self.detections3d.loan_uninit().map_err(|e| iox("detections3d loan")(&e))?;
        sample.write_payload(message).send().map_err(|e| iox("detections3d send")(&e))?;
        Ok(())
    }

    /// The 2D detections of frame `sequence` (at most [`MAX_DETECTIONS`]).
    pub fn detections2d(&self, sequence: u64, t: Timestamp, detections: &[ImageDetection]) -> Result<(), BridgeError> {
        let items: Vec<Detection2dItem> = detections
            .iter()
            .map(|d| {
                let b = &d.detection.bbox;
                Detection2dItem {
                    class: d.class,
                    reserved: 0,
                    score: d.detection.score as f32,
                    bbox: [b.x, b.y, b.w, b.h].map(|v| v as f32),
                }
            })
            .collect();
        self.send_detections2d(sequence, micros(t), &items)
    }

    /// 2D detections as their message items (at most [`MAX_DETECTIONS`]).
    pub fn send_detections2d(
        &self,
        sequence: u64,
        device_time_us: i64,
        detections: &[Detection2dItem],
    ) -> Result<(), BridgeError> {
        if detections.len() > MAX_DETECTIONS {
            return Err(BridgeError::Iceoryx(format!("{} 2D detections: at most {MAX_DETECTIONS}", detections.len())));
        }
        let mut message = Detections2dMsg {
            version: LAYOUT_VERSION,
            count: detections.len() as u32,
            sequence,
            device_time_us,
            items: [Detection2dItem::default(); MAX_DETECTIONS],
        };
        message.items[..detections.len()].copy_from_slice(detections);
        let sample = self.detections2d.loan_uninit().map_err(|e| iox("detections2d loan")(&e))?;
        sample.write_payload(message).send().map_err(|e| iox("detections2d send")(&e))?;
        Ok(())
    }
}

impl CameraPublisher {
    /// "Keep the file being recorded" at device time `t` (a button press, an event the
    /// camera saw): the logger protects it from loop recording's deletions.
    pub fn keep(&self, t: Timestamp) -> Result<(), BridgeError> {
        let message = KeepMsg { version: LAYOUT_VERSION, reserved: 0, device_time_us: micros(t) };
        let sample = self.keep.loan_uninit().map_err(|e| iox("keep loan")(&e))?;
        sample.write_payload(message).send().map_err(|e| iox("keep send")(&e))?;
        Ok(())
    }

    /// One IMU sample at device time `t`, on the sensor's axes (rad/s, m/s²). Sent as f32:
    /// a consumer sensor's 16-bit readings lose nothing.
    pub fn imu(&self, t: Timestamp, sample: &ImuSample) -> Result<(), BridgeError> {
        self.send_imu(ImuMsg {
            version: LAYOUT_VERSION,
            sequence: 0,
            device_time_us: micros(t),
            gyro: sample.gyro.map(|v| v as f32),
            accel: sample.accel.map(|v| v as f32),
        })
    }

    /// An IMU message as it is, stamped with [`LAYOUT_VERSION`] and numbered (the
    /// logger counts the samples it missed). The C ABI publishes through this.
    pub fn send_imu(&self, mut message: ImuMsg) -> Result<(), BridgeError> {
        message.version = LAYOUT_VERSION;
        // Numbered 1, 2, … (after 2³² samples, 124 days at 400 Hz, the number wraps and
        // the logger reads one restart).
        message.sequence = self.imu_sent.fetch_add(1, std::sync::atomic::Ordering::Relaxed).wrapping_add(1);
        let sample = self.imu.loan_uninit().map_err(|e| iox("imu loan")(&e))?;
        sample.write_payload(message).send().map_err(|e| iox("imu send")(&e))?;
        Ok(())
    }
}

/// An image being written straight into shared memory ([`CameraPublisher::loan_image`]);
/// dropped unsent, the memory goes back.
#[derive(Debug)]
pub struct ImageLoan(iceoryx2::sample_mut::SampleMut<ipc::Service, [u8], ()>);

impl ImageLoan {
    /// The image's bytes, in shared memory.
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        self.0.payload_mut()
    }
}

/// What the logger receives, converted for the pipeline.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraInput {
    /// A frame's metadata.
    Frame {
        /// Frame sequence number.
        sequence: u64,
        /// Capture time (device clock).
        t: Timestamp,
        /// Exposure, µs.
        exposure_us: u32,
        /// Bytes of the image sent with it (0: none).
        image_bytes: u32,
        /// The IMU samples its publisher had sent before it (their numbering; 0: not said).
        imu_published: u32,
    },
    /// The VO pose of a frame: capture time, frame, VO session, pose.
    Vo(Timestamp, u64, u32, Pose),
    /// The 3D detections of a frame.
    Detections3d(Timestamp, u64, Vec<Detection3d>),
    /// The 2D detections of a frame.
    Detections2d(Timestamp, u64, Vec<ImageDetection>),
    /// Keep the file being recorded (the camera process's mark).
    Keep(Timestamp),
    /// An IMU sample.
    Imu(Timestamp, ImuSample),
}

impl CameraInput {
    /// Its stamp (capture time, device clock).
    pub fn t(&self) -> Timestamp {
        match self {
            CameraInput::Frame { t, .. }
            | CameraInput::Vo(t, ..)
            | CameraInput::Detections3d(t, ..)
            | CameraInput::Detections2d(t, ..)
            | CameraInput::Keep(t)
            | CameraInput::Imu(t, _) => *t,
        }
    }
}

/// The logger's side: a subscriber per service, and the inputs held back to be released in
/// the order they were published ([`CameraSubscriber::receive_in_order`]).
#[derive(Debug)]
pub struct CameraSubscriber {
    node: Node<ipc::Service>,
    /// Whether it clears away dead camera processes' resources ([`Side::Logger`]).
    clears: bool,
    /// When it last did.
    cleared: std::cell::Cell<std::time::Instant>,
    merge: std::cell::RefCell<merge::Merge>,
    tally: std::cell::RefCell<sequence::Tally>,
    frame: Subscriber<ipc::Service, FrameMetaMsg, ()>,
    vo: Subscriber<ipc::Service, VoPoseMsg, ()>,
    detections3d: Subscriber<ipc::Service, Detections3dMsg, ()>,
    detections2d: Subscriber<ipc::Service, Detections2dMsg, ()>,
    keep: Subscriber<ipc::Service, KeepMsg, ()>,
    imu: Subscriber<ipc::Service, ImuMsg, ()>,
}

fn check(service: &'static str, version: u32) -> Result<(), BridgeError> {
    if version == LAYOUT_VERSION {
        Ok(())
    } else {
        Err(BridgeError::Layout { service, found: version })
    }
}

/// Whether a logger is listening under `prefix`: every camera service (frames, VO poses, 3D
/// and 2D detections, keep marks, IMU samples) has a subscriber. Samples published before a
/// subscriber exists are not kept for it, so a camera process (or a test) that must not lose
/// its first samples waits for this before it publishes; a logger takes a moment to
/// subscribe, and longer on a busy machine.
pub fn listening(prefix: &str) -> Result<bool, BridgeError> {
    set_log_level_from_env_or(LogLevel::Error);
    let node = node(Side::Camera)?;
    fn subscribed<T: std::fmt::Debug + ZeroCopySend + IceoryxSend>(
        node: &Node<ipc::Service>,
        prefix: &str,
        leaf: &str,
    ) -> Result<bool, BridgeError> {
        match node.service_builder(&service_name(prefix, leaf)?).publish_subscribe::<T>().open() {
            Ok(service) => Ok(service.dynamic_config().number_of_subscribers() > 0),
            // Not yet, or not yet done: a logger starved of CPU creates its services slowly.
            Err(
                iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError::DoesNotExist
                | iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError::HangsInCreation,
            ) => Ok(false),
            Err(e) => Err(BridgeError::Iceoryx(format!("{prefix}/{leaf}: {e:?}"))),
        }
    }
    Ok(subscribed::<FrameMetaMsg>(&node, prefix, "frame")?
        && subscribed::<VoPoseMsg>(&node, prefix, "vo")?
        && subscribed::<Detections3dMsg>(&node, prefix, "detections3d")?
        && subscribed::<Detections2dMsg>(&node, prefix, "detections2d")?
        && subscribed::<KeepMsg>(&node, prefix, "keep")?
        && subscribed::<ImuMsg>(&node, prefix, "imu")?)
}

impl CameraSubscriber {
    /// The logger's subscribers on the services under `prefix` (created if no publisher
    /// exists yet); it clears away what camera processes that died leave, once drained.
    pub fn new(prefix: &str) -> Result<Self, BridgeError> {
        Self::on(prefix, Side::Logger)
    }

    /// Subscribers beside the logger's (a monitor, a test watching the camera): they leave
    /// what camera processes that died leave to the logger, which may not have drained it.
    pub fn beside(prefix: &str) -> Result<Self, BridgeError> {
        Self::on(prefix, Side::Camera)
    }

    fn on(prefix: &str, side: Side) -> Result<Self, BridgeError> {
        set_log_level_from_env_or(LogLevel::Error);
        let node = node(side)?;
        let frame = service!(node, prefix, "frame", FrameMetaMsg).subscriber_builder().create();
        let vo = service!(node, prefix, "vo", VoPoseMsg).subscriber_builder().create();
        let detections3d = service!(node, prefix, "detections3d", Detections3dMsg).subscriber_builder().create();
        let detections2d = service!(node, prefix, "detections2d", Detections2dMsg).subscriber_builder().create();
        let keep = service!(node, prefix, "keep", KeepMsg).subscriber_builder().create();
        let imu = service!(node, prefix, "imu", ImuMsg, IMU_SUBSCRIBER_BUFFER).subscriber_builder().create();
        Ok(CameraSubscriber {
            node,
            clears: side == Side::Logger,
            cleared: std::cell::Cell::new(std::time::Instant::now()),
            merge: std::cell::RefCell::default(),
            tally: std::cell::RefCell::default(),
            frame: frame.map_err(|e| iox("frame subscriber")(&e))?,
            vo: vo.map_err(|e| iox("vo subscriber")(&e))?,
            detections3d: detections3d.map_err(|e| iox("detections3d subscriber")(&e))?,
            detections2d: detections2d.map_err(|e| iox("detections2d subscriber")(&e))?,
            keep: keep.map_err(|e| iox("keep subscriber")(&e))?,
            imu: imu.map_err(|e| iox("imu subscriber")(&e))?,
        })
    }

    /// Everything waiting, service by service as it comes: frames first, then IMU samples, VO
    /// poses, 3D and 2D detections, keep marks. A camera process publishing meanwhile can
    /// split a frame across two calls (its pose in one, its detections in the next, or a
    /// later pose before earlier IMU samples): [`CameraSubscriber::receive_in_order`] puts
    /// them back. Frames come first so that it can: everything published before the newest
    /// frame seen is in hand once the other services are drained after it. Returns how many.
    pub fn receive(&self, mut on: impl FnMut(CameraInput)) -> Result<usize, BridgeError> {
        let mut n = 0;
        while let Some(s) = self.frame.receive().map_err(|e| iox("frame receive")(&e))? {
            check("frame", s.version)?;
            self.tally.borrow_mut().count(Service::Frame, s.sequence);
            on(CameraInput::Frame {
                sequence: s.sequence,
                t: Timestamp::from_micros(s.device_time_us),
                exposure_us: s.exposure_us,
                image_bytes: s.image_bytes,
                imu_published: s.imu_published,
            });
            n += 1;
        }
        while let Some(s) = self.imu.receive().map_err(|e| iox("imu receive")(&e))? {
            check("imu", s.version)?;
            self.tally.borrow_mut().count(Service::Imu, u64::from(s.sequence));
            let sample = ImuSample { gyro: s.gyro.map(f64::from), accel: s.accel.map(f64::from) };
            on(CameraInput::Imu(Timestamp::from_micros(s.device_time_us), sample));
            n += 1;
        }
        while let Some(s) = self.vo.receive().map_err(|e| iox("vo receive")(&e))? {
            check("vo", s.version)?;
            self.tally.borrow_mut().count(Service::Vo, s.sequence);
            let r = &s.rotation;
            let pose = Pose {
                rotation: Matrix3::new(r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8]),
                translation: Vector3::from(s.position),
            };
            on(CameraInput::Vo(Timestamp::from_micros(s.device_time_us), s.sequence, s.session, pose));
            n += 1;
        }
        while let Some(s) = self.detections3d.receive().map_err(|e| iox("detections3d receive")(&e))? {
            check("detections3d", s.version)?;
            self.tally.borrow_mut().count(Service::Detections3d, s.sequence);
            let count = (s.count as usize).min(MAX_DETECTIONS);
            let detections = s.items[..count]
                .iter()
                .map(|d| {
                    let [x, y, z, yaw, l, w, h] = d.bbox.map(f64::from);
                    let cov = d.covariance.map(f64::from);
                    Detection3d {
                        class: d.class,
                        bbox: Box3d { x, y, z, yaw, l, w, h },
                        score: f64::from(d.score),
                        position_covariance: (cov != [0.0; 3]).then_some(cov),
                    }
                })
                .collect();
            on(CameraInput::Detections3d(Timestamp::from_micros(s.device_time_us), s.sequence, detections));
            n += 1;
        }
        while let Some(s) = self.detections2d.receive().map_err(|e| iox("detections2d receive")(&e))? {
            check("detections2d", s.version)?;
            self.tally.borrow_mut().count(Service::Detections2d, s.sequence);
            let count = (s.count as usize).min(MAX_DETECTIONS);
            let detections = s.items[..count]
                .iter()
                .map(|d| {
                    let [x, y, w, h] = d.bbox.map(f64::from);
                    ImageDetection {
                        class: d.class,
                        detection: Detection { bbox: Box2d { x, y, w, h }, score: f64::from(d.score) },
                    }
                })
                .collect();
            on(CameraInput::Detections2d(Timestamp::from_micros(s.device_time_us), s.sequence, detections));
            n += 1;
        }
        while let Some(s) = self.keep.receive().map_err(|e| iox("keep receive")(&e))? {
            check("keep", s.version)?;
            on(CameraInput::Keep(Timestamp::from_micros(s.device_time_us)));
            n += 1;
        }
        // Every service drained, from every publisher registered — those of camera processes
        // that died too ([`Side`]): what they left is in hand, their resources can go.
        if self.clears && self.cleared.get().elapsed() >= CLEAR_DEAD_EVERY {
            self.node.try_cleanup_dead_nodes();
            self.cleared.set(std::time::Instant::now());
        }
        Ok(n)
    }

    /// What [`CameraSubscriber::receive`] drains, handed on in the order the camera process
    /// published it ([`merge`]): up to the newest frame at once, what follows it with the
    /// next frame (or after [`merge::HOLD_US`] of stamps without one). Two runs of the same
    /// publication give the same sequence however the drains fall. Returns how many.
    /// Keep marks are handed on at once: they are about the file being recorded now, not a
    /// stamp's place among the inputs.
    pub fn receive_in_order(&self, mut on: impl FnMut(CameraInput)) -> Result<usize, BridgeError> {
        let mut merge = self.merge.borrow_mut();
        let mut marks = Vec::new();
        self.receive(|input| match input {
            CameraInput::Keep(_) => marks.push(input),
            input => merge.push(input),
        })?;
        if let Some(number) = self.tally.borrow().last_imu() {
            merge.imu_received(number);
        }
        let n = marks.len();
        marks.into_iter().for_each(&mut on);
        Ok(n + merge.release(on))
    }

    /// Everything waiting and everything [`CameraSubscriber::receive_in_order`] still
    /// holds, in order: the recording ends.
    pub fn flush(&self, mut on: impl FnMut(CameraInput)) -> Result<usize, BridgeError> {
        let n = self.receive_in_order(&mut on)?;
        Ok(n + self.merge.borrow_mut().flush(on))
    }

    /// The messages received per service, and those skipped in their numbers (lost to the
    /// subscriber's overflow, or never published: [`sequence`]).
    pub fn tally(&self) -> (ServiceCounts, ServiceCounts) {
        let tally = self.tally.borrow();
        (tally.received, tally.skipped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{run_stream, Setup};
    use dash2sim_core::geo::Geodetic;
    use dash2sim_core::pipeline::replay::Recorder;

    /// Frame `k` of a car driving straight on at 20 m/s, in the order a camera process
    /// publishes it: two IMU samples up to it, the frame, its VO pose, a cone ahead, a 2D box.
    fn frame_inputs(k: u64) -> Vec<CameraInput> {
        let t = 1_000_000 + 50_000 * k as i64;
        // Values the wire's f32 carries exactly.
        let sample = ImuSample { gyro: [0.0; 3], accel: [0.0, 0.0, 9.8125] };
        let at = Timestamp::from_micros(t);
        let pose = Pose { rotation: Matrix3::identity(), translation: Vector3::new(0.0, 0.0, k as f64) };
        let bbox = Box3d { x: 2.0, y: 1.0, z: 15.0 - k as f64, yaw: 0.0, l: 0.5, w: 0.5, h: 0.75 };
        let detection = Detection { bbox: Box2d { x: 600.0, y: 300.0, w: 40.0, h: 60.0 }, score: 0.875 };
        vec![
            CameraInput::Imu(Timestamp::from_micros(t - 25_000), sample),
            CameraInput::Imu(at, sample),
            CameraInput::Frame {
                sequence: k,
                t: at,
                exposure_us: 8_000,
                image_bytes: 0,
                imu_published: 2 * k as u32 + 2,
            },
            CameraInput::Vo(at, k, 0, pose),
            CameraInput::Detections3d(
                at,
                k,
                vec![Detection3d { class: 1, bbox, score: 0.875, position_covariance: None }],
            ),
            CameraInput::Detections2d(at, k, vec![ImageDetection { class: 1, detection }]),
        ]
    }

    fn publish(camera: &CameraPublisher, k: u64) {
        for input in frame_inputs(k) {
            match input {
                CameraInput::Imu(t, sample) => camera.imu(t, &sample),
                CameraInput::Frame { sequence, t, exposure_us, .. } => camera.frame(sequence, t, exposure_us, None),
                CameraInput::Vo(t, frame, session, pose) => camera.vo(frame, t, &pose, session),
                CameraInput::Detections3d(t, frame, d) => camera.detections3d(frame, t, &d),
                CameraInput::Detections2d(t, frame, d) => camera.detections2d(frame, t, &d),
                CameraInput::Keep(t) => camera.keep(t),
            }
            .expect("publish");
        }
    }

    /// The inputs through the pipeline in the order given: the log and how many inputs it
    /// refused.
    fn logged(inputs: &[CameraInput]) -> (Vec<u8>, u64) {
        let mut recorder = Recorder::new(Vec::new()).unwrap_or_else(|e| match e {});
        for input in inputs {
            let Ok(()) = match input {
                CameraInput::Vo(t, frame, session, pose) => recorder.vo(*t, *frame, *session, pose),
                CameraInput::Detections3d(t, frame, d) => recorder.detections3d(*t, *frame, d),
                CameraInput::Detections2d(t, frame, d) => recorder.detections2d(*t, *frame, d),
                CameraInput::Imu(t, sample) => recorder.imu(*t, sample),
                CameraInput::Frame { .. } | CameraInput::Keep(_) => Ok(()),
            };
        }
        let Ok(stream) = recorder.finish();
        let origin = Geodetic::new(60.2711, 24.8572, 20.0).expect("origin");
        let recording = run_stream(&stream, &Setup::work_zone(origin, None, *b"dash2sim-test\0\0\0")).expect("run");
        (recording.log, recording.issues.total())
    }

    /// Frames through real iceoryx2 services: 0 and 1, then `burst` more published the
    /// moment the logger's drain has just taken `trigger` of frame 1 — the interleaving a
    /// logger starved of CPU meets, made deterministic — and one last after. What the drain
    /// handed on as it came (what the logger fed the pipeline before issue #57), the same
    /// drain put in order, and what was published, in order.
    fn drained(
        name: &str,
        trigger: fn(&CameraInput) -> bool,
        burst: u64,
    ) -> (Vec<CameraInput>, Vec<CameraInput>, Vec<CameraInput>) {
        let prefix = format!("dash2sim-test/bridge-order/{name}/{}", std::process::id());
        let camera = CameraPublisher::new(&prefix, false).expect("publisher");
        let logger = CameraSubscriber::new(&prefix).expect("subscriber");
        let (mut raw, mut merge, mut published) = (Vec::new(), merge::Merge::default(), false);
        publish(&camera, 0);
        publish(&camera, 1);
        let mut take = |input: CameraInput| {
            raw.push(input.clone());
            merge.push(input);
        };
        logger
            .receive(|input| {
                let now = !published && trigger(&input);
                take(input);
                if now {
                    (2..2 + burst).for_each(|k| publish(&camera, k));
                    published = true;
                }
            })
            .expect("receive");
        assert!(published, "the trigger came");
        publish(&camera, 2 + burst);
        logger.receive(&mut take).expect("receive");
        merge.imu_received(logger.tally.borrow().last_imu().expect("numbered IMU samples"));
        let mut ordered = Vec::new();
        merge.release(|input| ordered.push(input));
        merge.flush(|input| ordered.push(input));
        (raw, ordered, (0..3 + burst).flat_map(frame_inputs).collect())
    }

    /// Issue #57's first failure, reproduced: the Rust and the C publisher's logs of the same
    /// files once differed (the same size, other bytes). A frame published while the logger
    /// drains the VO service reaches it pose first and its IMU samples a drain later: the
    /// pipeline writes another log than from the inputs in the order published.
    #[test]
    fn a_frame_published_during_the_drain_is_logged_as_if_it_had_not_been() {
        let (raw, ordered, published) = drained("vo", |i| matches!(i, CameraInput::Vo(_, 1, ..)), 1);
        assert_ne!(raw, published, "the reproduction: the drain saw frame 2 out of order");
        let in_publication_order = logged(&published).0;
        assert_ne!(logged(&raw).0, in_publication_order, "the failure: another log");
        assert_eq!(ordered, published, "put back in the order published");
        assert_eq!(logged(&ordered).0, in_publication_order);
    }

    /// Issue #57's second failure, reproduced: the demo's live recording, starved of CPU
    /// beside a CI run, refused one input. Two frames published while the logger drains the
    /// 3D detections reach it detections first and poses a drain later: the second frame's
    /// detections are 100 ms from the newest pose the pipeline has (more than its 50 ms),
    /// and refused as detections without a pose.
    #[test]
    fn detections_published_during_the_drain_are_not_refused_for_want_of_their_pose() {
        let (raw, ordered, published) = drained("detections", |i| matches!(i, CameraInput::Detections3d(_, 1, _)), 2);
        assert_eq!(logged(&raw).1, 1, "the reproduction: one input refused");
        assert_eq!(ordered, published);
        assert_eq!(logged(&ordered).1, 0);
        assert_eq!(logged(&ordered).0, logged(&published).0);
    }

    /// A logger further behind than the services keep loses the oldest messages to iceoryx2's
    /// overflow, silently: the messages' numbers say how many (issue #57).
    #[test]
    fn what_the_buffers_overwrote_is_counted_per_service() {
        let prefix = format!("dash2sim-test/bridge-skips/{}", std::process::id());
        let camera = CameraPublisher::new(&prefix, false).expect("publisher");
        let logger = CameraSubscriber::new(&prefix).expect("subscriber");
        let imu = |n: u64| camera.imu(Timestamp::from_micros(n as i64 * 2_500), &ImuSample::default()).expect("imu");
        let frame = |k: u64| camera.frame(k, Timestamp::from_micros(k as i64 * 33_000), 8_000, None).expect("frame");
        // The logger sees the first of each, then falls behind by more than its buffers.
        imu(1);
        frame(1);
        logger.receive(|_| ()).expect("receive");
        let (frames, samples) = (1 + SUBSCRIBER_BUFFER as u64 + 36, 1 + IMU_SUBSCRIBER_BUFFER as u64 + 76);
        (2..=samples).for_each(imu);
        (2..=frames).for_each(frame);
        let mut received = 1 + 1;
        logger.receive(|_| received += 1).expect("receive");
        let (got, skipped) = logger.tally();
        assert_eq!(received, got.total());
        assert_eq!((got.frames, skipped.frames), (1 + SUBSCRIBER_BUFFER as u64, 36), "frames: the oldest lost");
        assert_eq!((got.imu_samples, skipped.imu_samples), (1 + IMU_SUBSCRIBER_BUFFER as u64, 76), "IMU samples");
        assert_eq!(got.frames + skipped.frames, frames, "received + skipped = published");
        assert_eq!(got.imu_samples + skipped.imu_samples, samples);
    }

    #[test]
    fn a_logger_is_listening_once_subscribed_to_every_service_and_not_after() {
        let prefix = format!("dash2sim-test/bridge-listening/{}", std::process::id());
        assert!(!listening(&prefix).expect("no services yet"), "nothing under the prefix");
        let camera = CameraPublisher::new(&prefix, false).expect("publisher");
        assert!(!listening(&prefix).expect("services"), "a publisher alone is not a logger");
        let logger = CameraSubscriber::new(&prefix).expect("subscriber");
        assert!(listening(&prefix).expect("services"), "subscribed to all six services");
        drop(logger);
        assert!(!listening(&prefix).expect("services"), "the logger gone");
        drop(camera);
    }
}
