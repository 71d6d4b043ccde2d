//! `dash2sim export --parquet DIR`: a log as one Parquet file per record kind, for the
//! tools a fleet's results are queried with (DuckDB, pandas/pyarrow, Spark) — typed
//! columns in SI units, UTC timestamps, the log's id in every row and its id and origin in
//! each file's metadata. The schema is `docs/parquet.md`'s (CI checks the files against it).
//! Written with the Apache Arrow Rust crates (`arrow-array`, `parquet`), zstd-compressed.

use std::path::Path;
use std::sync::Arc;

use arrow_array::{
    ArrayRef, BooleanArray, Float64Array, Int64Array, RecordBatch, StringArray, TimestampMicrosecondArray,
};
use arrow_ipc::writer::StreamWriter;
use arrow_schema::{DataType, Field, Schema, TimeUnit};
use dash2sim_core::binlog::Record;
use dash2sim_core::geo::Geodetic;
use parquet::arrow::ArrowWriter;
use parquet::basic::{Compression, ZstdLevel};
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;

use dash2sim_core::class::name_of as class_name;
use dash2sim_linux::log::views::tracks;
use dash2sim_linux::log::{frame, LogContents};
use dash2sim_linux::{Error, Result};

/// The version of the schema in `docs/parquet.md`, in every file's metadata.
pub const SCHEMA_VERSION: &str = "1";

/// The files `export --parquet` writes, in order.
pub const TABLES: [&str; 7] = ["ego", "gnss", "speed", "anchors", "tracks3d", "verification", "events"];

/// One table's columns as they are built: the log's id and the time first.
struct Table {
    fields: Vec<Field>,
    arrays: Vec<ArrayRef>,
}

impl Table {
    fn new(log_id: &str, t_us: Vec<i64>) -> Self {
        let rows = t_us.len();
        let mut table = Table { fields: Vec::new(), arrays: Vec::new() };
        table.push("log_id", DataType::Utf8, false, Arc::new(StringArray::from(vec![log_id; rows])));
        let t = TimestampMicrosecondArray::from(t_us).with_timezone("UTC");
        table.push("t", DataType::Timestamp(TimeUnit::Microsecond, Some("UTC".into())), false, Arc::new(t));
        table
    }

    fn push(&mut self, name: &str, data_type: DataType, nullable: bool, array: ArrayRef) {
        self.fields.push(Field::new(name, data_type, nullable));
        self.arrays.push(array);
    }

    fn f64(mut self, name: &str, values: Vec<f64>) -> Self {
        self.push(name, DataType::Float64, false, Arc::new(Float64Array::from(values)));
        self
    }

    fn f64_or_null(mut self, name: &str, values: Vec<Option<f64>>) -> Self {
        self.push(name, DataType::Float64, true, Arc::new(Float64Array::from(values)));
        self
    }

    fn i64(mut self, name: &str, values: Vec<i64>) -> Self {
        self.push(name, DataType::Int64, false, Arc::new(Int64Array::from(values)));
        self
    }

    fn i64_or_null(mut self, name: &str, values: Vec<Option<i64>>) -> Self {
        self.push(name, DataType::Int64, true, Arc::new(Int64Array::from(values)));
        self
    }

    fn bool(mut self, name: &str, values: Vec<bool>) -> Self {
        self.push(name, DataType::Boolean, false, Arc::new(BooleanArray::from(values)));
        self
    }

    fn text(mut self, name: &str, values: Vec<String>) -> Self {
        self.push(name, DataType::Utf8, false, Arc::new(StringArray::from(values)));
        self
    }

    fn text_or_null(mut self, name: &str, values: Vec<Option<String>>) -> Self {
        self.push(name, DataType::Utf8, true, Arc::new(StringArray::from(values)));
        self
    }

    fn batch(self) -> Result<RecordBatch> {
        RecordBatch::try_new(Arc::new(Schema::new(self.fields)), self.arrays).map_err(Error::other)
    }
}

