//! The process's signals, which belong to the binary (the library takes flags): SIGINT and
//! SIGTERM stop the live logger, SIGUSR1 keeps the file being recorded.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use dash2sim_linux::{Error, Result};

/// A flag SIGINT and SIGTERM set: the live logger's stop.
pub fn stop_on_signals() -> Result<Arc<AtomicBool>> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, stop.clone()).map_err(|e| Error::refused("signal handler", e))?;
    }
    Ok(stop)
}

/// A flag SIGUSR1 sets: "keep the file being recorded" (the logger clears it once it has).
pub fn keep_on_signal() -> Result<Arc<AtomicBool>> {
    let keep = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, keep.clone())
        .map_err(|e| Error::refused("signal handler", e))?;
    Ok(keep)
}
