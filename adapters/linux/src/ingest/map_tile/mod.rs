//! Building map tiles (format v2, `docs/map-tile.md`): OpenStreetMap highway ways → lanes
//! in a local ENU frame → the bytes the core's `map::MapView` reads.
//!
//! Every drivable way becomes `forward + backward` lanes laid side by side across its
//! width (backward lanes on the left, as in right-hand traffic), each an offset copy of the
//! way's centreline in its own driving order. Successors join lanes through shared OSM
//! nodes: a lane ending at node n continues into every lane starting at n except the
//! reverse of itself. Lanelet2 lanelets become lanes with exact polygon areas
//! ([`lanelet2`]).

pub mod check;
mod fine_grid;
pub mod fine_index;
pub mod lane_index;
pub mod lanelet2;
pub mod polygon_index;

use std::collections::HashMap;

use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::map::{body_checksum, Header, CRC_AT, HEADER_LEN, NONE, POLYGON_BIT, VERSION_MAJOR};

use crate::geometry::offset_polyline;
use crate::ingest::osm::highway::{interpret, RoadSpec};
use crate::ingest::osm::OsmData;
use crate::{Error, Field, Result};
use serde::Serialize;

/// Road classes as stored in the tile (`docs/map-tile.md`).
pub const CLASSES: [&str; 12] = [
    "other",
    "motorway",
    "trunk",
    "primary",
    "secondary",
    "tertiary",
    "unclassified",
    "residential",
    "service",
    "living_street",
    "link",
    "lanelet",
];

fn class_code(class: &str) -> u8 {
    if class.ends_with("_link") {
        return 10;
    }
    CLASSES.iter().position(|c| *c == class).map_or(0, |i| i as u8)
}

/// One lane before encoding.
#[derive(Clone, Debug, PartialEq)]
pub struct TileLane {
    /// Centreline in driving order, ENU metres.
    pub points: Vec<(f64, f64)>,
    /// Width, m.
    pub width: f64,
    /// Speed limit, m/s.
    pub speed_limit: Option<f64>,
    /// Road class code.
    pub class: u8,
    /// Neighbour lanes in the same direction (left, right).
    pub neighbours: (Option<u32>, Option<u32>),
    /// Lanes it continues into.
    pub successors: Vec<u32>,
    /// Index in `TileContent::polygons` of the polygon that is this lane's area (Lanelet2),
    /// or `None` for the centreline buffered by half the width.
    pub area: Option<usize>,
}

/// Everything a tile holds, before encoding.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TileContent {
    /// ENU origin: latitude, longitude, height.
    pub origin: [f64; 3],
    /// Lanes.
    pub lanes: Vec<TileLane>,
    /// Drivable polygons (rings), ENU metres.
    pub polygons: Vec<Vec<(f64, f64)>>,
    /// Source counts: nodes, ways, highway ways, relations.
    pub source_counts: [u32; 4],
}

impl TileContent {
    /// Total centreline length of all lanes, km.
    pub fn lane_km(&self) -> f64 {
        self.lanes
            .iter()
            .map(|l| l.points.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum::<f64>())
            .sum::<f64>()
            / 1000.0
    }
}

/// What `data` holds: nodes, ways, highway ways, relations (the tile's source counts).
pub fn source_counts(data: &OsmData) -> [u32; 4] {
    let count = |n: usize| u32::try_from(n).unwrap_or(u32::MAX);
    [count(data.node_count), count(data.ways.len()), count(data.highway_ways().count()), count(data.relations.len())]
}