/// A log as Arrow tables: the metadata every file carries, and one batch per record kind
/// in [`TABLES`] order.
#[derive(Debug)]
pub struct LogTables {
    /// `dash2sim.schema_version`, `dash2sim.log_id`, `dash2sim.device_id`, `dash2sim.origin`.
    pub metadata: Vec<(String, String)>,
    /// The tables, named as in [`TABLES`].
    pub tables: Vec<(&'static str, RecordBatch)>,
}

/// Write `batch` to `path` as Parquet (zstd) with `metadata` as the file's key-value metadata.
fn write_parquet(path: &Path, batch: &RecordBatch, metadata: &[(String, String)]) -> Result<()> {
    let metadata = metadata.iter().map(|(k, v)| KeyValue::new(k.clone(), v.clone())).collect();
    let properties = WriterProperties::builder()
        .set_compression(Compression::ZSTD(ZstdLevel::default()))
        .set_key_value_metadata(Some(metadata))
        .build();
    let file = std::fs::File::create(path).map_err(|e| Error::file(path, e))?;
    let mut writer = ArrowWriter::try_new(file, batch.schema(), Some(properties)).map_err(|e| Error::file(path, e))?;
    writer.write(batch).map_err(|e| Error::file(path, e))?;
    writer.close().map_err(|e| Error::file(path, e))?;
    Ok(())
}

/// `batch` as an Arrow IPC stream with `metadata` on its schema: the form a Python caller
/// reads without a copy through `pyarrow.ipc.open_stream`.
pub fn ipc_stream(batch: &RecordBatch, metadata: &[(String, String)]) -> Result<Vec<u8>> {
    let schema = batch
        .schema()
        .as_ref()
        .clone()
        .with_metadata(metadata.iter().cloned().collect::<std::collections::HashMap<String, String>>());
    let batch = batch.clone().with_schema(Arc::new(schema.clone())).map_err(Error::other)?;
    let mut writer = StreamWriter::try_new(Vec::new(), &schema).map_err(Error::other)?;
    writer.write(&batch).map_err(Error::other)?;
    writer.into_inner().map_err(Error::other)
}

/// The rows of one record kind.
fn rows<'a, T>(log: &'a LogContents, pick: impl Fn(&'a Record) -> Option<&'a T>) -> Vec<&'a T> {
    log.records.iter().filter_map(pick).collect()
}

fn column<T, V>(rows: &[&T], value: impl Fn(&T) -> V) -> Vec<V> {
    rows.iter().map(|r| value(r)).collect()
}

/// A coded value with −1 for "none", scaled.
fn or_null(raw: i64, scale: f64) -> Option<f64> {
    (raw >= 0).then_some(raw as f64 * scale)
}

fn speed_source(code: i64) -> String {
    match code {
        1 => "ccvs1",
        2 => "obd",
        3 => "dbc",
        _ => "other",
    }
    .to_owned()
}

/// Write `log` as Parquet files into `dir` (created); rows per table, in [`TABLES`] order.
pub fn write(log: &LogContents, log_id: &str, dir: &Path) -> Result<Vec<(&'static str, usize)>> {
    let tables = tables(log, log_id)?;
    std::fs::create_dir_all(dir).map_err(|e| Error::file(dir, e))?;
    let mut written = Vec::new();
    for (name, batch) in &tables.tables {
        write_parquet(&dir.join(format!("{name}.parquet")), batch, &tables.metadata)?;
        written.push((*name, batch.num_rows()));
    }
    Ok(written)
}

