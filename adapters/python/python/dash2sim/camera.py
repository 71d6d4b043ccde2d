"""The camera side of dash2sim's shared-memory bridge, for camera processes in Python.

A VO (ORB-SLAM3, DROID-SLAM, MASt3R-SLAM) or a detector (PyTorch, ONNX Runtime) running in
Python publishes its poses and detections to ``dash2sim record --camera`` over iceoryx2,
with the same services and message layouts as the Rust ``CameraPublisher`` and the C ABI
(docs/bridge.md). Needs the ``iceoryx2`` package (``pip install "dash2sim[camera]"``)::

    from dash2sim.camera import Publisher, device_now_us

    with Publisher() as camera:                      # prefix "dash2sim/camera"
        t = device_now_us()                          # the logger's clock (CLOCK_MONOTONIC)
        camera.frame(42, t, exposure_us=8000)
        camera.vo(42, t, position, rotation)         # camera -> VO frame, any scale
        camera.detections3d(42, t, classes, boxes, scores)   # (N,), (N, 7), (N,)
        camera.detections2d(42, t, classes, boxes2d, scores2d)
        camera.imu(device_now_us(), gyro, accel)    # per IMU sample: rad/s, m/s^2

The message structures below mirror ``dash2sim_linux::record::bridge::messages``; the
package's tests compare their sizes, offsets and type names with what the Rust side reports
(``d2s_layout_json`` of the C ABI), so a field moved on one side fails there.
"""

from __future__ import annotations

import ctypes
import math
import time
from typing import Any, Optional, Sequence

import numpy as np

#: The message layout this module publishes (every message carries it).
LAYOUT_VERSION = 1
#: Detections one message carries at most.
MAX_DETECTIONS = 64
#: The largest image the image service carries, bytes (1920 x 1080 x 3).
MAX_IMAGE_BYTES = 1920 * 1080 * 3
#: The services' prefix unless told otherwise.
DEFAULT_PREFIX = "dash2sim/camera"
#: Samples the logger keeps per service (the services' setting; both sides must agree).
SUBSCRIBER_BUFFER = 64
#: Samples the logger keeps on the IMU service (2.56 s at 400 Hz).
IMU_SUBSCRIBER_BUFFER = 1024


class _Message(ctypes.Structure):
    """A bridge message: its iceoryx2 type name is ``dash2sim::<class name>``."""

    @classmethod
    def type_name(cls) -> str:
        return f"dash2sim::{cls.__name__}"


class FrameMetaMsg(_Message):
    _fields_ = [
        ("version", ctypes.c_uint32),
        ("exposure_us", ctypes.c_uint32),
        ("sequence", ctypes.c_uint64),
        ("device_time_us", ctypes.c_int64),
        ("image_bytes", ctypes.c_uint32),
        # IMU samples sent before this frame (their numbering): the logger holds the frame
        # until that sample is in.
        ("imu_published", ctypes.c_uint32),
    ]


class VoPoseMsg(_Message):
    _fields_ = [
        ("version", ctypes.c_uint32),
        ("session", ctypes.c_uint32),
        ("sequence", ctypes.c_uint64),
        ("device_time_us", ctypes.c_int64),
        ("position", ctypes.c_double * 3),
        ("rotation", ctypes.c_double * 9),
    ]


class Detection3dItem(_Message):
    _fields_ = [
        ("class", ctypes.c_uint16),
        ("reserved", ctypes.c_uint16),
        ("score", ctypes.c_float),
        ("bbox", ctypes.c_float * 7),
        ("covariance", ctypes.c_float * 3),
    ]


class Detections3dMsg(_Message):
    _fields_ = [
        ("version", ctypes.c_uint32),
        ("count", ctypes.c_uint32),
        ("sequence", ctypes.c_uint64),
        ("device_time_us", ctypes.c_int64),
        ("items", Detection3dItem * MAX_DETECTIONS),
    ]


class Detection2dItem(_Message):
    _fields_ = [
        ("class", ctypes.c_uint16),
        ("reserved", ctypes.c_uint16),
        ("score", ctypes.c_float),
        ("bbox", ctypes.c_float * 4),
    ]


class Detections2dMsg(_Message):
    _fields_ = [
        ("version", ctypes.c_uint32),
        ("count", ctypes.c_uint32),
        ("sequence", ctypes.c_uint64),
        ("device_time_us", ctypes.c_int64),
        ("items", Detection2dItem * MAX_DETECTIONS),
    ]


class KeepMsg(_Message):
    _fields_ = [
        ("version", ctypes.c_uint32),
        ("reserved", ctypes.c_uint32),
        ("device_time_us", ctypes.c_int64),
    ]


