//! The camera → logger bridge: what crossing from the camera process costs.
//!
//! * Frame metadata, one way: a ping-pong between two threads, each message answered by an
//!   echo; one way = half the round trip. iceoryx2 through the bridge's own publisher and
//!   subscriber (`CameraPublisher::frame`, `CameraSubscriber::receive`, which polls all four
//!   camera services as the logger does) against a Unix-domain datagram socket carrying the
//!   same 32-byte message, read blocking (the usual way) and polled (like the logger polls).
//! * A 1920×1080×3 image: iceoryx2 hands the subscriber the sample where the publisher wrote
//!   it (zero-copy: the timed part is send → received → acknowledged, the image having been
//!   written into the loaned sample beforehand as a camera writes its frame buffer) against
//!   a Unix stream socket (the image copied into the kernel and out again).
//!
//! Before criterion's runs, the percentiles (p50, p99, p99.9) of each are printed from
//! 20 000 messages (200 images). Figures in docs/benchmarks.md.

use std::io::{Read, Write};
use std::os::unix::net::{UnixDatagram, UnixStream};
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use dash2sim_linux::record::bridge::{device_now, CameraInput, CameraPublisher, CameraSubscriber, MAX_IMAGE_BYTES};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory;

/// The echo side's stop signal: a frame number no camera sends.
const STOP: u64 = u64::MAX;

fn prefix(name: &str) -> String {
    format!("dash2sim-bench/{name}/{}", std::process::id())
}

/// The frame metadata message as bytes (the same 32 bytes the bridge's message holds).
fn frame_bytes(sequence: u64) -> [u8; 32] {
    let mut b = [0u8; 32];
    b[0..4].copy_from_slice(&1u32.to_le_bytes());
    b[4..8].copy_from_slice(&8_000u32.to_le_bytes());
    b[8..16].copy_from_slice(&sequence.to_le_bytes());
    b[16..24].copy_from_slice(&device_now().micros().to_le_bytes());
    b
}

fn sequence_of(b: &[u8; 32]) -> u64 {
    u64::from_le_bytes([b[8], b[9], b[10], b[11], b[12], b[13], b[14], b[15]])
}

/// A round trip through one transport: send frame `sequence`, wait for its echo.
trait RoundTrip {
    fn round_trip(&mut self, sequence: u64) -> Duration;
}

/// iceoryx2 both ways, through the bridge's own API; the echo runs in its own thread.
struct Iceoryx {
    forth: CameraPublisher,
    back: CameraSubscriber,
    echo: Option<std::thread::JoinHandle<()>>,
}

impl Iceoryx {
    fn new() -> Self {
        let (forth_prefix, back_prefix) = (prefix("forth"), prefix("back"));
        let back = CameraSubscriber::new(&back_prefix).expect("subscriber");
        let forth = CameraPublisher::new(&forth_prefix, false).expect("publisher");
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let echo = std::thread::spawn(move || {
            let incoming = CameraSubscriber::new(&forth_prefix).expect("echo subscriber");
            let reply = CameraPublisher::new(&back_prefix, false).expect("echo publisher");
            ready_tx.send(()).expect("ready");
            let mut running = true;
            while running {
                incoming
                    .receive(|input| {
                        if let CameraInput::Frame { sequence, t, .. } = input {
                            running = sequence != STOP;
                            reply.frame(sequence, t, 8_000, None).expect("echo");
                        }
                    })
                    .expect("receive");
            }
        });
        ready_rx.recv().expect("echo ready");
        Iceoryx { forth, back, echo: Some(echo) }
    }
}

impl RoundTrip for Iceoryx {
    fn round_trip(&mut self, sequence: u64) -> Duration {
        let start = Instant::now();
        self.forth.frame(sequence, device_now(), 8_000, None).expect("send");
        let mut back = false;
        while !back {
            self.back
                .receive(|input| back |= matches!(input, CameraInput::Frame { sequence: s, .. } if s == sequence))
                .expect("receive");
        }
        start.elapsed()
    }
}

impl Drop for Iceoryx {
    fn drop(&mut self) {
        let _ = self.forth.frame(STOP, device_now(), 0, None);
        if let Some(echo) = self.echo.take() {
            let _ = echo.join();
        }
    }
}

