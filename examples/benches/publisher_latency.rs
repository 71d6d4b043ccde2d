//! One frame-metadata message from a camera process in Rust, C and Python into the logger's
//! subscriber: one way, across processes.
//!
//! Each publisher is a separate process sending 5 000 messages, one a millisecond, each
//! stamped with the device clock (`CLOCK_MONOTONIC`, the same in every process) just before
//! it is sent: Rust through `CameraPublisher::frame` (this bench run again as the publisher),
//! C through the C ABI (`examples/camera-c/latency.c`, compiled here with `cc`), Python
//! through `dash2sim.camera` (`adapters/python/examples/latency.py`, with the interpreter in
//! `$DASH2SIM_PYTHON`; skipped, and said so, without it). This process busy-polls
//! `CameraSubscriber::receive` as the logger does and takes now − stamp for each message.
//! The stamps are whole microseconds, so each latency is good to ±1 µs.
//!
//! `DASH2SIM_PYTHON=target/ci-venv/bin/python cargo bench -p dash2sim-examples --bench publisher_latency`
//! (figures in docs/benchmarks.md).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use dash2sim_linux::record::bridge::{device_now, CameraInput, CameraPublisher, CameraSubscriber};

const MESSAGES: u64 = 5_000;
/// Set in the environment of this bench run as the Rust publisher.
const PUBLISH: &str = "DASH2SIM_LATENCY_PUBLISH";

fn publish_rust(prefix: &str) {
    let camera = CameraPublisher::new(prefix, false).expect("publisher");
    for k in 1..=MESSAGES {
        std::thread::sleep(Duration::from_millis(1));
        camera.frame(k, device_now(), 0, None).expect("publish");
    }
    std::thread::sleep(Duration::from_millis(500));
}

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("workspace").to_path_buf()
}

/// The C publisher, compiled against the header and the shared library beside this bench.
fn c_publisher(deps: &Path) -> PathBuf {
    let exe = std::env::temp_dir().join(format!("dash2sim-latency-c-{}", std::process::id()));
    let status = Command::new("cc")
        .args(["-std=c11", "-O2", "-I"])
        .arg(workspace().join("adapters/camera-c/include"))
        .arg(workspace().join("examples/camera-c/latency.c"))
        .arg("-L")
        .arg(deps)
        .arg(format!("-Wl,-rpath,{}", deps.display()))
        .args(["-ldash2sim_camera", "-o"])
        .arg(&exe)
        .status()
        .expect("cc");
    assert!(status.success(), "cc failed");
    exe
}

/// Latencies (µs) of the messages `publisher` sends on `prefix`, as received here.
fn measure(prefix: &str, publisher: &mut Command) -> Vec<i64> {
    let subscriber = CameraSubscriber::new(prefix).expect("subscriber");
    let mut child: Child = publisher.stdout(Stdio::null()).spawn().expect("publisher");
    let mut latencies = Vec::with_capacity(MESSAGES as usize);
    let deadline = Instant::now() + Duration::from_secs(120);
    while latencies.len() < MESSAGES as usize && Instant::now() < deadline {
        subscriber
            .receive(|input| {
                if let CameraInput::Frame { t, .. } = input {
                    latencies.push(device_now().micros() - t.micros());
                }
            })
            .expect("receive");
    }
    let status = child.wait().expect("publisher");
    assert!(status.success(), "the publisher failed");
    latencies
}

fn percentile(sorted: &[i64], p: f64) -> i64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    if let Ok(prefix) = std::env::var(PUBLISH) {
        publish_rust(&prefix);
        return;
    }
    // `cargo bench` passes `--bench`; anything else (a filter, `--test`) is ignored.
    let me = std::env::current_exe().expect("bench binary");
    let deps = me.parent().expect("deps").to_path_buf();
    let prefix = |name: &str| format!("dash2sim-bench/latency/{name}/{}", std::process::id());
    let mut runs: Vec<(&str, Option<Command>)> = Vec::new();
    let mut rust = Command::new(&me);
    rust.env(PUBLISH, prefix("rust"));
    runs.push(("Rust (CameraPublisher::frame)", Some(rust)));
    let mut c = Command::new(c_publisher(&deps));
    c.args([prefix("c"), MESSAGES.to_string()]);
    runs.push(("C (d2s_publish_frame)", Some(c)));
    let python = std::env::var_os("DASH2SIM_PYTHON").map(|python| {
        let mut py = Command::new(python);
        py.arg(workspace().join("adapters/python/examples/latency.py")).args([prefix("python"), MESSAGES.to_string()]);
        py
    });
    runs.push(("Python (dash2sim.camera.Publisher.frame)", python));

    println!("one frame-metadata message, publisher process -> this subscriber, {MESSAGES} messages at 1 kHz (µs, ±1)");
    println!("| publisher | received | p50 | p99 | p99.9 | max |");
    println!("|---|---|---|---|---|---|");
    for (name, command) in runs {
        let Some(mut command) = command else {
            println!("| {name} | skipped: set DASH2SIM_PYTHON to a Python with dash2sim[camera] | | | | |");
            continue;
        };
        let leaf = name.split(' ').next().unwrap_or("x").to_lowercase();
        let mut latencies = measure(&prefix(&leaf), &mut command);
        if latencies.is_empty() {
            println!("| {name} | nothing received | | | | |");
            continue;
        }
        latencies.sort_unstable();
        let (n, max) = (latencies.len(), latencies.last().copied().unwrap_or(0));
        println!(
            "| {name} | {n} | {} | {} | {} | {max} |",
            percentile(&latencies, 0.5),
            percentile(&latencies, 0.99),
            percentile(&latencies, 0.999)
        );
    }
}
