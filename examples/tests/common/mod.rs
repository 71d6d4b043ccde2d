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
