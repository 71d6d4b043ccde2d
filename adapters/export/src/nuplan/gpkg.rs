//! A GeoPackage writer (OGC 12-128r18, version 1.2): the few tables a reader needs — the
//! spatial reference systems, the contents, the geometry columns — and feature tables whose
//! geometries are GeoPackage binary blobs (an envelope header, then little-endian WKB).
//! Enough for GDAL (`ogrinfo`), geopandas and nuPlan's map reader; no spatial index (R-tree
//! triggers need SQLite functions that only GDAL registers) and no extensions.

use dash2sim_linux::{Error, Result};
use rusqlite::{params, Connection};

/// A geometry in the layer's projected coordinates.
#[derive(Clone, Debug, PartialEq)]
pub enum Geometry {
    /// A polyline.
    LineString(Vec<(f64, f64)>),
    /// A polygon: one exterior ring (closed here if it is not).
    Polygon(Vec<(f64, f64)>),
}

impl Geometry {
    /// Its points (a polygon's ring as given).
    pub fn points(&self) -> &[(f64, f64)] {
        match self {
            Geometry::LineString(p) | Geometry::Polygon(p) => p,
        }
    }

    /// The GeoPackage binary form: `GP`, version 0, flags (little-endian, xy envelope),
    /// the SRS id, the envelope (min x, max x, min y, max y), then WKB.
    pub fn to_gpkg(&self, srs_id: i32) -> Vec<u8> {
        let points = self.points();
        let (mut min_x, mut max_x, mut min_y, mut max_y) =
            (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in points {
            (min_x, max_x, min_y, max_y) = (min_x.min(x), max_x.max(x), min_y.min(y), max_y.max(y));
        }
        let mut out = Vec::with_capacity(48 + 16 * points.len() + 16);
        out.extend_from_slice(b"GP");
        out.push(0);
        out.push(0b0000_0011);
        out.extend_from_slice(&srs_id.to_le_bytes());
        for v in [min_x, max_x, min_y, max_y] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.push(1);
        let push_points = |out: &mut Vec<u8>, ring: &[(f64, f64)]| {
            out.extend_from_slice(&(ring.len() as u32).to_le_bytes());
            for &(x, y) in ring {
                out.extend_from_slice(&x.to_le_bytes());
                out.extend_from_slice(&y.to_le_bytes());
            }
        };
        match self {
            Geometry::LineString(p) => {
                out.extend_from_slice(&2u32.to_le_bytes());
                push_points(&mut out, p);
            }
            Geometry::Polygon(p) => {
                out.extend_from_slice(&3u32.to_le_bytes());
                out.extend_from_slice(&1u32.to_le_bytes());
                let mut ring = p.clone();
                if ring.first() != ring.last() {
                    if let Some(&first) = ring.first() {
                        ring.push(first);
                    }
                }
                push_points(&mut out, &ring);
            }
        }
        out
    }

    fn type_name(&self) -> &'static str {
        match self {
            Geometry::LineString(_) => "LINESTRING",
            Geometry::Polygon(_) => "POLYGON",
        }
    }
}

/// A column value of a feature.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// INTEGER.
    Int(i64),
    /// REAL.
    Real(f64),
    /// TEXT.
    Text(String),
    /// NULL (of the column's declared type).
    Null,
}

impl rusqlite::ToSql for Value {
    fn to_sql(&self) -> rusqlite::Result<rusqlite::types::ToSqlOutput<'_>> {
        use rusqlite::types::{ToSqlOutput, Value as V};
        Ok(ToSqlOutput::Owned(match self {
            Value::Int(v) => V::Integer(*v),
            Value::Real(v) => V::Real(*v),
            Value::Text(v) => V::Text(v.clone()),
            Value::Null => V::Null,
        }))
    }
}

/// A column of a layer: name and SQL type (`INTEGER`, `REAL`, `TEXT`).
pub type Column = (&'static str, &'static str);