/// Lanes from the drivable highway ways of `data` around `origin` (default: the centre of
/// the nodes those ways use). Problems go to `warnings`.
pub fn from_osm(data: &OsmData, origin: Option<Geodetic>, warnings: &mut Vec<String>) -> TileContent {
    let roads: Vec<(&crate::ingest::osm::Way, RoadSpec)> =
        data.highway_ways().filter_map(|w| Some((w, interpret(w, warnings)?))).collect();
    let origin = origin.unwrap_or_else(|| {
        let (mut lat0, mut lon0, mut lat1, mut lon1) = (90.0f64, 180.0f64, -90.0f64, -180.0f64);
        let mut grow = |(lat, lon): &(f64, f64)| {
            (lat0, lon0, lat1, lon1) = (lat0.min(*lat), lon0.min(*lon), lat1.max(*lat), lon1.max(*lon));
        };
        if roads.is_empty() {
            // A Lanelet2 map has no highway ways: centre on all its nodes.
            data.nodes.values().for_each(&mut grow);
        }
        for (way, _) in &roads {
            way.refs.iter().filter_map(|r| data.nodes.get(r)).for_each(&mut grow);
        }
        let centre = if lat0 <= lat1 { ((lat0 + lat1) / 2.0, (lon0 + lon1) / 2.0) } else { (0.0, 0.0) };
        Geodetic::new(centre.0, centre.1, 0.0).unwrap_or(Geodetic { lat_deg: 0.0, lon_deg: 0.0, height_m: 0.0 })
    });
    let frame = LocalFrame::new(origin);
    let mut content = TileContent {
        origin: [origin.lat_deg, origin.lon_deg, origin.height_m],
        source_counts: source_counts(data),
        ..TileContent::default()
    };
    // (start node, end node, way id, reversed copy of lane?) per lane, for successors.
    let mut ends: Vec<(i64, i64, i64)> = Vec::new();
    for (way, road) in roads {
        let mut nodes = Vec::with_capacity(way.refs.len());
        for r in &way.refs {
            match data.nodes.get(r) {
                Some(&(lat, lon)) => {
                    let Ok(g) = Geodetic::new(lat, lon, 0.0) else { continue };
                    let p = frame.geodetic_to_enu(&g);
                    if nodes.last().is_none_or(|&(_, q): &(i64, (f64, f64))| (q.0 - p.x).hypot(q.1 - p.y) > 0.01) {
                        nodes.push((*r, (p.x, p.y)));
                    }
                }
                None => warnings.push(format!("way {} references missing node {r}; node skipped", way.id)),
            }
        }
        if nodes.len() < 2 {
            warnings.push(format!("way {}: fewer than 2 usable nodes; way skipped", way.id));
            continue;
        }
        if nodes.len() > usize::from(u16::MAX) {
            warnings.push(format!("way {}: more than 65535 nodes; way skipped", way.id));
            continue;
        }
        if road.reversed {
            nodes.reverse();
        }
        let line: Vec<(f64, f64)> = nodes.iter().map(|(_, p)| *p).collect();
        let (first_node, last_node) = (nodes[0].0, nodes[nodes.len() - 1].0);
        let (f, b) = (usize::from(road.forward_lanes), usize::from(road.backward_lanes));
        let total = f + b;
        let width = road.lane_width * total as f64;
        let base = content.lanes.len() as u32;
        for j in 0..total {
            let offset = width / 2.0 - (j as f64 + 0.5) * road.lane_width;
            let mut points = offset_polyline(&line, offset);
            let forward = j >= b;
            let (start, end) = if forward { (first_node, last_node) } else { (last_node, first_node) };
            let index = |k: usize| Some(base + k as u32);
            let neighbours = if forward {
                (if j > b { index(j - 1) } else { None }, if j + 1 < total { index(j + 1) } else { None })
            } else {
                points.reverse();
                (if j + 1 < b { index(j + 1) } else { None }, if j > 0 { index(j - 1) } else { None })
            };
            content.lanes.push(TileLane {
                points,
                width: road.lane_width,
                speed_limit: road.speed_limit,
                class: class_code(&road.class),
                neighbours,
                successors: Vec::new(),
                area: None,
            });
            ends.push((start, end, way.id));
        }
    }
    let mut starting: HashMap<i64, Vec<u32>> = HashMap::new();
    for (i, (start, _, _)) in ends.iter().enumerate() {
        starting.entry(*start).or_default().push(i as u32);
    }
    for (i, (start, end, way)) in ends.iter().enumerate() {
        let next = starting.get(end).map_or(&[][..], Vec::as_slice);
        content.lanes[i].successors =
            next.iter().copied().filter(|&k| !(ends[k as usize].2 == *way && ends[k as usize].1 == *start)).collect();
    }
    lanelet2::add_lanelets(data, &frame, &mut content, warnings);
    content
}

/// The grid's cell size unless asked otherwise, m. A smaller cell lists fewer lanes that
/// are not near a query (the drivable check got 15 % faster on central Helsinki going from
/// 50 m to 25 m) for a larger index (the tile 12 % larger): `docs/benchmarks.md`.
pub const DEFAULT_CELL_M: f64 = 25.0;

