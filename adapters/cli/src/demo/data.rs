//! `dash2sim demo --data DIR`: the real recordings of a data folder through the product
//! ([`dash2sim_sim::datasets`]). A recording whose files are missing is named with what is
//! missing, and the others run.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use super::progress::Progress;
use dash2sim_linux::{Error, Result};
use dash2sim_sim::datasets::{self, comma, css};

/// One recording the demo knows: its folder, the files it needs, how it runs.
struct Known {
    name: &'static str,
    folder: &'static str,
    missing: fn(&Path) -> Vec<PathBuf>,
    run: fn(&Path, &Path) -> Result<Value>,
    doing: &'static str,
}

const KNOWN: [Known; 2] = [
    Known {
        name: "comma2k19",
        folder: "comma2k19",
        missing: |dir| datasets::missing(dir, &comma::REQUIRED),
        run: |dir, out| comma::run(dir, out).and_then(|r| crate::render::json_of(&r)),
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
        run: |dir, out| css::run(dir, out).and_then(|r| crate::render::json_of(&r)),
        doing: "CSS CANedge: recording 40 minutes of GNSS over CAN (CANmod.gps through its DBC) and OBD-II speed",
    },
];

/// Run every recording found in `dir` into `out`; the summary. An error only when none
/// could run.
pub fn run(dir: &Path, out: &Path, progress: &Progress) -> Result<Value> {
    let mut results = Vec::new();
    let mut ran = 0;
    for (n, known) in KNOWN.iter().enumerate() {
        let folder = dir.join(known.folder);
        let missing = (known.missing)(&folder);
        if !missing.is_empty() {
            let list: Vec<String> = missing.iter().map(|p| p.display().to_string()).collect();
            eprintln!("dash2sim demo: {} is missing, skipped: {}", known.name, list.join(", "));
            results.push(json!({"name": known.name, "folder": folder.display().to_string(), "missing": list}));
            continue;
        }
        progress.step(n as u32 + 1, KNOWN.len() as u32, known.doing);
        let spinner = progress.spinner(known.name);
        let result = (known.run)(&folder, &out.join(known.name));
        spinner.finish_and_clear();
        match result {
            Ok(summary) => {
                ran += 1;
                results.push(summary);
            }
            Err(e) => {
                eprintln!("dash2sim demo: {}: {e}", known.name);
                results
                    .push(json!({"name": known.name, "folder": folder.display().to_string(), "error": e.to_string()}));
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
    Ok(json!({"data": dir.display().to_string(), "recordings": results}))
}