/// A layer to write: its name, geometry type (for an empty layer), columns and features
/// (fid, geometry, values in column order).
#[derive(Clone, Debug)]
pub struct Layer {
    /// Table name.
    pub name: &'static str,
    /// `LINESTRING` or `POLYGON` when the layer has no feature to tell.
    pub geometry_type: &'static str,
    /// Attribute columns.
    pub columns: Vec<Column>,
    /// Features: fid, geometry, attributes.
    pub features: Vec<(i64, Geometry, Vec<Value>)>,
}

/// A GeoPackage being written.
#[derive(Debug)]
pub struct GeoPackage {
    db: Connection,
    srs_id: i32,
}

fn sql_err(e: rusqlite::Error) -> Error {
    Error::refused("GeoPackage", e)
}

impl GeoPackage {
    /// Create `path` (which must not exist) with the projected CRS `srs_id` (an EPSG code)
    /// defined by `wkt`.
    pub fn create(path: &std::path::Path, srs_id: i32, srs_name: &str, wkt: &str) -> Result<Self> {
        let db = Connection::open(path).map_err(sql_err)?;
        db.execute_batch(
            "PRAGMA application_id = 1196444487; PRAGMA user_version = 10200;
             CREATE TABLE gpkg_spatial_ref_sys (srs_name TEXT NOT NULL, srs_id INTEGER NOT NULL PRIMARY KEY,
               organization TEXT NOT NULL, organization_coordsys_id INTEGER NOT NULL, definition TEXT NOT NULL,
               description TEXT);
             CREATE TABLE gpkg_contents (table_name TEXT NOT NULL PRIMARY KEY, data_type TEXT NOT NULL,
               identifier TEXT UNIQUE, description TEXT DEFAULT '',
               last_change DATETIME NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%fZ','now')),
               min_x DOUBLE, min_y DOUBLE, max_x DOUBLE, max_y DOUBLE, srs_id INTEGER,
               CONSTRAINT fk_gc_r_srs_id FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys(srs_id));
             CREATE TABLE gpkg_geometry_columns (table_name TEXT NOT NULL, column_name TEXT NOT NULL,
               geometry_type_name TEXT NOT NULL, srs_id INTEGER NOT NULL, z TINYINT NOT NULL, m TINYINT NOT NULL,
               CONSTRAINT pk_geom_cols PRIMARY KEY (table_name, column_name),
               CONSTRAINT fk_gc_tn FOREIGN KEY (table_name) REFERENCES gpkg_contents(table_name),
               CONSTRAINT fk_gc_srs FOREIGN KEY (srs_id) REFERENCES gpkg_spatial_ref_sys (srs_id));",
        )
        .map_err(sql_err)?;
        let wgs84 = r#"GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AXIS["Latitude",NORTH],AXIS["Longitude",EAST],AUTHORITY["EPSG","4326"]]"#;
        let mut insert =
            db.prepare("INSERT INTO gpkg_spatial_ref_sys VALUES (?1, ?2, ?3, ?4, ?5, ?6)").map_err(sql_err)?;
        for (name, id, org, org_id, def, description) in [
            ("Undefined cartesian SRS", -1, "NONE", -1, "undefined", "undefined cartesian coordinate reference system"),
            ("Undefined geographic SRS", 0, "NONE", 0, "undefined", "undefined geographic coordinate reference system"),
            (
                "WGS 84 geodetic",
                4326,
                "EPSG",
                4326,
                wgs84,
                "longitude/latitude coordinates in decimal degrees on the WGS 84 spheroid",
            ),
            (srs_name, srs_id, "EPSG", srs_id, wkt, srs_name),
        ] {
            insert.execute(params![name, id, org, org_id, def, description]).map_err(sql_err)?;
        }
        drop(insert);
        Ok(GeoPackage { db, srs_id })
    }