/// Encode `content` with a grid of `cell_size` metres.
pub fn encode(content: &TileContent, cell_size: f64) -> Vec<u8> {
    let mut points: Vec<(f64, f64)> = Vec::new();
    let mut successors: Vec<u32> = Vec::new();
    let mut lane_records = Vec::with_capacity(content.lanes.len() * 28);
    let (mut min, mut max) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
    let mut grow = |p: (f64, f64), margin: f64| {
        min = (min.0.min(p.0 - margin), min.1.min(p.1 - margin));
        max = (max.0.max(p.0 + margin), max.1.max(p.1 + margin));
    };
    for lane in &content.lanes {
        let first = points.len() as u32;
        for &p in &lane.points {
            grow(p, lane.width / 2.0);
            points.push(p);
        }
        let succ_first = successors.len() as u32;
        successors.extend(&lane.successors);
        let mut r = [0u8; 28];
        r[0..4].copy_from_slice(&first.to_le_bytes());
        r[4..6].copy_from_slice(&(lane.points.len().min(usize::from(u16::MAX)) as u16).to_le_bytes());
        r[6..8].copy_from_slice(&width_cm(lane.width).to_le_bytes());
        let speed = lane.speed_limit.map_or(0, |v| (v * 100.0).round().clamp(1.0, 65535.0) as u16);
        r[8..10].copy_from_slice(&speed.to_le_bytes());
        r[10] = lane.class;
        r[12..16].copy_from_slice(&lane.neighbours.0.unwrap_or(NONE).to_le_bytes());
        r[16..20].copy_from_slice(&lane.neighbours.1.unwrap_or(NONE).to_le_bytes());
        r[20..24].copy_from_slice(&succ_first.to_le_bytes());
        r[24..26].copy_from_slice(&(lane.successors.len().min(usize::from(u16::MAX)) as u16).to_le_bytes());
        let area = lane.area.and_then(|a| u16::try_from(a + 1).ok()).unwrap_or(0);
        r[26..28].copy_from_slice(&area.to_le_bytes());
        lane_records.extend_from_slice(&r);
    }
    let mut polygon_records = Vec::new();
    for ring in &content.polygons {
        polygon_records.extend_from_slice(&(points.len() as u32).to_le_bytes());
        polygon_records.extend_from_slice(&(ring.len() as u32).to_le_bytes());
        for &p in ring {
            grow(p, 0.0);
            points.push(p);
        }
    }
    if min.0 > max.0 {
        (min, max) = ((0.0, 0.0), (0.0, 0.0));
    }
    let cell_size = cell_size.max(1.0);
    let cols = (((max.0 - min.0) / cell_size).ceil() as usize).clamp(1, usize::from(u16::MAX));
    let rows = (((max.1 - min.1) / cell_size).ceil() as usize).clamp(1, usize::from(u16::MAX));
    let mut cells: Vec<Vec<u32>> = vec![Vec::new(); cols * rows];
    let cell_of = |v: f64, lo: f64, n: usize| (((v - lo) / cell_size).floor().max(0.0) as usize).min(n - 1);
    let mut register = |a: (f64, f64), b: (f64, f64), margin: f64, item: u32| {
        let (c0, c1) = (cell_of(a.0.min(b.0) - margin, min.0, cols), cell_of(a.0.max(b.0) + margin, min.0, cols));
        let (r0, r1) = (cell_of(a.1.min(b.1) - margin, min.1, rows), cell_of(a.1.max(b.1) + margin, min.1, rows));
        for row in r0..=r1 {
            for col in c0..=c1 {
                let cell = &mut cells[row * cols + col];
                if cell.last() != Some(&item) {
                    cell.push(item);
                }
            }
        }
    };
    let bounds = |ring: &[(f64, f64)]| {
        let (mut lo, mut hi) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for p in ring {
            lo = (lo.0.min(p.0), lo.1.min(p.1));
            hi = (hi.0.max(p.0), hi.1.max(p.1));
        }
        (lo, hi)
    };
    for (i, lane) in content.lanes.iter().enumerate() {
        match lane.area.and_then(|a| content.polygons.get(a)) {
            Some(ring) => {
                let (lo, hi) = bounds(ring);
                register(lo, hi, 0.0, i as u32);
            }
            None => {
                for w in lane.points.windows(2) {
                    register(w[0], w[1], lane.width / 2.0, i as u32);
                }
            }
        }
    }
    // A polygon that is a lane's area is reached through the lane.
    for (i, ring) in content.polygons.iter().enumerate() {
        if !content.lanes.iter().any(|l| l.area == Some(i)) {
            let (lo, hi) = bounds(ring);
            register(lo, hi, 0.0, i as u32 | POLYGON_BIT);
        }
    }
    let entries: usize = cells.iter().map(Vec::len).sum();
    let header = Header {
        origin: content.origin,
        points: points.len() as u32,
        lanes: content.lanes.len() as u32,
        successors: successors.len() as u32,
        polygons: content.polygons.len() as u32,
        grid_entries: entries as u32,
        cell_size: cell_size as f32,
        grid_min: [min.0 as f32, min.1 as f32],
        grid_size: [cols as u16, rows as u16],
        source_counts: content.source_counts,
        boxes: true,
    };
    let mut out = vec![0u8; HEADER_LEN];
    header.write(&mut out);
    for (x, y) in &points {
        out.extend_from_slice(&(*x as f32).to_le_bytes());
        out.extend_from_slice(&(*y as f32).to_le_bytes());
    }
    out.extend_from_slice(&lane_records);
    for s in &successors {
        out.extend_from_slice(&s.to_le_bytes());
    }
    out.extend_from_slice(&polygon_records);
    let mut start = 0u32;
    for cell in &cells {
        out.extend_from_slice(&start.to_le_bytes());
        start += cell.len() as u32;
    }
    out.extend_from_slice(&start.to_le_bytes());
    for cell in &cells {
        for e in cell {
            out.extend_from_slice(&e.to_le_bytes());
        }
    }
    // Item boxes (format 2): lanes, then polygons, from the stored f32 points and width,
    // rounded outward so that every box holds its item exactly.
    let stored = |p: &(f64, f64)| (f64::from(p.0 as f32), f64::from(p.1 as f32));
    let ring_box = |ring: &[(f64, f64)], margin: f64| item_box(ring.iter().map(stored), margin);
    for lane in &content.lanes {
        let b = match lane.area.and_then(|a| content.polygons.get(a)) {
            Some(ring) => ring_box(ring, 0.0),
            None => ring_box(&lane.points, f64::from(width_cm(lane.width)) / 100.0 / 2.0),
        };
        out.extend(b.iter().flat_map(|v| v.to_le_bytes()));
    }
    for ring in &content.polygons {
        out.extend(ring_box(ring, 0.0).iter().flat_map(|v| v.to_le_bytes()));
    }
    let crc = body_checksum(&out);
    out[CRC_AT..CRC_AT + 4].copy_from_slice(&crc.to_le_bytes());
    out
}

/// A lane's width as stored, cm.
fn width_cm(width: f64) -> u16 {
    (width * 100.0).round().clamp(1.0, 65535.0) as u16
}

/// The box (lo x, lo y, hi x, hi y) of points grown by `margin`, in f32 rounded outward.
fn item_box(points: impl Iterator<Item = (f64, f64)>, margin: f64) -> [f32; 4] {
    let (mut lo, mut hi) = ((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY));
    for (x, y) in points {
        lo = (lo.0.min(x - margin), lo.1.min(y - margin));
        hi = (hi.0.max(x + margin), hi.1.max(y + margin));
    }
    let down = |v: f64| if f64::from(v as f32) > v { (v as f32).next_down() } else { v as f32 };
    let up = |v: f64| if f64::from(v as f32) < v { (v as f32).next_up() } else { v as f32 };
    [down(lo.0), down(lo.1), up(hi.0), up(hi.1)]
}

/// A bounding box written `WEST,SOUTH,EAST,NORTH` (degrees), as `[west, south, east, north]`.
pub fn parse_bbox(text: &str) -> Result<[f64; 4]> {
    let values = crate::numbers::comma_separated(text, "four numbers WEST,SOUTH,EAST,NORTH")?;
    let [west, south, east, north] = values[..] else {
        return Err(Error::invalid(format!("expected four numbers WEST,SOUTH,EAST,NORTH, not {}", values.len())));
    };
    if !((-180.0..=180.0).contains(&west) && (-180.0..=180.0).contains(&east) && west < east) {
        return Err(Error::invalid("WEST and EAST must be longitudes with WEST < EAST"));
    }
    if !((-90.0..=90.0).contains(&south) && (-90.0..=90.0).contains(&north) && south < north) {
        return Err(Error::invalid("SOUTH and NORTH must be latitudes with SOUTH < NORTH"));
    }
    Ok([west, south, east, north])
}