/// A Unix datagram socket pair; `polled` reads non-blocking in a loop, else blocking.
struct Socket {
    here: UnixDatagram,
    polled: bool,
    echo: Option<std::thread::JoinHandle<()>>,
}

fn receive(socket: &UnixDatagram, polled: bool) -> [u8; 32] {
    let mut b = [0u8; 32];
    loop {
        match socket.recv(&mut b) {
            Ok(32) => return b,
            Ok(n) => panic!("short datagram {n}"),
            Err(e) if polled && e.kind() == std::io::ErrorKind::WouldBlock => std::hint::spin_loop(),
            Err(e) => panic!("recv: {e}"),
        }
    }
}

impl Socket {
    fn new(polled: bool) -> Self {
        let (here, there) = UnixDatagram::pair().expect("socket pair");
        here.set_nonblocking(polled).expect("mode");
        there.set_nonblocking(polled).expect("mode");
        let echo = std::thread::spawn(move || loop {
            let b = receive(&there, polled);
            there.send(&b).expect("echo");
            if sequence_of(&b) == STOP {
                break;
            }
        });
        Socket { here, polled, echo: Some(echo) }
    }
}

impl RoundTrip for Socket {
    fn round_trip(&mut self, sequence: u64) -> Duration {
        let start = Instant::now();
        self.here.send(&frame_bytes(sequence)).expect("send");
        let b = receive(&self.here, self.polled);
        assert_eq!(sequence_of(&b), sequence);
        start.elapsed()
    }
}

impl Drop for Socket {
    fn drop(&mut self) {
        let _ = self.here.send(&frame_bytes(STOP));
        if let Some(echo) = self.echo.take() {
            let _ = echo.join();
        }
    }
}

/// A 1080p image through iceoryx2, zero-copy: the image service (a slice of bytes) one way,
/// a `u64` acknowledgement the other.
struct ImageZeroCopy {
    _node: Node<ipc::Service>,
    publisher: iceoryx2::port::publisher::Publisher<ipc::Service, [u8], ()>,
    acks: iceoryx2::port::subscriber::Subscriber<ipc::Service, u64, ()>,
    image: Vec<u8>,
    echo: Option<std::thread::JoinHandle<()>>,
}

fn byte_service(node: &Node<ipc::Service>, name: &str) -> PortFactory<ipc::Service, [u8], ()> {
    node.service_builder(&ServiceName::new(name).expect("name"))
        .publish_subscribe::<[u8]>()
        .subscriber_max_buffer_size(2)
        .open_or_create()
        .expect("image service")
}

fn ack_service(node: &Node<ipc::Service>, name: &str) -> PortFactory<ipc::Service, u64, ()> {
    node.service_builder(&ServiceName::new(name).expect("name"))
        .publish_subscribe::<u64>()
        .open_or_create()
        .expect("ack service")
}

impl ImageZeroCopy {
    fn new() -> Self {
        let (images, acks) = (prefix("image"), prefix("image-ack"));
        let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
        let publisher = byte_service(&node, &images)
            .publisher_builder()
            .initial_max_slice_len(MAX_IMAGE_BYTES)
            .create()
            .expect("publisher");
        let ack_subscriber = ack_service(&node, &acks).subscriber_builder().create().expect("subscriber");
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let echo = std::thread::spawn(move || {
            let node = NodeBuilder::new().create::<ipc::Service>().expect("node");
            let incoming = byte_service(&node, &images).subscriber_builder().create().expect("subscriber");
            let reply = ack_service(&node, &acks).publisher_builder().create().expect("publisher");
            ready_tx.send(()).expect("ready");
            loop {
                if let Some(sample) = incoming.receive().expect("receive") {
                    // The logger reads the image where it lies: its first and last bytes.
                    let (first, last) = (sample[0], sample[sample.len() - 1]);
                    reply.send_copy(u64::from(first) + u64::from(last)).expect("ack");
                    if sample.len() == 1 {
                        break;
                    }
                }
            }
        });
        ready_rx.recv().expect("echo ready");
        ImageZeroCopy {
            _node: node,
            publisher,
            acks: ack_subscriber,
            image: vec![0x80; MAX_IMAGE_BYTES],
            echo: Some(echo),
        }
    }
}