    /// Write a feature layer.
    pub fn write_layer(&mut self, layer: &Layer) -> Result<()> {
        let columns: String = layer.columns.iter().map(|(n, t)| format!(", \"{n}\" {t}")).collect();
        let tx = self.db.transaction().map_err(sql_err)?;
        tx.execute_batch(&format!(
            "CREATE TABLE \"{0}\" (fid INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, geom {1}{columns});",
            layer.name,
            layer.features.first().map_or(layer.geometry_type, |f| f.1.type_name()),
        ))
        .map_err(sql_err)?;
        let placeholders: String = (0..layer.columns.len()).map(|k| format!(", ?{}", k + 3)).collect();
        let names: String = layer.columns.iter().map(|(n, _)| format!(", \"{n}\"")).collect();
        let (mut min_x, mut min_y, mut max_x, mut max_y) =
            (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        {
            let mut insert = tx
                .prepare(&format!("INSERT INTO \"{}\" (fid, geom{names}) VALUES (?1, ?2{placeholders})", layer.name))
                .map_err(sql_err)?;
            for (fid, geometry, values) in &layer.features {
                for &(x, y) in geometry.points() {
                    (min_x, min_y, max_x, max_y) = (min_x.min(x), min_y.min(y), max_x.max(x), max_y.max(y));
                }
                let blob = geometry.to_gpkg(self.srs_id);
                let mut row: Vec<&dyn rusqlite::ToSql> = vec![fid, &blob];
                row.extend(values.iter().map(|v| v as &dyn rusqlite::ToSql));
                insert.execute(row.as_slice()).map_err(sql_err)?;
            }
        }
        let bounds = |v: f64| if v.is_finite() { Some(v) } else { None };
        tx.execute(
            "INSERT INTO gpkg_contents (table_name, data_type, identifier, min_x, min_y, max_x, max_y, srs_id)
             VALUES (?1, 'features', ?1, ?2, ?3, ?4, ?5, ?6)",
            params![layer.name, bounds(min_x), bounds(min_y), bounds(max_x), bounds(max_y), self.srs_id],
        )
        .map_err(sql_err)?;
        let geometry_type = layer.features.first().map_or(layer.geometry_type, |f| f.1.type_name());
        tx.execute(
            "INSERT INTO gpkg_geometry_columns VALUES (?1, 'geom', ?2, ?3, 0, 0)",
            params![layer.name, geometry_type, self.srs_id],
        )
        .map_err(sql_err)?;
        tx.commit().map_err(sql_err)
    }

    /// Write a table without geometry (`data_type` `attributes`).
    pub fn write_attributes(&mut self, name: &str, rows: &[(&str, &str)]) -> Result<()> {
        let tx = self.db.transaction().map_err(sql_err)?;
        tx.execute_batch(&format!(
            "CREATE TABLE \"{name}\" (fid INTEGER PRIMARY KEY AUTOINCREMENT NOT NULL, key TEXT, value TEXT);"
        ))
        .map_err(sql_err)?;
        for (key, value) in rows {
            tx.execute(&format!("INSERT INTO \"{name}\" (key, value) VALUES (?1, ?2)"), params![key, value])
                .map_err(sql_err)?;
        }
        tx.execute(
            "INSERT INTO gpkg_contents (table_name, data_type, identifier) VALUES (?1, 'attributes', ?1)",
            params![name],
        )
        .map_err(sql_err)?;
        tx.commit().map_err(sql_err)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polygon_blob_has_the_header_the_envelope_and_a_closed_ring() {
        let blob = Geometry::Polygon(vec![(0.0, 0.0), (2.0, 0.0), (2.0, 1.0)]).to_gpkg(32635);
        assert_eq!(&blob[..4], b"GP\x00\x03");
        assert_eq!(i32::from_le_bytes([blob[4], blob[5], blob[6], blob[7]]), 32635);
        let f = |at: usize| f64::from_le_bytes(blob[at..at + 8].try_into().expect("8 bytes"));
        assert_eq!([f(8), f(16), f(24), f(32)], [0.0, 2.0, 0.0, 1.0]);
        // WKB: little endian, polygon, one ring of four points (closed).
        assert_eq!(blob[40], 1);
        assert_eq!(&blob[41..45], &3u32.to_le_bytes());
        assert_eq!(&blob[45..49], &1u32.to_le_bytes());
        assert_eq!(&blob[49..53], &4u32.to_le_bytes());
        assert_eq!(blob.len(), 53 + 4 * 16);
        assert_eq!((f(blob.len() - 16), f(blob.len() - 8)), (0.0, 0.0));
    }
}
