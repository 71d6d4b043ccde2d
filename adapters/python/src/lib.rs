//! `dash2sim._native`: the Rust side of the dash2sim Python package.
//!
//! A thin layer: each function calls the same library function as the command line
//! (`dash2sim finish`, `verify`, `export`, `inspect`), so a verdict from Python is the
//! command line's verdict on the same log. Every call releases the GIL while Rust works,
//! so Python threads (and Dask's threaded workers) run logs side by side. Errors come back
//! as `dash2sim.Dash2SimError` carrying the Rust message. Reports cross as JSON text and
//! tables as Arrow IPC streams; `python/dash2sim/__init__.py` turns them into `dict`s and
//! `pyarrow.Table`s, so this module needs no Python-side types of its own.

use std::path::PathBuf;

use dash2sim_core::obb::{Footprint, PACIFICA};
use dash2sim_export::parquet;
use dash2sim_export::ExportRequest;
use dash2sim_finish::FinishRequest;
use dash2sim_linux::log;
use dash2sim_linux::record::{Device, VoFrame};
use dash2sim_verify::{EgoSource, VerifyRequest};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

create_exception!(
    _native,
    Dash2SimError,
    PyException,
    "An error from dash2sim: the message is the command line's, naming the file and what was wrong."
);

fn error(e: impl std::fmt::Display) -> PyErr {
    Dash2SimError::new_err(e.to_string())
}

/// The log's id: `log_id` if given, else the file's name without its extension (as
/// `dash2sim export --parquet` does).
fn id_of(path: &std::path::Path, log_id: Option<String>) -> String {
    log_id.unwrap_or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default())
}

/// Read a log into Arrow IPC streams, one per record kind: `[(name, stream bytes)]`.
#[pyfunction]
#[pyo3(signature = (path, log_id = None))]
fn read_log(py: Python<'_>, path: PathBuf, log_id: Option<String>) -> PyResult<Vec<(String, Py<PyBytes>)>> {
    let streams = py
        .detach(|| -> dash2sim_linux::Result<Vec<(&'static str, Vec<u8>)>> {
            let log = log::read(&path).map_err(dash2sim_linux::Error::other)?;
            let tables = parquet::tables(&log, &id_of(&path, log_id))?;
            tables
                .tables
                .iter()
                .map(|(name, batch)| Ok((*name, parquet::ipc_stream(batch, &tables.metadata)?)))
                .collect()
        })
        .map_err(error)?;
    Ok(streams.into_iter().map(|(name, bytes)| (name.to_owned(), PyBytes::new(py, &bytes).unbind())).collect())
}

/// What a log holds (`dash2sim inspect --json`), as JSON text.
#[pyfunction]
fn inspect(py: Python<'_>, path: PathBuf) -> PyResult<String> {
    py.detach(|| {
        let log = log::read(&path).map_err(dash2sim_linux::Error::other)?;
        let report = serde_json::to_value(log::inspect::report(&log)).map_err(dash2sim_linux::Error::other)?;
        Ok::<_, dash2sim_linux::Error>(report.to_string())
    })
    .map_err(error)
}

/// Finish a log (`dash2sim finish --json`): the report as JSON text.
#[pyfunction]
#[pyo3(signature = (log, output, map = None, anchors = None, mount = "1.8,0,1.3".to_owned(), mode = "gravity", uere = 2.5, keyframe = 0.5, require_signed = None, factor_graph = None))]
#[allow(clippy::too_many_arguments)]
fn finish(
    py: Python<'_>,
    log: PathBuf,
    output: PathBuf,
    map: Option<PathBuf>,
    anchors: Option<PathBuf>,
    mount: String,
    mode: &str,
    uere: f64,
    keyframe: f64,
    require_signed: Option<&str>,
    factor_graph: Option<PathBuf>,
) -> PyResult<String> {
    let require_signed = require_signed.map(log::signing::read_public).transpose().map_err(error)?;
    let mode = match mode {
        "gravity" => VoFrame::Gravity,
        "full" => VoFrame::Full,
        other => return Err(error(format!("mode {other:?}: give \"gravity\" or \"full\""))),
    };
    let mount = dash2sim_linux::record::parse_mount(&mount).map_err(|e| error(format!("mount {mount:?}: {e}")))?;
    let device = Device { mount, mode, uere, ..Device::default() };
    let args = FinishRequest { log, output, anchors, map, device, keyframe, require_signed, factor_graph };
    py.detach(|| {
        let finished = dash2sim_finish::finish_file(&args)?;
        serde_json::to_value(finished).map(|report| report.to_string()).map_err(dash2sim_linux::Error::other)
    })
    .map_err(error)
}

