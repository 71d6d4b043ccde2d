//! What a simulator export of scenarios is asked: the log, its map, where to write, the
//! windows.

use std::path::Path;

use dash2sim_linux::log::LogContents;

/// What a simulator export of scenarios (CommonRoad, ScenarioNet) is asked.
#[derive(Clone, Debug)]
pub struct ScenarioRequest<'a> {
    /// The log, read.
    pub log: &'a LogContents,
    /// Its name, for messages and the files' metadata.
    pub log_name: &'a str,
    /// The map tile's bytes.
    pub tile: &'a [u8],
    /// Where to write (a file or a folder, as the format has it).
    pub out: &'a Path,
    /// One scenario per window of this length, s (`None`: one for the whole log).
    pub window_s: Option<f64>,
}