/// What [`build_file`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Built {
    /// Lanes in the tile.
    pub lanes: usize,
    /// Their length, km.
    pub lane_km: f64,
    /// The tile's size, bytes.
    pub bytes: usize,
    /// What was odd in the OSM file (ways skipped, tags not understood).
    pub warnings: Vec<String>,
}

/// `dash2sim map build`: a tile from an OSM file, with its ENU origin (else the data's
/// centre) and cut to `bbox` (`[west, south, east, north]`, degrees, [`parse_bbox`]) if
/// given, written to `output`.
pub fn build_file(
    osm: &std::path::Path,
    output: &std::path::Path,
    origin: Option<Geodetic>,
    bbox: Option<[f64; 4]>,
    cell: f64,
) -> Result<Built> {
    if !(cell.is_finite() && (1.0..=10_000.0).contains(&cell)) {
        return Err(Error::request(Field::Cell, format!("{cell} must be between 1 and 10000 metres")));
    }
    let mut data = crate::ingest::osm::read(osm).map_err(Error::other)?;
    // The counts describe the source file, before any clipping.
    let source_counts = source_counts(&data);
    if let Some(bbox) = bbox {
        data.clip(bbox);
    }
    let mut warnings = data.warnings.clone();
    let mut content = from_osm(&data, origin, &mut warnings);
    content.source_counts = source_counts;
    if content.lanes.is_empty() {
        return Err(Error::file(
            osm,
            "no drivable highway ways or Lanelet2 lanelets (an OpenStreetMap extract with highway=* roads, or a \
             Lanelet2 map; cut to a bounding box, one that covers them)",
        ));
    }
    let bytes = encode(&content, cell);
    std::fs::write(output, &bytes).map_err(|e| Error::file(output, e))?;
    Ok(Built { lanes: content.lanes.len(), lane_km: content.lane_km(), bytes: bytes.len(), warnings })
}

/// A position by latitude and longitude, degrees.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LatLon {
    /// Latitude.
    pub lat: f64,
    /// Longitude.
    pub lon: f64,
}

/// A tile's lanes and free-standing polygons (`dash2sim map lanes`).
#[derive(Clone, Debug, Serialize)]
pub struct Lanes {
    /// The tile's ENU origin.
    pub origin: LatLon,
    /// Every lane.
    pub lanes: Vec<LaneShape>,
    /// Polygons that are no lane's area (ENU, m).
    pub polygons: Vec<Vec<[f64; 2]>>,
}

/// One lane of a tile.
#[derive(Clone, Debug, Serialize)]
pub struct LaneShape {
    /// Its index in the tile.
    pub index: u32,
    /// Width, m.
    pub width: f64,
    /// Speed limit, m/s.
    pub speed_limit: Option<f64>,
    /// Road class (OSM `highway=*`, or `other`).
    pub class: &'static str,
    /// The lane to its left.
    pub left: Option<u32>,
    /// The lane to its right.
    pub right: Option<u32>,
    /// Lanes it leads to.
    pub successors: Vec<u32>,
    /// Its centreline (ENU, m).
    pub points: Vec<[f64; 2]>,
    /// Its area's outline where the tile has one (Lanelet2).
    pub area: Option<Vec<[f64; 2]>>,
}

/// `dash2sim map lanes`: the lanes and free-standing polygons of the tile at `path`.
pub fn lanes(path: &std::path::Path) -> Result<Lanes> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let view = dash2sim_core::map::MapView::parse(&bytes).map_err(|e| Error::file(path, e))?;
    let ring = |i: u32| view.polygon(i).map(|p| p.map(|(x, y)| [x, y]).collect::<Vec<_>>());
    let lanes = (0..view.header().lanes)
        .filter_map(|i| view.lane(i))
        .map(|l| LaneShape {
            index: l.index,
            width: l.width,
            speed_limit: l.speed_limit,
            class: CLASSES.get(usize::from(l.class)).copied().unwrap_or("other"),
            left: l.left,
            right: l.right,
            successors: l.successors().collect(),
            points: l.points().map(|(x, y)| [x, y]).collect(),
            area: l.area.and_then(ring),
        })
        .collect();
    let areas: std::collections::HashSet<u32> = (0..view.header().lanes).filter_map(|i| view.lane(i)?.area).collect();
    let polygons = (0..view.header().polygons).filter(|i| !areas.contains(i)).filter_map(ring).collect();
    let h = view.header();
    Ok(Lanes { origin: LatLon { lat: h.origin[0], lon: h.origin[1] }, lanes, polygons })
}

/// What a tile is (`dash2sim map info`).
#[derive(Clone, Debug)]
pub struct TileInfo {
    /// The tile's header.
    pub header: Header,
    /// The format's major version.
    pub version: u8,
    /// Lanes' length, km.
    pub lane_km: f64,
    /// The tile's size, bytes.
    pub bytes: usize,
}

/// How `dash2sim map info --json` gives a tile: the header's counts by name.
impl Serialize for TileInfo {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Origin {
            lat: f64,
            lon: f64,
            height_m: f64,
        }
        #[derive(Serialize)]
        struct Osm {
            nodes: u32,
            ways: u32,
            highway_ways: u32,
            relations: u32,
        }
        #[derive(Serialize)]
        struct Grid {
            cell_m: f32,
            columns: u16,
            rows: u16,
            entries: u32,
        }
        #[derive(Serialize)]
        struct Info {
            origin: Origin,
            osm: Osm,
            lanes: u32,
            lane_km: f64,
            polygons: u32,
            points: u32,
            grid: Grid,
            bytes: usize,
            bytes_per_lane_km: f64,
        }
        let h = &self.header;
        let [nodes, ways, highway_ways, relations] = h.source_counts;
        Info {
            origin: Origin { lat: h.origin[0], lon: h.origin[1], height_m: h.origin[2] },
            osm: Osm { nodes, ways, highway_ways, relations },
            lanes: h.lanes,
            lane_km: self.lane_km,
            polygons: h.polygons,
            points: h.points,
            grid: Grid { cell_m: h.cell_size, columns: h.grid_size[0], rows: h.grid_size[1], entries: h.grid_entries },
            bytes: self.bytes,
            bytes_per_lane_km: self.bytes as f64 / self.lane_km.max(1e-9),
        }
        .serialize(serializer)
    }
}