/// Replay a log's ego against a map tile and score it (`dash2sim verify --json`).
#[pyfunction]
#[pyo3(signature = (log, map, channel_sensitive = false, start = None, end = None, footprint = None, decide_at = None, object_sigma = None))]
#[allow(clippy::too_many_arguments)] // Python's keyword arguments, one each
fn verify(
    py: Python<'_>,
    log: PathBuf,
    map: PathBuf,
    channel_sensitive: bool,
    start: Option<f64>,
    end: Option<f64>,
    footprint: Option<(f64, f64, f64)>,
    decide_at: Option<f64>,
    object_sigma: Option<f64>,
) -> PyResult<String> {
    let defaults = dash2sim_verify::decide::DoubtSettings::default();
    let doubt = dash2sim_verify::decide::DoubtSettings {
        decide_at: decide_at.unwrap_or(defaults.decide_at),
        object_sigma_m: object_sigma.unwrap_or(defaults.object_sigma_m),
    };
    if !(doubt.decide_at >= 0.0
        && doubt.object_sigma_m >= 0.0
        && doubt.decide_at.is_finite()
        && doubt.object_sigma_m.is_finite())
    {
        return Err(error("decide_at and object_sigma must be finite and ≥ 0".to_owned()));
    }
    let footprint = footprint.map_or(PACIFICA, |(width, front, rear)| Footprint { width, front, rear });
    if !(footprint.width > 0.0 && footprint.front + footprint.rear > 0.0) {
        return Err(error("footprint: the width and front + rear must be positive".to_owned()));
    }
    let request = VerifyRequest {
        map: &map,
        ego: EgoSource::Log(&log),
        objects: None,
        channel_sensitive,
        footprint,
        poses: None,
        window: (start.unwrap_or(f64::NEG_INFINITY), end.unwrap_or(f64::INFINITY)),
        doubt,
    };
    py.detach(|| {
        let (verification, _) = dash2sim_verify::evaluate(&request, &mut |warning| eprintln!("warning: {warning}"))?;
        Ok::<_, dash2sim_linux::Error>(
            serde_json::to_value(dash2sim_verify::report(&verification, channel_sensitive))
                .map_err(dash2sim_linux::Error::other)?
                .to_string(),
        )
    })
    .map_err(error)
}

/// Export a log (`dash2sim export`): a warning if the log was damaged, and a line per output.
#[pyfunction]
#[pyo3(signature = (log, parquet = None, log_id = None, tum = None, geojson = None, mcap = None, nuplan = None, map = None, commonroad = None, scenarionet = None, openscenario = None, scenario_seconds = None))]
#[allow(clippy::too_many_arguments)]
fn export(
    py: Python<'_>,
    log: PathBuf,
    parquet: Option<PathBuf>,
    log_id: Option<String>,
    tum: Option<PathBuf>,
    geojson: Option<PathBuf>,
    mcap: Option<PathBuf>,
    nuplan: Option<PathBuf>,
    map: Option<PathBuf>,
    commonroad: Option<PathBuf>,
    scenarionet: Option<PathBuf>,
    openscenario: Option<PathBuf>,
    scenario_seconds: Option<f64>,
) -> PyResult<(Option<String>, Vec<String>)> {
    let request = ExportRequest {
        log,
        mcap,
        tum,
        geojson,
        parquet,
        log_id,
        nuplan,
        commonroad,
        scenarionet,
        openscenario,
        map,
        scenario_seconds,
        map_name: None,
    };
    let exported = py.detach(|| dash2sim_export::export(&request)).map_err(error)?;
    Ok((exported.warning, exported.written))
}

/// The tracker's class id of a class name (`"car"`, `"cone"`, …: the work-zone profile), or
/// None: what a camera process publishes as a detection's class (`dash2sim.camera`).
#[pyfunction]
fn class_id(name: &str) -> Option<u16> {
    dash2sim_core::pipeline::profile::class_id(name)
}

/// The module `dash2sim._native`.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("Dash2SimError", m.py().get_type::<Dash2SimError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(read_log, m)?)?;
    m.add_function(wrap_pyfunction!(inspect, m)?)?;
    m.add_function(wrap_pyfunction!(finish, m)?)?;
    m.add_function(wrap_pyfunction!(verify, m)?)?;
    m.add_function(wrap_pyfunction!(export, m)?)?;
    m.add_function(wrap_pyfunction!(class_id, m)?)?;
    Ok(())
}
