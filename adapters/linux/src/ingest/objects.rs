//! The objects CSV (`frame,t_s,id,class,x,y,z,yaw,l,w,h,vx,vy,static,visible`, as
//! `dash2sim scenario generate` writes it; only `t_s,id,class,x,y,yaw,l,w,vx,vy` are
//! required, in any column order): 3D boxes in the map's ENU frame over time.

use std::path::Path;

use crate::{Error, Result};
use dash2sim_core::box3d::Box3d;

/// The header line the writers use.
pub const HEADER: &str = "frame,t_s,id,class,x,y,z,yaw,l,w,h,vx,vy,static,visible";

/// One CSV line (with its newline) of `row` at `frame`.
pub fn line(frame: u64, row: &ObjectRow, visible: bool) -> String {
    let ([x, y, z], [l, w, h], [vx, vy]) = (row.centre, row.size, row.velocity);
    format!(
        "{frame},{:.3},{},{},{x:.4},{y:.4},{z:.4},{:.5},{l:.3},{w:.3},{h:.3},{vx:.3},{vy:.3},{},{}\n",
        row.t,
        row.id,
        row.class,
        row.yaw,
        u8::from(row.is_static),
        u8::from(visible)
    )
}

/// One object at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjectRow {
    /// Time, s.
    pub t: f64,
    /// Track id.
    pub id: u32,
    /// Class name.
    pub class: String,
    /// Centre (east, north, up), m; up is 0 when the column is absent.
    pub centre: [f64; 3],
    /// Heading, rad.
    pub yaw: f64,
    /// Length, width, height (m); height 0 when absent.
    pub size: [f64; 3],
    /// Velocity (east, north), m/s.
    pub velocity: [f64; 2],
    /// Static flag (false when absent).
    pub is_static: bool,
}

impl ObjectRow {
    /// A row for a 3D box at time `t`.
    pub fn from_box(t: f64, id: u32, class: &str, b: &Box3d, velocity: [f64; 2], is_static: bool) -> Self {
        ObjectRow {
            t,
            id,
            class: class.to_owned(),
            centre: [b.x, b.y, b.z],
            yaw: b.yaw,
            size: [b.l, b.w, b.h],
            velocity,
            is_static,
        }
    }
}

/// Read every row; the error names the file, line and column.
pub fn read(path: &Path) -> Result<Vec<ObjectRow>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let mut lines = text.lines().enumerate();
    let header = lines.next().map(|(_, l)| l.trim()).unwrap_or_default();
    let columns: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |name: &str| columns.iter().position(|c| *c == name);
    let need =
        |name: &str| find(name).ok_or_else(|| Error::invalid(format!("{}:1: no column {name:?}", path.display())));
    let [t, id, class, x, y, yaw, l, w, vx, vy] =
        ["t_s", "id", "class", "x", "y", "yaw", "l", "w", "vx", "vy"].map(need);
    let (t, id, class, x, y, yaw, l, w, vx, vy) = (t?, id?, class?, x?, y?, yaw?, l?, w?, vx?, vy?);
    let (z, h, stat) = (find("z"), find("h"), find("static"));
    let mut rows = Vec::new();
    for (n, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let number = |k: usize, name: &str| -> Result<f64> {
            fields
                .get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| Error::line(path, n + 1, format!("{name} is not a finite number")))
        };
        let optional = |k: Option<usize>, name: &str| k.map_or(Ok(0.0), |k| number(k, name));
        let object_id = fields
            .get(id)
            .and_then(|v| v.parse::<u32>().ok())
            .ok_or_else(|| Error::line(path, n + 1, "id is not a non-negative integer"))?;
        let size = [number(l, "l")?, number(w, "w")?, optional(h, "h")?];
        if size.iter().any(|v| *v < 0.0) {
            return Err(Error::line(path, n + 1, "negative size"));
        }
        rows.push(ObjectRow {
            t: number(t, "t_s")?,
            id: object_id,
            class: fields.get(class).copied().unwrap_or_default().to_owned(),
            centre: [number(x, "x")?, number(y, "y")?, optional(z, "z")?],
            yaw: number(yaw, "yaw")?,
            size,
            velocity: [number(vx, "vx")?, number(vy, "vy")?],
            is_static: optional(stat, "static")? != 0.0,
        });
    }
    Ok(rows)
}
