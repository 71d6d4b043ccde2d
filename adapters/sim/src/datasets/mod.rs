//! The real recordings of the shared data folder through the product (`dash2sim demo
//! --data`): comma2k19's minute ([`comma`]: real u-blox NMEA and Toyota CAN, VO made from
//! comma's fused poses) and CSS Electronics' CANedge drive ([`css`]: GNSS over CAN and
//! OBD-II speed, no camera). Each is recorded by the on-device pipeline, finished where
//! there is VO to finish, exported, and measured against what the recording's own
//! references say.

pub mod comma;
pub mod comma_imu;
pub mod css;

use crate::{Error, Result};
use std::path::{Path, PathBuf};

/// A file a recording's run wrote, and what it holds.
#[derive(Clone, Debug, serde::Serialize)]
pub struct OutputFile {
    /// What the file holds and what it is for.
    pub what: &'static str,
    /// Where it was written.
    pub path: String,
}

impl OutputFile {
    pub(crate) fn new(what: &'static str, dir: &Path, name: &str) -> Self {
        Self { what, path: dir.join(name).display().to_string() }
    }
}

/// The data folder `--data` defaults to: `$DASH2SIM_DATA`, else `../shared/data`.
pub fn default_dir() -> PathBuf {
    std::env::var_os("DASH2SIM_DATA").map_or_else(|| PathBuf::from("../shared/data"), PathBuf::from)
}

/// The files of `required` (relative to `dir`) that are not there; the folder alone
/// when it is not there.
pub fn missing(dir: &Path, required: &[&str]) -> Vec<PathBuf> {
    if !dir.is_dir() {
        return vec![dir.to_path_buf()];
    }
    required.iter().map(|f| dir.join(f)).filter(|p| !p.is_file()).collect()
}

/// Device time of every record of a log: its UTC minus the clock offset in force when it
/// was written (records before the first offset were moved onto UTC with it by the
/// reader). An error when the log never learnt UTC.
pub fn device_times(records: &[dash2sim_core::binlog::Record]) -> Result<Vec<f64>> {
    use dash2sim_core::binlog::Record;
    let mut offset = records
        .iter()
        .find_map(|r| if let Record::ClockOffset(c) = r { Some(c.offset_us) } else { None })
        .ok_or_else(|| Error::invalid("the log has no clock offset: no GNSS time reached it"))?;
    Ok(records
        .iter()
        .map(|r| {
            if let Record::ClockOffset(c) = r {
                offset = c.offset_us;
            }
            (r.t_us() - offset) as f64 * 1e-6
        })
        .collect())
}

fn write(path: &Path, contents: impl AsRef<[u8]>) -> Result<()> {
    std::fs::write(path, contents).map_err(|e| Error::file(path, e))
}