class ImuMsg(_Message):
    _fields_ = [
        ("version", ctypes.c_uint32),
        ("sequence", ctypes.c_uint32),
        ("device_time_us", ctypes.c_int64),
        ("gyro", ctypes.c_float * 3),
        ("accel", ctypes.c_float * 3),
    ]


#: Every message type, in the order the Rust side reports them.
MESSAGES = (
    FrameMetaMsg,
    VoPoseMsg,
    Detection3dItem,
    Detections3dMsg,
    Detection2dItem,
    Detections2dMsg,
    KeepMsg,
    ImuMsg,
)

#: The camera services under a prefix and their messages (a logger subscribes to all six).
_SERVICES = (
    ("frame", FrameMetaMsg),
    ("vo", VoPoseMsg),
    ("detections3d", Detections3dMsg),
    ("detections2d", Detections2dMsg),
    ("keep", KeepMsg),
    ("imu", ImuMsg),
)


def class_id(name: str) -> int:
    """The tracker's class id of a class name (``"car"``, ``"cone"``, ...: the work-zone
    profile, docs/tracking.md); 65535, which the tracker refuses and counts, for a name it
    does not know (as ``dash2sim record`` reads the detections CSV)."""
    from . import _native

    found = _native.class_id(name)
    return 0xFFFF if found is None else found


def logger_listening(prefix: str = DEFAULT_PREFIX) -> bool:
    """Whether a logger (``dash2sim record --camera``) has subscribed to every camera service
    under ``prefix``. A sample published before the logger subscribes is not kept for it, and
    a logger takes a moment to subscribe (longer on a busy machine): a camera process that
    must not lose its first frames polls this before it publishes them (the Rust side's
    ``record::bridge::listening``)."""
    iox = _iceoryx2()
    iox.set_log_level_from_env_or(iox.LogLevel.Error)
    node = _camera_node(iox)
    for leaf, message in _SERVICES:
        builder = node.service_builder(iox.ServiceName.new(f"{prefix}/{leaf}")).publish_subscribe(message)
        try:
            service = builder.open()
        except iox.PublishSubscribeOpenError as e:
            # Not yet, or not yet done: a logger starved of CPU creates its services slowly.
            if "DoesNotExist" in str(e) or "HangsInCreation" in str(e):
                return False
            raise BridgeError(f"{prefix}/{leaf}: {e!r}") from e
        if service.dynamic_config.number_of_subscribers == 0:
            return False
    return True


def device_now_us() -> int:
    """The device clock the logger stamps its other inputs with (CLOCK_MONOTONIC), µs."""
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC) // 1000


def micros(t_s: float) -> int:
    """Seconds to whole microseconds, rounded half away from zero as the Rust side does."""
    x = t_s * 1e6
    return int(math.floor(x + 0.5)) if x >= 0 else -int(math.floor(-x + 0.5))


def rotation_from_quaternion(w: float, x: float, y: float, z: float) -> np.ndarray:
    """The 3x3 rotation of a (not quite) unit quaternion, normalised inside the formula
    exactly as ``dash2sim record`` and evo read TUM files (bit for bit); the identity for a
    zero quaternion."""
    n = w * w + x * x + y * y + z * z
    if n < 4.0 * 2.220446049250313e-16:
        return np.eye(3)
    k = math.sqrt(2.0 / n)
    w, x, y, z = w * k, x * k, y * k, z * k
    return np.array(
        [
            [1.0 - y * y - z * z, x * y - z * w, x * z + y * w],
            [x * y + z * w, 1.0 - x * x - z * z, y * z - x * w],
            [x * z - y * w, y * z + x * w, 1.0 - x * x - y * y],
        ]
    )


class BridgeError(RuntimeError):
    """iceoryx2 refused (opening, loaning, sending), or an argument was out of range."""


def _iceoryx2() -> Any:
    try:
        import iceoryx2
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise BridgeError('dash2sim.camera needs iceoryx2: pip install "dash2sim[camera]"') from e
    return iceoryx2


#: How long opening a service waits for another process still creating it, s (iceoryx2's
#: default is 1 s; a logger starved of CPU takes longer: the Rust side's
#: ``record::bridge::CREATION_TIMEOUT``).
CREATION_TIMEOUT_S = 10


def _camera_node(iox: Any) -> Any:
    """A node of the camera's side, as the Rust side's (``record::bridge``, issue #57): it
    leaves the resources of camera processes that died to the logger, which removes them once
    it has drained them — iceoryx2's default has every new node remove them, and with them
    what a starved logger had not yet received."""
    config = iox.config.default()
    config.global_cfg.node.cleanup_dead_nodes_on_creation = False
    config.global_cfg.node.cleanup_dead_nodes_on_destruction = False
    config.global_cfg.service.cleanup_dead_nodes_on_open = False
    config.global_cfg.creation_timeout = iox.Duration.from_secs(CREATION_TIMEOUT_S)
    return iox.NodeBuilder.new().config(config).create(iox.ServiceType.Ipc)


