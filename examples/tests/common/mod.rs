//! What the live tests share: waiting for something to happen, never for a time to pass.

use std::time::Duration;

/// How long a test waits for something that takes a moment on an idle machine (a logger
/// subscribing, a publisher's first frames) before it gives up: generous, since these
/// tests also run starved of CPU (issue #57: at nice 19 beside a CPU hog on every core).
pub const PATIENCE: Duration = Duration::from_secs(300);

/// Wait, polling, until `ready` holds; panics after [`PATIENCE`] saying `what`.
pub fn wait_for(what: &str, mut ready: impl FnMut() -> bool) {
    let start = std::time::Instant::now();
    while !ready() {
        assert!(start.elapsed() < PATIENCE, "gave up waiting for {what} after {PATIENCE:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// `program` as a command, at the niceness `DASH2SIM_TEST_RECORDER_NICE` names when set:
/// how the starved runs of issue #57 put the recorder (and only it) at low priority beside
/// a CPU hog, as a dashcam's recorder runs beside its video encoder.
#[allow(dead_code)] // live_record.rs runs its recorder in a thread of its own process
pub fn recorder(program: &std::path::Path) -> std::process::Command {
    match std::env::var("DASH2SIM_TEST_RECORDER_NICE") {
        Ok(nice) => {
            let mut command = std::process::Command::new("nice");
            command.args(["-n", &nice]).arg(program);
            command
        }
        Err(_) => std::process::Command::new(program),
    }
}

/// A test's own subscriber to a camera's services, beside the logger's: it counts the
/// frames published, so a test acts on what happened (kill a camera process once it has
/// published) rather than on how long it waited.
pub struct FrameWatch {
    subscriber: dash2sim_linux::record::bridge::CameraSubscriber,
    frames: u64,
}

impl FrameWatch {
    /// Subscribed to the services under `prefix`.
    pub fn new(prefix: &str) -> Self {
        let subscriber =
            dash2sim_linux::record::bridge::CameraSubscriber::beside(prefix).expect("the test's subscriber");
        FrameWatch { subscriber, frames: 0 }
    }

    /// Frames received so far.
    pub fn frames(&mut self) -> u64 {
        let frames = &mut self.frames;
        self.subscriber
            .receive(|input| {
                *frames += u64::from(matches!(input, dash2sim_linux::record::bridge::CameraInput::Frame { .. }))
            })
            .expect("receive");
        *frames
    }
}