/// Describe the tile at `path`.
pub fn info(path: &std::path::Path) -> Result<TileInfo> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let view = dash2sim_core::map::MapView::parse(&bytes).map_err(|e| Error::file(path, e))?;
    let h = view.header();
    let lane_km: f64 = (0..h.lanes)
        .filter_map(|i| view.lane(i))
        .map(|l| {
            let p: Vec<(f64, f64)> = l.points().collect();
            p.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum::<f64>()
        })
        .sum::<f64>()
        / 1000.0;
    let version = if h.boxes { VERSION_MAJOR } else { 1 };
    Ok(TileInfo { header: *h, version, lane_km, bytes: bytes.len() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::map::{Item, MapError, MapView};
    use dash2sim_core::obb::{Pose2, PACIFICA};

    fn square_road() -> TileContent {
        let lane = |points: Vec<(f64, f64)>| TileLane {
            points,
            width: 3.5,
            speed_limit: Some(50.0 / 3.6),
            class: 7,
            neighbours: (None, None),
            successors: vec![1],
            area: None,
        };
        TileContent {
            origin: [60.0, 24.0, 0.0],
            lanes: vec![lane(vec![(0.0, 0.0), (100.0, 0.0)]), lane(vec![(100.0, 0.0), (100.0, 100.0)])],
            polygons: vec![vec![(-20.0, -20.0), (-10.0, -20.0), (-10.0, -10.0), (-20.0, -10.0)]],
            source_counts: [1, 2, 3, 4],
        }
    }

    /// `n` parallel lanes 100 m long, `spacing` apart, 3 m wide, plus the square road's
    /// polygon; with `areas`, each lane's area is a polygon of 42 points around it
    /// (Lanelet2's kind, long enough to be walked in several runs), and they overlap when
    /// the lanes are closer than 3 m.
    fn parallel_lanes(n: usize, spacing: f64, areas: bool) -> TileContent {
        let mut content = square_road();
        content.lanes = (0..n)
            .map(|k| TileLane {
                points: vec![(0.0, k as f64 * spacing), (50.0, k as f64 * spacing + 1.0), (100.0, k as f64 * spacing)],
                width: 3.0,
                successors: Vec::new(),
                area: areas.then_some(k + 1),
                ..content.lanes[0].clone()
            })
            .collect();
        if areas {
            for k in 0..n {
                // The centreline's kink, 1 m up at x = 50.
                let centre = |x: f64| k as f64 * spacing + 1.0 - (x - 50.0).abs() / 50.0;
                let xs = (0..=20).map(|i| 5.0 * f64::from(i));
                let right = xs.clone().map(|x| (x, centre(x) - 1.5));
                let left = xs.rev().map(|x| (x, centre(x) + 1.5));
                content.polygons.push(right.chain(left).collect());
            }
        }
        content
    }

    /// The check of one pose, as the one-point queries answer it: each corner's distance
    /// to the drivable area, the lanes holding the centre or a corner (in point order, then
    /// lane order), and the centre's lane (nearest centreline among those holding it).
    fn reference(view: &MapView<'_>, pose: &Pose2) -> ([Option<f64>; 4], Vec<u32>, Option<u32>) {
        use dash2sim_core::drivable::SEARCH_RADIUS;
        let footprint = PACIFICA.at(pose);
        let corners = footprint.corners();
        let points = [(footprint.centre.x, footprint.centre.y), corners[0], corners[1], corners[2], corners[3]];
        let distances = corners.map(|(x, y)| view.distance_to_drivable(x, y, SEARCH_RADIUS, |_| true));
        let lanes: Vec<_> = (0..view.header().lanes).filter_map(|i| view.lane(i)).collect();
        let mut occupied = Vec::new();
        for &(x, y) in &points {
            for lane in lanes.iter().filter(|l| l.distance_outside(x, y) <= 0.0) {
                if !occupied.contains(&lane.index) {
                    occupied.push(lane.index);
                }
            }
        }
        let (cx, cy) = points[0];
        let centre = lanes
            .iter()
            .filter(|l| l.distance_outside(cx, cy) <= 0.0)
            .min_by(|a, b| a.project(cx, cy).distance.total_cmp(&b.project(cx, cy).distance))
            .map(|l| l.index);
        occupied.truncate(dash2sim_core::drivable::MAX_OCCUPIED);
        (distances, occupied, centre)
    }

    /// The same tile in format 1: no item boxes.
    fn without_boxes(tile: &[u8]) -> Vec<u8> {
        let view = MapView::parse(tile).expect("tile");
        let mut v1 = tile[..view.header().layout().expect("layout")[6]].to_vec();
        v1[6] = 1;
        let crc = body_checksum(&v1);
        v1[CRC_AT..CRC_AT + 4].copy_from_slice(&crc.to_le_bytes());
        v1
    }

    #[test]
    fn the_check_agrees_with_one_point_queries_on_sparse_and_crowded_tiles() {
        use dash2sim_core::drivable::{Channel, Checker};
        // 10 lanes 7 m apart: every item near a footprint is remembered. 300 lanes 0.3 m
        // apart: more grid entries near a footprint than the check remembers, so the rest
        // are measured as they come and occupancy is looked up point by point.
        // Each in format 2 and in format 1, whose check reads every lane near the footprint;
        // and with polygon areas (Lanelet2's kind), 2 m apart so that they overlap.
        let cases = [(10, 7.0, 2, false), (10, 7.0, 1, false), (300, 0.3, 2, false), (300, 0.3, 1, false)];
        for (n, spacing, format, areas) in cases.into_iter().chain([(12, 2.0, 2, true), (12, 2.0, 1, true)]) {
            let mut bytes = encode(&parallel_lanes(n, spacing, areas), 50.0);
            if format == 1 {
                bytes = without_boxes(&bytes);
            }
            let view = MapView::parse(&bytes).expect("tile");
            assert_eq!(view.header().boxes, format == 2);
            let checker = Checker::new(view, PACIFICA);
            let mut compared = 0;
            for i in 0..40 {
                for j in 0..12 {
                    let pose =
                        Pose2::new(-8.0 + 3.1 * f64::from(i), -12.0 + 9.7 * f64::from(j), 0.3 * f64::from(i + j));
                    let check = checker.check::<1>(&pose, Channel::Insensitive, None);
                    let (corners, occupied, centre) = reference(&view, &pose);
                    assert_eq!(check.corners, corners, "{n} lanes, pose {pose:?}");
                    assert_eq!(check.occupied.as_slice(), occupied.as_slice(), "{n} lanes, pose {pose:?}");
                    assert_eq!(check.centre_lane.map(|c| c.lane), centre, "{n} lanes, pose {pose:?}");
                    compared += usize::from(!occupied.is_empty());
                }
            }
            assert!(compared > 100, "{n} lanes: only {compared} poses on a lane");
        }
    }

    #[test]
    fn the_polygon_index_gives_the_checks_answers_bit_for_bit() {
        use dash2sim_core::drivable::{Channel, Checker, LaneSet, PoseCheck};
        // Tiles of buffered centrelines (OpenStreetMap's) get no index.
        let osm = encode(&square_road(), 25.0);
        assert!(polygon_index::build(&MapView::parse(&osm).expect("tile")).is_none());
        // 12 lanelet-like polygons 3 m wide, 2 m apart (they overlap), and a free-standing
        // square: every way a point can lie.
        let bytes = encode(&parallel_lanes(12, 2.0, true), 50.0);
        let view = MapView::parse(&bytes).expect("tile");
        let arrays = polygon_index::build(&view).expect("a tile of polygons");
        let index = arrays.view();
        let (plain, indexed) = (Checker::new(view, PACIFICA), Checker::new(view, PACIFICA).with_index(index));
        let mut channel = LaneSet::<1>::new();
        channel.insert(3);
        let bits = |c: &PoseCheck| c.corners.map(|d| d.map(f64::to_bits));
        let (mut inside, mut outside, mut far, mut whole) = (0, 0, 0, 0);
        for i in 0..70 {
            for j in 0..30 {
                let pose = Pose2::new(-30.0 + 2.3 * f64::from(i), -25.0 + 2.9 * f64::from(j), 0.37 * f64::from(i * j));
                for previous in [None, Some(4)] {
                    let (a, b) = (
                        plain.check::<1>(&pose, Channel::Insensitive, previous),
                        indexed.check::<1>(&pose, Channel::Insensitive, previous),
                    );
                    assert_eq!((bits(&a), &a), (bits(&b), &b), "pose {pose:?}");
                    // The channel-sensitive mode does not use the index.
                    let sensitive = Channel::Sensitive(&channel);
                    assert_eq!(plain.check(&pose, sensitive, previous), indexed.check(&pose, sensitive, previous));
                }
                for d in plain.check::<1>(&pose, Channel::Insensitive, None).corners {
                    match d {
                        Some(d) if d <= 0.0 => inside += 1,
                        Some(_) => outside += 1,
                        None => far += 1,
                    }
                }
                let centre = PACIFICA.at(&pose).centre;
                let cell = index.cell_of(centre.x, centre.y);
                whole += cell.map_or(0, |c| index.areas(c).iter().filter(|a| a.whole).count());
            }
        }
        assert!(inside > 1000 && outside > 1000 && far > 1000 && whole > 100, "{inside} {outside} {far} {whole}");
        // Outside the grid, and at a point that is not a number: nothing.
        assert_eq!(index.cell_of(-1e6, 0.0), None);
        assert_eq!(index.cell_of(f64::NAN, 0.0), None);
    }

    #[test]
    fn the_lane_index_gives_the_checks_answers_bit_for_bit_in_both_modes() {
        use dash2sim_core::drivable::{Channel, Checker, LaneSet, PoseCheck};
        // Tiles with polygons get no lane index.
        assert!(lane_index::build(&MapView::parse(&encode(&square_road(), 25.0)).expect("tile")).is_none());
        // 12 kinked lanes 3 m wide, 2.6 m apart (they overlap), of every width from 2 to
        // 7.5 m; a lane across them all; a ring of 72 short segments (ties between
        // neighbours, a centre far from it) and a lane doubling back on itself.
        let mut content = parallel_lanes(12, 2.6, false);
        content.polygons.clear();
        for (k, lane) in content.lanes.iter_mut().enumerate() {
            lane.width = 2.0 + 0.5 * k as f64;
        }
        let template = content.lanes[0].clone();
        let lane = |points: Vec<(f64, f64)>, width: f64| TileLane { points, width, ..template.clone() };
        content.lanes.push(lane(vec![(40.0, -20.0), (45.0, 60.0)], 3.5));
        let ring = (0..=72).map(|k| {
            let a = f64::from(k) * std::f64::consts::TAU / 72.0;
            (150.0 + 20.0 * a.cos(), 15.0 + 20.0 * a.sin())
        });
        content.lanes.push(lane(ring.collect(), 4.0));
        content.lanes.push(lane(vec![(120.0, 60.0), (180.0, 62.0), (121.0, 64.0)], 3.0));
        let bytes = encode(&content, 25.0);
        let view = MapView::parse(&bytes).expect("tile");
        let arrays = lane_index::build(&view).expect("a tile of buffered lanes");
        let index = arrays.view();
        let (plain, indexed) = (Checker::new(view, PACIFICA), Checker::new(view, PACIFICA).with_lane_index(index));
        let mut channel = LaneSet::<1>::new();
        for lane in [3, 4, 12, 13] {
            channel.insert(lane);
        }
        let bits = |c: &PoseCheck| c.corners.map(|d| d.map(f64::to_bits));
        let (mut inside, mut outside, mut far, mut sensitive_differs) = (0, 0, 0, 0);
        for i in 0..120 {
            for j in 0..50 {
                let pose = Pose2::new(-30.0 + 1.9 * f64::from(i), -25.0 + 2.3 * f64::from(j), 0.37 * f64::from(i * j));
                for previous in [None, Some(4), Some(13)] {
                    for mode in [Channel::Insensitive, Channel::Sensitive(&channel)] {
                        let (a, b) =
                            (plain.check::<1>(&pose, mode, previous), indexed.check::<1>(&pose, mode, previous));
                        assert_eq!((bits(&a), &a), (bits(&b), &b), "pose {pose:?}, {mode:?}");
                    }
                }
                let insensitive = plain.check::<1>(&pose, Channel::Insensitive, None);
                sensitive_differs +=
                    usize::from(insensitive.corners != plain.check(&pose, Channel::Sensitive(&channel), None).corners);
                for d in insensitive.corners {
                    match d {
                        Some(d) if d <= 0.0 => inside += 1,
                        Some(_) => outside += 1,
                        None => far += 1,
                    }
                }
            }
        }
        assert!(
            inside > 3000 && outside > 3000 && far > 3000 && sensitive_differs > 1000,
            "{inside} {outside} {far} {sensitive_differs}"
        );
        // Outside the grid, and at a point that is not a number: nothing.
        assert_eq!(index.cell_of(-1e6, 0.0), None);
        assert_eq!(index.cell_of(f64::NAN, 0.0), None);
        // Built where the checks pay for it: a handful of checks keep the grid, many get the
        // index; a tile of polygons gets its index whatever the number.
        let cells = lane_index::cells(&view);
        assert!(cells > 100, "{cells} cells");
        assert!(fine_index::for_checks(&view, cells).is_none());
        assert!(matches!(fine_index::for_checks(&view, 4 * cells), Some(fine_index::FineIndex::Lanes(_))));
        let polygons = encode(&parallel_lanes(3, 5.0, true), 50.0);
        let polygons = MapView::parse(&polygons).expect("tile");
        assert!(matches!(fine_index::for_checks(&polygons, 0), Some(fine_index::FineIndex::Polygons(_))));
    }

    #[test]
    fn a_tile_round_trips_and_answers_distance_queries() {
        let bytes = encode(&square_road(), 25.0);
        let view = MapView::parse(&bytes).expect("valid");
        assert_eq!(view.header().source_counts, [1, 2, 3, 4]);
        let lane = view.lane(0).expect("lane");
        assert_eq!(lane.points().collect::<Vec<_>>(), vec![(0.0, 0.0), (100.0, 0.0)]);
        assert_eq!((lane.width, lane.class, lane.successors().collect::<Vec<_>>()), (3.5, 7, vec![1]));
        assert!((lane.speed_limit.expect("limit") - 13.89).abs() < 1e-9);
        let all = |_: Item| true;
        // On the first lane's centreline; 1 m outside its edge; at the corner's round join.
        assert_eq!(view.distance_to_drivable(50.0, 0.0, 5.0, all), Some(-1.75));
        assert!((view.distance_to_drivable(50.0, 2.75, 5.0, all).expect("near") - 1.0).abs() < 1e-6);
        assert!((view.distance_to_drivable(102.0, -2.0, 5.0, all).expect("near") - (8f64.sqrt() - 1.75)).abs() < 1e-6);
        // Inside the polygon, and far from everything.
        assert!(view.distance_to_drivable(-15.0, -15.0, 5.0, all).expect("inside") < 0.0);
        assert_eq!(view.distance_to_drivable(50.0, 60.0, 5.0, all), None);
        // Channel-sensitive: only lane 1 counts.
        let only_second = |i: Item| i == Item::Lane(1);
        assert!(view.distance_to_drivable(50.0, 0.0, 5.0, only_second).is_none());
    }

    #[test]
    fn a_lane_whose_area_is_a_polygon_is_measured_against_the_polygon() {
        let mut content = square_road();
        content.lanes.push(TileLane {
            points: vec![(-20.0, -15.0), (-10.0, -15.0)],
            width: 10.0,
            speed_limit: None,
            class: 11,
            neighbours: (None, None),
            successors: vec![],
            area: Some(0),
        });
        let bytes = encode(&content, 25.0);
        let view = MapView::parse(&bytes).expect("valid");
        let lane = view.lane(2).expect("lane");
        assert_eq!(lane.area, Some(0));
        // The polygon's corner region: inside the square, where a 10 m wide capsule would
        // have rounded the corner off, and outside the square where the capsule reaches.
        assert!((lane.distance_outside(-10.5, -10.5) - -0.5).abs() < 1e-6);
        assert!((lane.distance_outside(-15.0, -21.0) - 1.0).abs() < 1e-6);
        // The polygon is reached through its lane only.
        let mut seen = Vec::new();
        view.for_each_near(-15.0, -15.0, 1.0, |item| seen.push(item));
        assert!(seen.contains(&Item::Lane(2)) && !seen.iter().any(|i| matches!(i, Item::Polygon(_))), "{seen:?}");
        // A lane naming a polygon the tile lacks is refused.
        let mut bad = bytes.clone();
        let at = view.header().layout().expect("layout")[1] + 2 * 28 + 26;
        bad[at] = 9;
        let crc = body_checksum(&bad);
        bad[CRC_AT..CRC_AT + 4].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(MapView::parse(&bad), Err(MapError::BadReference("lane", 2)));
    }

    #[test]
    fn polygon_distances_equal_every_edge_measured_with_culls_and_limits_or_without() {
        use dash2sim_core::map::segment_distance;
        use rand::{Rng, SeedableRng};
        // A 60-point star with uneven arms (walked in four runs of 16 edges), and a thin
        // sliver: points inside, outside, near vertices and far away.
        let star: Vec<(f64, f64)> = (0..60)
            .map(|i| {
                let angle = std::f64::consts::TAU * f64::from(i) / 60.0;
                let r = if i % 2 == 0 { 20.0 + f64::from(i % 7) } else { 8.0 };
                (r * angle.cos(), r * angle.sin())
            })
            .collect();
        let mut content = square_road();
        content.polygons = vec![star, vec![(30.0, 0.0), (60.0, 0.4), (30.0, 0.5)]];
        let bytes = encode(&content, 25.0);
        let view = MapView::parse(&bytes).expect("tile");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(16);
        for j in 0..2u32 {
            let ring: Vec<(f64, f64)> = view.polygon(j).expect("ring").collect();
            for _ in 0..2000 {
                let p = (rng.random_range(-35.0..65.0), rng.random_range(-35.0..35.0));
                // Every edge, no cull: the nearest edge's distance, even-odd parity.
                let mut inside = false;
                let mut nearest = f64::INFINITY;
                for (k, &b) in ring.iter().enumerate() {
                    let a = ring[(k + ring.len() - 1) % ring.len()];
                    nearest = nearest.min(segment_distance(p, a, b));
                    if (a.1 > p.1) != (b.1 > p.1) && p.0 < a.0 + (p.1 - a.1) * (b.0 - a.0) / (b.1 - a.1) {
                        inside = !inside;
                    }
                }
                let exact = if inside { -nearest } else { nearest };
                assert_eq!(view.polygon_distance(j, p.0, p.1), Some(exact), "polygon {j}, {p:?}");
                // With limits: exact below the limit; at or above it, a value at or above it
                // of the right sign.
                let limits = [f64::NEG_INFINITY, -6.0, -2.0, -0.5, 0.0, 1.0, 5.0];
                let mut d = [0.0; 7];
                view.polygon_distances(j, &[p; 7], &limits, &mut d).expect("polygon");
                for (&d, &limit) in d.iter().zip(&limits) {
                    assert_eq!(d <= 0.0, inside, "polygon {j}, {p:?}, limit {limit}");
                    if exact < limit {
                        assert_eq!(d, exact, "polygon {j}, {p:?}, limit {limit}");
                    } else {
                        assert!(d >= limit, "polygon {j}, {p:?}, limit {limit}: {d} < {limit}");
                    }
                }
            }
        }
    }

    #[test]
    fn item_boxes_hold_their_areas_and_a_box_that_does_not_is_refused() {
        let mut content = square_road();
        content.lanes[0].points = vec![(0.1, 0.3), (100.7, -0.2)];
        let bytes = encode(&content, 25.0);
        let view = MapView::parse(&bytes).expect("valid");
        // The centreline grown by half the 3.5 m width, rounded outward to f32.
        let (lo, hi) = view.item_box(Item::Lane(0)).expect("box");
        assert!(f64::from(lo[0]) <= 0.1f32 as f64 - 1.75 && f64::from(lo[0]) > 0.1f32 as f64 - 1.75 - 1e-5, "{lo:?}");
        assert!(f64::from(hi[1]) >= 0.3f32 as f64 + 1.75 && f64::from(hi[1]) < 0.3f32 as f64 + 1.75 + 1e-5, "{hi:?}");
        assert_eq!(view.item_box(Item::Polygon(0)), Some(([-20.0, -20.0], [-10.0, -10.0])));
        // A lane's box shrunk by 1 cm no longer holds its area: the tile is refused.
        let mut lying = bytes.clone();
        let at = view.header().layout().expect("layout")[6];
        lying[at..at + 4].copy_from_slice(&(lo[0] + 0.01).to_le_bytes());
        let crc = body_checksum(&lying);
        lying[CRC_AT..CRC_AT + 4].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(MapView::parse(&lying), Err(MapError::BadValue("lane box", 0)));
        // Format 1 has no boxes; it is read, and its answers are the same.
        let v1 = without_boxes(&bytes);
        let old = MapView::parse(&v1).expect("format 1");
        assert_eq!((old.header().boxes, old.item_box(Item::Lane(0))), (false, None));
        assert_eq!(
            old.distance_to_drivable(50.0, 3.0, 5.0, |_| true),
            view.distance_to_drivable(50.0, 3.0, 5.0, |_| true)
        );
    }

    #[test]
    fn corruption_and_truncation_are_refused() {
        let bytes = encode(&square_road(), 25.0);
        assert_eq!(MapView::parse(&bytes[..bytes.len() - 1]), Err(MapError::BadLength));
        assert_eq!(MapView::parse(&bytes[..10]), Err(MapError::TooShort));
        let mut flipped = bytes.clone();
        flipped[HEADER_LEN + 3] ^= 0x10;
        assert_eq!(MapView::parse(&flipped), Err(MapError::BadChecksum));
        let mut version = bytes.clone();
        version[6] = 3;
        assert_eq!(MapView::parse(&version), Err(MapError::UnsupportedVersion(3)));
        let mut magic = bytes;
        magic[0] = b'X';
        assert_eq!(MapView::parse(&magic), Err(MapError::BadMagic));
    }

    #[test]
    fn offset_lines_keep_their_distance_around_a_bend() {
        let line = [(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)];
        let left = offset_polyline(&line, 2.0);
        assert_eq!(left[0], (0.0, 2.0));
        // Inside of the left turn: the miter point sits 2 m from both segments.
        assert!((left[1].0 - 8.0).abs() < 1e-9 && (left[1].1 - 2.0).abs() < 1e-9, "{left:?}");
        assert_eq!(left[2], (8.0, 10.0));
    }
}