impl RoundTrip for ImageZeroCopy {
    fn round_trip(&mut self, _: u64) -> Duration {
        // The camera writes its frame into the loaned sample (not timed: it writes it somewhere
        // whichever the transport); the transport's part is send → received → acknowledged.
        let sample = self.publisher.loan_slice_uninit(MAX_IMAGE_BYTES).expect("loan").write_from_slice(&self.image);
        let start = Instant::now();
        sample.send().expect("send");
        while self.acks.receive().expect("ack").is_none() {
            std::hint::spin_loop();
        }
        start.elapsed()
    }
}

impl Drop for ImageZeroCopy {
    fn drop(&mut self) {
        if let Ok(sample) = self.publisher.loan_slice_uninit(1) {
            let _ = sample.write_from_slice(&[0]).send();
        }
        if let Some(echo) = self.echo.take() {
            let _ = echo.join();
        }
    }
}

/// A 1080p image through a Unix stream socket: copied into the kernel and out again.
struct ImageCopied {
    here: UnixStream,
    image: Vec<u8>,
    echo: Option<std::thread::JoinHandle<()>>,
}

impl ImageCopied {
    fn new() -> Self {
        let (here, mut there) = UnixStream::pair().expect("stream pair");
        let echo = std::thread::spawn(move || {
            let mut image = vec![0u8; MAX_IMAGE_BYTES];
            while there.read_exact(&mut image).is_ok() {
                if there.write_all(&[image[0] ^ image[MAX_IMAGE_BYTES - 1]]).is_err() {
                    break;
                }
            }
        });
        ImageCopied { here, image: vec![0x80; MAX_IMAGE_BYTES], echo: Some(echo) }
    }
}

impl RoundTrip for ImageCopied {
    fn round_trip(&mut self, _: u64) -> Duration {
        let start = Instant::now();
        self.here.write_all(&self.image).expect("send");
        let mut ack = [0u8; 1];
        self.here.read_exact(&mut ack).expect("ack");
        start.elapsed()
    }
}

impl Drop for ImageCopied {
    fn drop(&mut self) {
        let _ = self.here.shutdown(std::net::Shutdown::Both);
        if let Some(echo) = self.echo.take() {
            let _ = echo.join();
        }
    }
}

/// One-way times (half the round trip), µs, after `warm` unmeasured round trips.
fn one_way_us(transport: &mut dyn RoundTrip, n: usize, warm: usize) -> Vec<f64> {
    for i in 0..warm {
        transport.round_trip(i as u64);
    }
    let mut times: Vec<f64> =
        (0..n).map(|i| transport.round_trip((warm + i) as u64).as_secs_f64() * 1e6 / 2.0).collect();
    times.sort_by(f64::total_cmp);
    times
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn print_percentiles(name: &str, transport: &mut dyn RoundTrip, n: usize) {
    let t = one_way_us(transport, n, n / 10);
    println!(
        "{name:<44} one way p50 {:>9.2} µs  p99 {:>9.2} µs  p99.9 {:>9.2} µs  ({n} messages)",
        percentile(&t, 0.5),
        percentile(&t, 0.99),
        percentile(&t, 0.999)
    );
}

fn bridge(c: &mut Criterion) {
    print_percentiles("frame metadata, iceoryx2 (bridge API, polled)", &mut Iceoryx::new(), 20_000);
    print_percentiles("frame metadata, Unix datagram socket, blocking", &mut Socket::new(false), 20_000);
    print_percentiles("frame metadata, Unix datagram socket, polled", &mut Socket::new(true), 20_000);
    print_percentiles("1080p image, iceoryx2 zero-copy", &mut ImageZeroCopy::new(), 200);
    print_percentiles("1080p image, Unix stream socket (copied)", &mut ImageCopied::new(), 200);

    let mut group = c.benchmark_group("bridge round trip");
    let mut time = |name: &str, transport: &mut dyn RoundTrip| {
        group.bench_function(name, |b| {
            b.iter_custom(|iterations| (0..iterations).map(|i| transport.round_trip(i)).sum());
        });
    };
    time("frame metadata iceoryx2", &mut Iceoryx::new());
    time("frame metadata uds blocking", &mut Socket::new(false));
    time("frame metadata uds polled", &mut Socket::new(true));
    time("1080p image iceoryx2 zero-copy", &mut ImageZeroCopy::new());
    time("1080p image uds copied", &mut ImageCopied::new());
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).measurement_time(Duration::from_secs(3));
    targets = bridge
}
criterion_main!(benches);