/// `log` as Arrow tables, `log_id` in every row.
pub fn tables(log: &LogContents, log_id: &str) -> Result<LogTables> {
    let header = log.header.ok_or_else(|| Error::invalid("the log's header is damaged: no origin to place it"))?;
    let frame = frame(&header).ok_or_else(|| Error::invalid("the header's origin is not a position"))?;
    let [lat0, lon0, h0] =
        [header.origin[0] as f64 * 1e-7, header.origin[1] as f64 * 1e-7, header.origin[2] as f64 * 1e-3];
    let device = String::from_utf8_lossy(&header.device_id).trim_end_matches('\0').to_owned();
    let metadata: Vec<(String, String)> = [
        ("dash2sim.schema_version", SCHEMA_VERSION.to_owned()),
        ("dash2sim.log_id", log_id.to_owned()),
        ("dash2sim.device_id", device),
        ("dash2sim.origin", format!("{lat0},{lon0},{h0}")),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_owned(), v))
    .collect();
    let mut batches = Vec::new();

    let ego = rows(log, |r| if let Record::EgoPose(p) = r { Some(p) } else { None });
    let geodetic: Vec<Option<Geodetic>> = column(&ego, |p| {
        let enu = dash2sim_core::nalgebra::Vector3::new(p.x_mm as f64, p.y_mm as f64, p.z_mm as f64) * 1e-3;
        frame.enu_to_geodetic(&enu).ok()
    });
    let table = Table::new(log_id, column(&ego, |p| p.t_us))
        .f64("x_m", column(&ego, |p| p.x_mm as f64 * 1e-3))
        .f64("y_m", column(&ego, |p| p.y_mm as f64 * 1e-3))
        .f64("z_m", column(&ego, |p| p.z_mm as f64 * 1e-3))
        .f64("heading_rad", column(&ego, |p| p.yaw_e4 as f64 * 1e-4))
        .f64_or_null("sigma_m", column(&ego, |p| (p.sigma_mm > 0).then_some(p.sigma_mm as f64 * 1e-3)))
        .f64_or_null("lat_deg", geodetic.iter().map(|g| g.map(|g| g.lat_deg)).collect())
        .f64_or_null("lon_deg", geodetic.iter().map(|g| g.map(|g| g.lon_deg)).collect());
    batches.push(("ego", table.batch()?));

    let fixes = rows(log, |r| if let Record::GnssFix(f) = r { Some(f) } else { None });
    let table = Table::new(log_id, column(&fixes, |f| f.t_us))
        .f64("lat_deg", column(&fixes, |f| f.lat_e7 as f64 * 1e-7))
        .f64("lon_deg", column(&fixes, |f| f.lon_e7 as f64 * 1e-7))
        .f64("alt_m", column(&fixes, |f| f.alt_mm as f64 * 1e-3))
        .f64_or_null("speed_mps", column(&fixes, |f| or_null(f.speed_mm_s, 1e-3)))
        .f64_or_null("track_rad", column(&fixes, |f| or_null(f.track_e4, 1e-4)))
        .f64_or_null("hdop", column(&fixes, |f| or_null(f.hdop_e2, 1e-2)))
        .i64_or_null("satellites", column(&fixes, |f| (f.satellites >= 0).then_some(f.satellites)))
        .i64("mode", column(&fixes, |f| f.mode));
    batches.push(("gnss", table.batch()?));

    let speeds = rows(log, |r| if let Record::VehicleSpeed(v) = r { Some(v) } else { None });
    let table = Table::new(log_id, column(&speeds, |v| v.t_us))
        .f64("speed_mps", column(&speeds, |v| v.speed_mm_s as f64 * 1e-3))
        .text("source", column(&speeds, |v| speed_source(v.source)));
    batches.push(("speed", table.batch()?));

    let anchors = rows(log, |r| if let Record::AnchorEstimate(a) = r { Some(a) } else { None });
    let table = Table::new(log_id, column(&anchors, |a| a.t_us))
        .f64("scale", column(&anchors, |a| a.scale_e6 as f64 * 1e-6))
        .f64("yaw_rad", column(&anchors, |a| a.yaw_e6 as f64 * 1e-6))
        .f64("pitch_rad", column(&anchors, |a| a.pitch_e6 as f64 * 1e-6))
        .f64("roll_rad", column(&anchors, |a| a.roll_e6 as f64 * 1e-6))
        .f64("tx_m", column(&anchors, |a| a.tx_mm as f64 * 1e-3))
        .f64("ty_m", column(&anchors, |a| a.ty_mm as f64 * 1e-3))
        .f64("tz_m", column(&anchors, |a| a.tz_mm as f64 * 1e-3))
        .i64("observability", column(&anchors, |a| a.observability))
        .i64("anchors", column(&anchors, |a| a.anchors))
        .f64("rms_m", column(&anchors, |a| a.rms_mm as f64 * 1e-3))
        .f64("gnss_latency_s", column(&anchors, |a| a.latency_us as f64 * 1e-6));
    batches.push(("anchors", table.batch()?));

    let states: Vec<(i64, &dash2sim_core::binlog::Track3d)> = tracks(log).collect();
    // Each track's covariance, where the log states one (`TrackCovariance`, finished logs).
    let covariance: std::collections::BTreeMap<i64, [f64; 3]> = log
        .records
        .iter()
        .filter_map(|r| match r {
            Record::TrackCovariance(c) => {
                Some((c.id, [c.cov_xx_mm2, c.cov_xy_mm2, c.cov_yy_mm2].map(|v| v as f64 * 1e-6)))
            }
            _ => None,
        })
        .collect();
    let stated =
        |k: usize| -> Vec<Option<f64>> { states.iter().map(|(_, s)| covariance.get(&s.id).map(|c| c[k])).collect() };
    let track =
        |f: fn(&dash2sim_core::binlog::Track3d) -> f64| -> Vec<f64> { states.iter().map(|(_, s)| f(s)).collect() };
    let table = Table::new(log_id, states.iter().map(|(t, _)| *t).collect())
        .i64("track_id", states.iter().map(|(_, s)| s.id).collect())
        .text("class", states.iter().map(|(_, s)| class_name(s.class).to_owned()).collect())
        .i64("class_code", states.iter().map(|(_, s)| s.class).collect())
        .f64("x_m", track(|s| s.x_mm as f64 * 1e-3))
        .f64("y_m", track(|s| s.y_mm as f64 * 1e-3))
        .f64("z_m", track(|s| s.z_mm as f64 * 1e-3))
        .f64("yaw_rad", track(|s| s.yaw_e4 as f64 * 1e-4))
        .f64("length_m", track(|s| s.l_mm as f64 * 1e-3))
        .f64("width_m", track(|s| s.w_mm as f64 * 1e-3))
        .f64("height_m", track(|s| s.h_mm as f64 * 1e-3))
        .f64("vx_mps", track(|s| s.vx_mm_s as f64 * 1e-3))
        .f64("vy_mps", track(|s| s.vy_mm_s as f64 * 1e-3))
        .bool("is_static", states.iter().map(|(_, s)| s.is_static != 0).collect())
        .f64_or_null("cov_xx_m2", stated(0))
        .f64_or_null("cov_xy_m2", stated(1))
        .f64_or_null("cov_yy_m2", stated(2));
    batches.push(("tracks3d", table.batch()?));

    let windows = rows(log, |r| if let Record::Verification(v) = r { Some(v) } else { None });
    let metric = |f: fn(&dash2sim_core::binlog::Verification) -> i64| -> Vec<f64> {
        windows.iter().map(|v| f(v) as f64 * 1e-4).collect()
    };
    let table = Table::new(log_id, column(&windows, |v| v.t_us))
        .f64("score", column(&windows, |v| v.score_e2 as f64 * 1e-2))
        .bool("verified", column(&windows, |v| v.score_e2 > 9000))
        .f64("no_at_fault_collisions", metric(|v| v.collisions_e4))
        .f64("drivable_area_compliance", metric(|v| v.drivable_e4))
        .f64("driving_direction_compliance", metric(|v| v.direction_e4))
        .f64("ego_is_making_progress", metric(|v| v.making_progress_e4))
        .f64("ego_progress_along_expert_route", metric(|v| v.progress_e4))
        .f64("time_to_collision_within_bound", metric(|v| v.ttc_e4))
        .f64("speed_limit_compliance", metric(|v| v.speed_limit_e4))
        .f64("ego_is_comfortable", metric(|v| v.comfort_e4))
        .f64("worst_corner_outside_m", column(&windows, |v| v.worst_corner_mm as f64 * 1e-3))
        .text_or_null("decision", column(&windows, |v| v.decision_name().map(str::to_owned)))
        .f64_or_null("score_low", column(&windows, |v| v.decision_name().map(|_| v.score_low_e2 as f64 * 1e-2)))
        .f64_or_null("score_high", column(&windows, |v| v.decision_name().map(|_| v.score_high_e2 as f64 * 1e-2)));
    batches.push(("verification", table.batch()?));

    let deltas = rows(log, |r| if let Record::ImuDelta(d) = r { Some(d) } else { None });
    let table = Table::new(log_id, column(&deltas, |d| d.t_us))
        .f64("dt_s", column(&deltas, |d| d.dt_us as f64 * 1e-6))
        .f64("dtheta_x_rad", column(&deltas, |d| d.dtheta_x_e6 as f64 * 1e-6))
        .f64("dtheta_y_rad", column(&deltas, |d| d.dtheta_y_e6 as f64 * 1e-6))
        .f64("dtheta_z_rad", column(&deltas, |d| d.dtheta_z_e6 as f64 * 1e-6))
        .f64("dv_x_mps", column(&deltas, |d| d.dv_x_mm_s as f64 * 1e-3))
        .f64("dv_y_mps", column(&deltas, |d| d.dv_y_mm_s as f64 * 1e-3))
        .f64("dv_z_mps", column(&deltas, |d| d.dv_z_mm_s as f64 * 1e-3))
        .i64("samples", column(&deltas, |d| d.samples));
    batches.push(("imu", table.batch()?));

    let estimates = rows(log, |r| if let Record::ImuEstimate(e) = r { Some(e) } else { None });
    let table = Table::new(log_id, column(&estimates, |e| e.t_us))
        .f64("pitch_rad", column(&estimates, |e| e.pitch_e6 as f64 * 1e-6))
        .f64("roll_rad", column(&estimates, |e| e.roll_e6 as f64 * 1e-6))
        .f64("gyro_bias_x_rad_s", column(&estimates, |e| e.bias_x_e7 as f64 * 1e-7))
        .f64("gyro_bias_y_rad_s", column(&estimates, |e| e.bias_y_e7 as f64 * 1e-7))
        .f64("gyro_bias_z_rad_s", column(&estimates, |e| e.bias_z_e7 as f64 * 1e-7))
        .f64("gyro_bias_z_sigma_rad_s", column(&estimates, |e| e.bias_sigma_e7 as f64 * 1e-7))
        .i64("standstills", column(&estimates, |e| e.standstills))
        .i64("courses", column(&estimates, |e| e.courses));
    batches.push(("imu_estimates", table.batch()?));

    let events = rows(log, |r| if let Record::Event(e) = r { Some(e) } else { None });
    let table = Table::new(log_id, column(&events, |e| e.t_us))
        .i64("level", column(&events, |e| i64::from(e.level)))
        .text("text", column(&events, |e| String::from_utf8_lossy(&e.text).into_owned()));
    batches.push(("events", table.batch()?));
    Ok(LogTables { metadata, tables: batches })
}