def _rows(name: str, values: Any, width: Optional[int], count: int) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    shape = (count, width) if width else (count,)
    if array.shape != shape:
        raise BridgeError(f"{name}: shape {array.shape}, expected {shape}")
    if not np.all(np.isfinite(array)):
        raise BridgeError(f"{name}: not finite")
    return array


class ImageLoan:
    """An image being written straight into shared memory (``Publisher.loan_image``):
    ``array`` is a writable uint8 numpy view of it; ``Publisher.send_image`` publishes it."""

    def __init__(self, sample: Any, nbytes: int) -> None:
        self._sample = sample
        self.array = np.frombuffer(sample.payload().as_memory_view(), dtype=np.uint8, count=nbytes)


class Publisher:
    """Publishers on the bridge's services under ``prefix``; ``images`` adds the image
    service. Publish each frame's metadata first, then its VO pose, then its detections."""

    def __init__(self, prefix: str = DEFAULT_PREFIX, images: bool = False) -> None:
        iox = _iceoryx2()
        self._iox = iox
        iox.set_log_level_from_env_or(iox.LogLevel.Error)
        try:
            self._node = _camera_node(iox)
            self._frame = self._publisher(prefix, "frame", FrameMetaMsg)
            self._vo = self._publisher(prefix, "vo", VoPoseMsg)
            self._detections3d = self._publisher(prefix, "detections3d", Detections3dMsg)
            self._detections2d = self._publisher(prefix, "detections2d", Detections2dMsg)
            self._keep = self._publisher(prefix, "keep", KeepMsg)
            self._imu = self._service(prefix, "imu", ImuMsg, IMU_SUBSCRIBER_BUFFER).publisher_builder().create()
            # IMU samples sent (numbered 1, 2, ...: the logger counts the ones it missed).
            self._imu_sent = 0
            self._image = None
            if images:
                service = self._service(prefix, "image", iox.Slice[ctypes.c_uint8], 2)
                self._image = service.publisher_builder().initial_max_slice_len(MAX_IMAGE_BYTES).create()
        except Exception as e:
            if isinstance(e, BridgeError):
                raise
            raise BridgeError(f"{prefix}: {e!r} (a publisher or logger of another dash2sim message layout?)") from e

    def _service(self, prefix: str, leaf: str, payload: Any, buffer: int = SUBSCRIBER_BUFFER) -> Any:
        """The service `prefix/leaf`, opened (or created) with the logger's settings."""
        iox = self._iox
        return (
            self._node.service_builder(iox.ServiceName.new(f"{prefix}/{leaf}"))
            .publish_subscribe(payload)
            .subscriber_max_buffer_size(buffer)
            .enable_safe_overflow(True)
            .open_or_create()
        )

    def _publisher(self, prefix: str, leaf: str, message: type) -> Any:
        """A publisher on the service; when it already has its most publishers — those of camera
        processes that died, left for a logger to drain, and no logger clearing them — the dead
        ones are removed and it is made again."""
        service = self._service(prefix, leaf, message)
        try:
            return service.publisher_builder().create()
        except self._iox.PublisherCreateError as e:
            if "ExceedsMaxSupportedPublishers" not in str(e):
                raise
            service.try_cleanup_dead_nodes()
            return service.publisher_builder().create()

    def __enter__(self) -> "Publisher":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Closes the publishers (the logger sees the camera process go)."""
        for name in ("_image", "_frame", "_vo", "_detections3d", "_detections2d", "_keep", "_imu"):
            port = getattr(self, name, None)
            if port is not None:
                port.delete()
                setattr(self, name, None)
        self._node = None

    def _send(self, publisher: Any, message: ctypes.Structure) -> None:
        if publisher is None:
            raise BridgeError("the publisher is closed")
        try:
            publisher.send_copy(message)
        except Exception as e:
            raise BridgeError(f"send: {e!r}") from e

    def frame(self, sequence: int, device_time_us: int, exposure_us: int = 0, image: Any = None) -> None:
        """A frame's metadata and, with the image service on, its image (bytes or a uint8
        array, copied once into shared memory; ``loan_image`` avoids the copy)."""
        if image is not None and self._image is not None:
            data = np.frombuffer(memoryview(image).cast("B"), dtype=np.uint8)
            loan = self.loan_image(data.size)
            loan.array[:] = data
            self.send_image(loan, sequence, device_time_us, exposure_us)
            return
        self._send(self._frame, FrameMetaMsg(LAYOUT_VERSION, exposure_us, sequence, device_time_us, 0, self._imu_sent))

    def keep(self, device_time_us: int) -> None:
        """"Keep the file being recorded" (a button press, an event the camera saw): the
        logger protects the log file it is writing from loop recording's deletions."""
        self._send(self._keep, KeepMsg(LAYOUT_VERSION, 0, device_time_us))

    def imu(self, device_time_us: int, gyro: Sequence[float], accel: Sequence[float]) -> None:
        """One IMU sample on the sensor's own axes: the angular rate about x, y, z (rad/s)
        and the specific force along them (m/s^2; at rest +9.81 along "up"). The logger
        turns them to the camera's axes (``record --imu-mount``) and refuses a stream in g
        or deg/s with an error event; a value that is not finite is refused here."""
        g = _rows("gyro", gyro, None, 3)
        a = _rows("accel", accel, None, 3)
        self._imu_sent = (self._imu_sent + 1) % (1 << 32) or 1
        message = ImuMsg(LAYOUT_VERSION, self._imu_sent, device_time_us)
        message.gyro[:] = g.tolist()
        message.accel[:] = a.tolist()
        self._send(self._imu, message)

    def loan_image(self, nbytes: int) -> ImageLoan:
        """Shared memory for the next frame's image, ``nbytes`` long: write into
        ``loan.array`` and publish with ``send_image``."""
        if self._image is None:
            raise BridgeError("image loan: the publisher was opened without the image service")
        if not 0 <= nbytes <= MAX_IMAGE_BYTES:
            raise BridgeError(f"image of {nbytes} bytes: at most {MAX_IMAGE_BYTES}")
        try:
            return ImageLoan(self._image.loan_slice_uninit(nbytes), nbytes)
        except Exception as e:
            raise BridgeError(f"image loan: {e!r}") from e

    def send_image(self, loan: ImageLoan, sequence: int, device_time_us: int, exposure_us: int = 0) -> None:
        """The frame's metadata with the loaned image (the logger reads it in place)."""
        try:
            loan._sample.assume_init().send()
        except Exception as e:
            raise BridgeError(f"image send: {e!r}") from e
        size = loan.array.size
        self._send(self._frame, FrameMetaMsg(LAYOUT_VERSION, exposure_us, sequence, device_time_us, size, self._imu_sent))

    def vo(self, sequence: int, device_time_us: int, position: Sequence[float], rotation: Any, session: int = 0) -> None:
        """The VO pose of frame ``sequence``: the camera's position in the VO frame (any
        scale) and its rotation camera -> VO frame (3x3); ``session`` is 0 until the VO
        first re-initialises, then one more each time."""
        p = _rows("position", position, None, 3)
        r = _rows("rotation", rotation, 3, 3).reshape(9)
        message = VoPoseMsg(LAYOUT_VERSION, session, sequence, device_time_us)
        message.position[:] = p.tolist()
        message.rotation[:] = r.tolist()
        self._send(self._vo, message)

    def detections3d(
        self,
        sequence: int,
        device_time_us: int,
        classes: Sequence[int],
        boxes: Any,
        scores: Sequence[float],
        covariances: Any = None,
    ) -> None:
        """The 3D detections of frame ``sequence`` in the camera frame (x forward, y left,
        z up): class ids (N,), boxes (N, 7) as x, y, z, heading, length, width, height (m,
        rad), scores (N,), optionally the horizontal centre's covariance (N, 3) xx, xy, yy."""
        n = len(classes)
        if n > MAX_DETECTIONS:
            raise BridgeError(f"{n} 3D detections: at most {MAX_DETECTIONS}")
        message = Detections3dMsg(LAYOUT_VERSION, n, sequence, device_time_us)
        items = np.ctypeslib.as_array(message.items)
        items["class"][:n] = np.asarray(classes, dtype=np.uint16)
        items["score"][:n] = _rows("scores", scores, None, n)
        items["bbox"][:n] = _rows("boxes", boxes, 7, n)
        if covariances is not None:
            items["covariance"][:n] = _rows("covariances", covariances, 3, n)
        self._send(self._detections3d, message)

    def detections2d(
        self, sequence: int, device_time_us: int, classes: Sequence[int], boxes: Any, scores: Sequence[float]
    ) -> None:
        """The 2D detections of frame ``sequence``: class ids (N,), boxes (N, 4) as left,
        top, width, height in pixels, scores (N,)."""
        n = len(classes)
        if n > MAX_DETECTIONS:
            raise BridgeError(f"{n} 2D detections: at most {MAX_DETECTIONS}")
        message = Detections2dMsg(LAYOUT_VERSION, n, sequence, device_time_us)
        items = np.ctypeslib.as_array(message.items)
        items["class"][:n] = np.asarray(classes, dtype=np.uint16)
        items["score"][:n] = _rows("scores", scores, None, n)
        items["bbox"][:n] = _rows("boxes", boxes, 4, n)
        self._send(self._detections2d, message)
