//! The objects CSV (`frame,t_s,id,class,x,y,z,yaw,l,w,h,vx,vy,static,visible`, as
//! `dash2sim scenario generate` writes it; only `t_s,id,class,x,y,yaw,l,w,vx,vy` are
//! required, in any column order): 3D boxes in the map's ENU frame over time.

use std::path::Path;

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

/// Read every row; the error names the file, line and column.
pub fn read(path: &Path) -> Result<Vec<ObjectRow>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut lines = text.lines().enumerate();
    let header = lines.next().map(|(_, l)| l.trim()).unwrap_or_default();
    let columns: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |name: &str| columns.iter().position(|c| *c == name);
    let need = |name: &str| find(name).ok_or_else(|| format!("{}:1: no column {name:?}", path.display()));
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
        let number = |k: usize, name: &str| -> Result<f64, String> {
            fields
                .get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{}:{}: {name} is not a finite number", path.display(), n + 1))
        };
        let optional = |k: Option<usize>, name: &str| k.map_or(Ok(0.0), |k| number(k, name));
        let object_id = fields
            .get(id)
            .and_then(|v| v.parse::<u32>().ok())
            .ok_or_else(|| format!("{}:{}: id is not a non-negative integer", path.display(), n + 1))?;
        let size = [number(l, "l")?, number(w, "w")?, optional(h, "h")?];
        if size.iter().any(|v| *v < 0.0) {
            return Err(format!("{}:{}: negative size", path.display(), n + 1));
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
