//! The demo on the real recordings of a data folder ([`crate::datasets`]). A recording whose
//! files are missing is named with what is missing, and the others run.

use std::path::{Path, PathBuf};

use serde::Serialize;

use super::Progress;
use crate::datasets::{self, comma, css};
use crate::{Error, Result};

/// What the demo came to on a data folder.
#[derive(Debug, Serialize)]
pub struct DataReport {
    /// The data folder.
    pub data: String,
    /// Each recording the demo knows, in its order.
    pub recordings: Vec<DataRecording>,
}

impl DataReport {
    /// The recordings that failed, each `name: why`.
    pub fn failures(&self) -> Vec<String> {
        self.recordings
            .iter()
            .filter_map(|r| match r {
                DataRecording::Failed { name, error, .. } => Some(format!("{name}: {error}")),
                _ => None,
            })
            .collect()
    }
}

/// One recording: what it came to, or why it did not run.
#[derive(Debug, Serialize)]
#[serde(untagged)]
pub enum DataRecording {
    /// The comma2k19 minute.
    Comma(Box<comma::Report>),
    /// The CSS Electronics CANedge drive.
    Css(Box<css::Report>),
    /// Not run: files are missing.
    Missing {
        /// The recording.
        name: &'static str,
        /// Where it was looked for.
        folder: String,
        /// What is missing.
        missing: Vec<String>,
    },
    /// Run, and failed.
    Failed {
        /// The recording.
        name: &'static str,
        /// Where it was.
        folder: String,
        /// Why it failed.
        error: String,
    },
}

/// One recording the demo knows: its folder, the files it needs, how it runs.
struct Known {
    name: &'static str,
    folder: &'static str,
    missing: fn(&Path) -> Vec<PathBuf>,
    run: fn(&Path, &Path) -> Result<DataRecording>,
    doing: &'static str,
}

const KNOWN: [Known; 2] = [
    Known {
        name: "comma2k19",
        folder: "comma2k19",
        missing: |dir| datasets::missing(dir, &comma::REQUIRED),
        run: |dir, out| comma::run(dir, out).map(|r| DataRecording::Comma(Box::new(r))),
        doing: "comma2k19: recording the u-blox NMEA, Toyota CAN and VO made from the fused poses; finishing; comparing with the fused poses",
    },
    Known {
        name: "css",
        folder: "css-electronics-canedge",
        missing: |dir| {
            let mut missing = datasets::missing(dir, &css::REQUIRED);
            if dir.is_dir() && css::splits(dir).is_empty() {
                missing.push(dir.join(format!("{}*.log", css::SPLITS)));
            }
            missing
        },
        run: |dir, out| css::run(dir, out).map(|r| DataRecording::Css(Box::new(r))),
        doing: "CSS CANedge: recording 40 minutes of GNSS over CAN (CANmod.gps through its DBC) and OBD-II speed",
    },
];

/// Run every recording found in `dir` into `out` (with `summary.json`); what they came to.
/// An error only when none could run.
pub fn run(dir: &Path, out: &Path, progress: &dyn Progress) -> Result<DataReport> {
    std::fs::create_dir_all(out).map_err(|e| Error::file(out, e))?;
    let mut recordings = Vec::new();
    let mut ran = 0;
    for (n, known) in KNOWN.iter().enumerate() {
        let folder = dir.join(known.folder);
        let missing = (known.missing)(&folder);
        if !missing.is_empty() {
            let missing: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
            progress.note(&format!("{} is missing, skipped: {}", known.name, missing.join(", ")));
            recordings.push(DataRecording::Missing { name: known.name, folder: folder.display().to_string(), missing });
            continue;
        }
        progress.step(n as u32 + 1, KNOWN.len() as u32, known.doing);
        progress.begin(None, known.name);
        let result = (known.run)(&folder, &out.join(known.name));
        progress.end();
        match result {
            Ok(recording) => {
                ran += 1;
                recordings.push(recording);
            }
            Err(e) => {
                progress.note(&format!("{}: {e}", known.name));
                recordings.push(DataRecording::Failed {
                    name: known.name,
                    folder: folder.display().to_string(),
                    error: e.to_string(),
                });
            }
        }
    }
    if ran == 0 {
        let names: Vec<String> =
            KNOWN.iter().map(|k| format!("{} ({})", k.name, dir.join(k.folder).display())).collect();
        return Err(Error::invalid(format!(
            "no recording could run from {}: looked for {}",
            dir.display(),
            names.join(" and ")
        )));
    }
    let report = DataReport { data: dir.display().to_string(), recordings };
    super::write_file(&out.join(super::SUMMARY_FILE), super::summary_json(&report)?)?;
    Ok(report)
}
