//! The compact map tile (format v2, `docs/map-tile.md`; v1 is read too) and a zero-copy
//! view of it.
//!
//! A tile is a byte slice — from flash, a file or a `static` — holding an ENU origin,
//! lanes (centreline in driving order, width, speed limit, road class, neighbours and
//! successors), drivable polygons, a uniform grid index so that a query touches only
//! the lanes near it, and (v2) the bounding box of every lane's and polygon's area, so that
//! a lane near a query in the grid but far from it in fact is passed over without reading
//! its points. [`MapView::parse`] checks the whole tile once (magic, version,
//! CRC-32C, every length, index and float); after that every accessor is cheap and none
//! can panic, so a truncated or corrupted tile is an error, never a crash.
//!
//! A lane's area is its centreline buffered by half its width with round caps and joins
//! (the union of one capsule per segment): where ways meet, the round ends cover the
//! junction, which is the lenient junction the verification wants.

use crc::{Crc, CRC_32_ISCSI};

/// The file's first six bytes.
pub const MAGIC: [u8; 6] = *b"D2SMAP";
/// Format major version written by this crate; this view reads it and version 1 (the
/// same without item boxes).
pub const VERSION_MAJOR: u8 = 2;
/// Format minor version written by this crate (a reader accepts any minor of its major).
pub const VERSION_MINOR: u8 = 0;
/// Header length in bytes.
pub const HEADER_LEN: usize = 88;
/// Bytes per point (x, y as f32).
pub const POINT_LEN: usize = 8;
/// Bytes per lane record.
pub const LANE_LEN: usize = 28;
/// Bytes per polygon record.
pub const POLYGON_LEN: usize = 8;
/// Bytes per item box (lo x, lo y, hi x, hi y as f32; format 2).
pub const BOX_LEN: usize = 16;
/// "No neighbour".
pub const NONE: u32 = u32::MAX;
/// Grid entries with this bit set name a polygon, otherwise a lane.
pub const POLYGON_BIT: u32 = 0x8000_0000;

/// CRC-32C (Castagnoli), the checksum of the tile's body.
pub const CRC32C: Crc<u32> = Crc::<u32>::new(&CRC_32_ISCSI);

/// Why a tile was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapError {
    /// Shorter than the header.
    TooShort,
    /// Not a dash2sim map tile.
    BadMagic,
    /// A major version this reader does not know.
    UnsupportedVersion(u8),
    /// The body does not match its CRC-32C.
    BadChecksum,
    /// The sections do not add up to the tile's length.
    BadLength,
    /// A record refers outside its section (section name, record index).
    BadReference(&'static str, u32),
    /// A coordinate, size or origin is not finite or out of range (section, index).
    BadValue(&'static str, u32),
}

impl core::fmt::Display for MapError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            MapError::TooShort => write!(f, "shorter than the {HEADER_LEN}-byte header"),
            MapError::BadMagic => write!(f, "not a dash2sim map tile (bad magic)"),
            MapError::UnsupportedVersion(v) => {
                write!(f, "format version {v} is not supported (this reader: 1 and {VERSION_MAJOR})")
            }
            MapError::BadChecksum => write!(f, "CRC-32C mismatch: the tile is corrupted"),
            MapError::BadLength => write!(f, "section lengths do not match the tile length (truncated?)"),
            MapError::BadReference(section, i) => write!(f, "{section} {i} refers outside the tile"),
            MapError::BadValue(section, i) => write!(f, "{section} {i} has a value out of range"),
        }
    }
}

impl core::error::Error for MapError {}

fn u16_at(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[x, y]) => u16::from_le_bytes([x, y]),
        _ => 0,
    }
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    match b.get(at..at + 4) {
        Some(&[a, c, d, e]) => u32::from_le_bytes([a, c, d, e]),
        _ => 0,
    }
}

fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

fn f64_at(b: &[u8], at: usize) -> f64 {
    match b.get(at..at + 8) {
        Some(s) => {
            let mut a = [0u8; 8];
            a.copy_from_slice(s);
            f64::from_le_bytes(a)
        }
        None => f64::NAN,
    }
}

/// The counts and grid geometry of a tile, from its header.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Header {
    /// ENU origin: latitude, longitude (degrees), height (m).
    pub origin: [f64; 3],
    /// Points.
    pub points: u32,
    /// Lanes.
    pub lanes: u32,
    /// Successor entries.
    pub successors: u32,
    /// Drivable polygons.
    pub polygons: u32,
    /// Grid entries.
    pub grid_entries: u32,
    /// Grid cell size, m.
    pub cell_size: f32,
    /// Grid lower-left corner (x, y), m.
    pub grid_min: [f32; 2],
    /// Grid columns and rows.
    pub grid_size: [u16; 2],
    /// What the source file held: nodes, ways, highway ways, relations (for `map info`).
    pub source_counts: [u32; 4],
    /// Whether the tile has a box per lane and polygon (format 2; format 1 has none).
    pub boxes: bool,
}

impl Header {
    fn read(b: &[u8]) -> Header {
        Header {
            origin: [f64_at(b, 8), f64_at(b, 16), f64_at(b, 24)],
            points: u32_at(b, 32),
            lanes: u32_at(b, 36),
            successors: u32_at(b, 40),
            polygons: u32_at(b, 44),
            grid_entries: u32_at(b, 48),
            cell_size: f32_at(b, 52),
            grid_min: [f32_at(b, 56), f32_at(b, 60)],
            grid_size: [u16_at(b, 64), u16_at(b, 66)],
            source_counts: [u32_at(b, 68), u32_at(b, 72), u32_at(b, 76), u32_at(b, 80)],
            boxes: b.get(6).is_some_and(|&major| major >= 2),
        }
    }

    /// Write the header (CRC left zero) into `out[..HEADER_LEN]`.
    pub fn write(&self, out: &mut [u8]) {
        let Some(h) = out.get_mut(..HEADER_LEN) else { return };
        h.fill(0);
        h[..6].copy_from_slice(&MAGIC);
        h[6] = if self.boxes { VERSION_MAJOR } else { 1 };
        h[7] = VERSION_MINOR;
        for (k, v) in self.origin.iter().enumerate() {
            h[8 + 8 * k..16 + 8 * k].copy_from_slice(&v.to_le_bytes());
        }
        for (at, v) in
            [(32, self.points), (36, self.lanes), (40, self.successors), (44, self.polygons), (48, self.grid_entries)]
        {
            h[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
        for (at, v) in [(52, self.cell_size), (56, self.grid_min[0]), (60, self.grid_min[1])] {
            h[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
        h[64..66].copy_from_slice(&self.grid_size[0].to_le_bytes());
        h[66..68].copy_from_slice(&self.grid_size[1].to_le_bytes());
        for (k, v) in self.source_counts.iter().enumerate() {
            h[68 + 4 * k..72 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
    }

    fn cells(&self) -> usize {
        usize::from(self.grid_size[0]) * usize::from(self.grid_size[1])
    }

    /// Byte offsets of the sections: points, lanes, successors, polygons, cell starts,
    /// entries, boxes (empty in format 1), end.
    pub fn layout(&self) -> Option<[usize; 8]> {
        let points = HEADER_LEN;
        let lanes = points.checked_add((self.points as usize).checked_mul(POINT_LEN)?)?;
        let successors = lanes.checked_add((self.lanes as usize).checked_mul(LANE_LEN)?)?;
        let polygons = successors.checked_add((self.successors as usize).checked_mul(4)?)?;
        let cells = polygons.checked_add((self.polygons as usize).checked_mul(POLYGON_LEN)?)?;
        let entries = cells.checked_add(self.cells().checked_add(1)?.checked_mul(4)?)?;
        let boxes = entries.checked_add((self.grid_entries as usize).checked_mul(4)?)?;
        let items = if self.boxes { (self.lanes as usize).checked_add(self.polygons as usize)? } else { 0 };
        let end = boxes.checked_add(items.checked_mul(BOX_LEN)?)?;
        Some([points, lanes, successors, polygons, cells, entries, boxes, end])
    }
}

/// Where the body's CRC-32C is stored.
pub const CRC_AT: usize = 84;

/// CRC-32C of a tile body, stored at bytes 84..88.
pub fn body_checksum(tile: &[u8]) -> u32 {
    CRC32C.checksum(tile.get(HEADER_LEN..).unwrap_or(&[]))
}

/// One lane of a tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lane<'a> {
    view: MapView<'a>,
    /// Index in the tile.
    pub index: u32,
    first_point: u32,
    point_count: u16,
    /// Width, m.
    pub width: f64,
    /// Speed limit, m/s, if known.
    pub speed_limit: Option<f64>,
    /// Road class (see `docs/map-tile.md`).
    pub class: u8,
    /// Lane to the left in the same direction.
    pub left: Option<u32>,
    /// Lane to the right in the same direction.
    pub right: Option<u32>,
    successor_first: u32,
    successor_count: u16,
    /// The polygon that is this lane's area (Lanelet2 lanes), instead of the buffered
    /// centreline.
    pub area: Option<u32>,
}

impl<'a> Lane<'a> {
    /// Centreline points in driving order, ENU metres.
    pub fn points(&self) -> impl Iterator<Item = (f64, f64)> + 'a {
        self.centreline().points()
    }

    /// Lanes a vehicle may continue into at the end of this one.
    pub fn successors(&self) -> impl Iterator<Item = u32> + 'a {
        let view = self.view;
        (self.successor_first..self.successor_first + u32::from(self.successor_count))
            .filter_map(move |i| view.successor(i))
    }

    /// Distance from (x, y) to the centreline, and the heading of the nearest segment.
    pub fn nearest(&self, x: f64, y: f64) -> (f64, f64) {
        let p = self.project(x, y);
        (p.distance, p.heading)
    }

    /// The centreline and width (what the distance queries read).
    pub fn centreline(&self) -> Centreline<'a> {
        Centreline {
            points: self.view.stored_points(self.first_point, usize::from(self.point_count)),
            width: self.width,
        }
    }

    /// The point of the centreline nearest to (x, y).
    pub fn project(&self, x: f64, y: f64) -> Projection {
        self.centreline().project(x, y)
    }

    /// Signed distance from (x, y) to the lane's area: ≤ 0 inside.
    pub fn distance_outside(&self, x: f64, y: f64) -> f64 {
        let mut d = [0.0];
        self.distances_outside(&[(x, y)], &[f64::INFINITY], &mut d);
        d[0]
    }

    /// [`Lane::distance_outside`] of several points at once (one pass over the lane), each
    /// wanted only below its limit ([`MapView::polygon_distances`] says what comes back
    /// otherwise).
    pub fn distances_outside<const N: usize>(&self, points: &[(f64, f64); N], limits: &[f64; N], out: &mut [f64; N]) {
        let area = self.area.and_then(|polygon| self.view.polygon_distances(polygon, points, limits, out));
        if area.is_none() {
            self.centreline().distances_outside(points, limits, out);
        }
    }
}

/// What a lane's area is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LaneArea<'a> {
    /// The centreline buffered by half the width (OpenStreetMap lanes).
    Buffered(Centreline<'a>),
    /// A drivable polygon of the tile (Lanelet2 lanes).
    Polygon(u32),
}

/// A lane's centreline (its points as stored: x, y f32 pairs, range checked when the tile
/// was parsed) and width: the area is the centreline buffered by half the width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Centreline<'a> {
    points: &'a [StoredPoint],
    /// Width, m.
    pub width: f64,
}

impl<'a> Centreline<'a> {
    /// Points in driving order, ENU metres.
    pub fn points(&self) -> impl Iterator<Item = (f64, f64)> + 'a {
        self.points.iter().map(|p| wide(xy(p)))
    }

    /// The point nearest to (x, y).
    pub fn project(&self, x: f64, y: f64) -> Projection {
        let mut nearest = [Nearest::NONE];
        self.nearest_segments(&[(x, y)], &mut nearest);
        self.projection((x, y), &nearest[0])
    }

    /// The projection of `point` that its [`Centreline::nearest_segments`] result stands
    /// for (the same as [`Centreline::project`] when nothing cut the search short).
    pub fn projection(&self, point: (f64, f64), n: &Nearest) -> Projection {
        let segment = self.points.get(n.segment as usize..n.segment as usize + 2);
        let Some([a, b]) = segment.filter(|_| n.segment != u32::MAX) else {
            return Projection { distance: f64::INFINITY, heading: 0.0, along: 0.0 };
        };
        let (a, b) = (wide(xy(a)), wide(xy(b)));
        let direction = (b.0 - a.0, b.1 - a.1);
        let (t, _) = closest_on_segment(point, a, direction);
        // The arc length to the nearest segment, summed in driving order.
        let mut start = 0.0;
        let mut previous: Option<(f64, f64)> = None;
        for (k, p) in self.points().enumerate().take(n.segment as usize + 1) {
            if let Some(a) = previous {
                start += libm::sqrt((p.0 - a.0) * (p.0 - a.0) + (p.1 - a.1) * (p.1 - a.1));
            }
            if k == n.segment as usize {
                break;
            }
            previous = Some(p);
        }
        let (dx, dy) = direction;
        Projection {
            distance: n.distance(),
            heading: libm::atan2(dy, dx),
            along: start + t * libm::sqrt(dx * dx + dy * dy),
        }
    }

    /// Signed distances of `points` to the area (≤ 0 inside), exact up to the limits (or 0)
    /// and infinite beyond them.
    pub fn distances_outside<const N: usize>(&self, points: &[(f64, f64); N], limits: &[f64; N], out: &mut [f64; N]) {
        let mut nearest = [Nearest::NONE; N];
        self.nearest_within(points, limits, &mut nearest);
        for (d, best) in out.iter_mut().zip(&nearest) {
            *d = self.outside(best);
        }
    }

    /// The nearest segment to each point, not looking farther from the area than the
    /// point's limit (a limit of 0 or less: only as far as it takes to know whether the
    /// point is inside).
    pub fn nearest_within<const N: usize>(
        &self,
        points: &[(f64, f64); N],
        limits: &[f64; N],
        nearest: &mut [Nearest; N],
    ) {
        for (n, limit) in nearest.iter_mut().zip(limits) {
            *n = Nearest::within(limit.max(0.0) + self.width / 2.0);
        }
        self.nearest_segments(points, nearest);
    }

    /// The signed distance to the area (≤ 0 inside) of a point whose nearest segment is `n`.
    pub fn outside(&self, n: &Nearest) -> f64 {
        n.distance() - self.width / 2.0
    }

    /// For each point, the nearest segment, in one pass over the centreline.
    ///
    /// Segments are compared by squared distance and only the winner's distance is taken
    /// ([`Nearest::distance`]). The points are read in chunks of [`CHUNK`] segments; a
    /// chunk whose bounding box is farther from every point than that point's nearest
    /// segment so far (or than its [`Nearest::within`] cut-off) is skipped whole — exactly,
    /// since no segment in it could be nearer.
    pub fn nearest_segments(&self, points: &[(f64, f64)], nearest: &mut [Nearest]) {
        let count = self.points.len();
        let mut first = 0usize;
        // Chunks overlap by one point: the last point of one is the first of the next.
        while first + 1 < count {
            let n = (count - first).min(CHUNK + 1);
            let chunk = self.points.get(first..first + n).unwrap_or(&[]);
            let (lo, hi) = bounding_box(chunk);
            // The points this chunk could bring nearer (one bit each).
            let reachable = points.iter().zip(nearest.iter()).enumerate().fold(0u64, |mask, (k, (&point, best))| {
                if k < 64 && box_reaches(lo, hi, point, best.squared) {
                    mask | 1 << k
                } else {
                    mask
                }
            });
            if reachable != 0 {
                let mut a32 = chunk.first().map_or([0.0; 2], xy);
                let mut a = wide(a32);
                for (j, p32) in chunk.iter().skip(1).map(xy).enumerate() {
                    let p = wide(p32);
                    let direction = (p.0 - a.0, p.1 - a.1);
                    // The segment's own box: where f64 is software, culling each segment in
                    // f32 saves most of the f64 work; elsewhere it costs more than it saves.
                    let (lo, hi) = ([a32[0].min(p32[0]), a32[1].min(p32[1])], [a32[0].max(p32[0]), a32[1].max(p32[1])]);
                    let active = points
                        .iter()
                        .zip(nearest.iter_mut())
                        .enumerate()
                        .filter(|(k, _)| *k < 64 && reachable & 1 << k != 0)
                        .filter(|(_, (&point, best))| !SOFT_F64 || box_reaches(lo, hi, point, best.squared));
                    for (_, (&point, best)) in active {
                        let (_, residual) = closest_on_segment(point, a, direction);
                        let squared = residual.0 * residual.0 + residual.1 * residual.1;
                        if squared < best.squared {
                            *best = Nearest { squared, residual, segment: (first + j) as u32 };
                        }
                    }
                    (a, a32) = (p, p32);
                }
            }
            first += n - 1;
        }
    }
}

/// Whether f64 arithmetic is done in software here (Cortex-M: a single-precision FPU at
/// most): the box culls then run in f32 and reach down to single segments.
const SOFT_F64: bool = cfg!(all(target_arch = "arm", not(target_feature = "fp64")));

/// The precision of the box culls (see [`SOFT_F64`]).
#[cfg(all(target_arch = "arm", not(target_feature = "fp64")))]
type Cull = f32;
#[cfg(not(all(target_arch = "arm", not(target_feature = "fp64"))))]
type Cull = f64;

/// Whether a point may lie within `squared` (a squared distance) of the box `lo`–`hi` (the
/// stored f32 coordinates). The box is grown by [`CULL_SLACK`], far more than f32's rounding
/// at map distances, so that `false` is certain.
fn box_reaches(lo: [f32; 2], hi: [f32; 2], point: (f64, f64), squared: f64) -> bool {
    let (x, y) = (point.0 as Cull, point.1 as Cull);
    let slack = CULL_SLACK as Cull;
    let dx = (lo[0] as Cull - x).max(x - hi[0] as Cull).max(slack) - slack;
    let dy = (lo[1] as Cull - y).max(y - hi[1] as Cull).max(slack) - slack;
    dx * dx + dy * dy <= squared as Cull * 1.001
}

/// Margin on a box in the culls, m: f32 rounding of map coordinates (tiles span a few km)
/// is below a millimetre.
const CULL_SLACK: f32 = 0.01;

/// A point as stored: x, y as little-endian f32.
type StoredPoint = [u8; POINT_LEN];

/// The coordinates of a stored point.
fn xy(p: &StoredPoint) -> [f32; 2] {
    let [a, b, c, d, e, f, g, h] = *p;
    [f32::from_le_bytes([a, b, c, d]), f32::from_le_bytes([e, f, g, h])]
}

/// Distance from `point` to the nearest of `edges` (x, y of both ends, as stored), found as
/// [`MapView::polygon_distances`] finds it; infinite for none.
pub fn edges_distance(edges: &[[f32; 4]], point: (f64, f64)) -> f64 {
    let mut n = EdgeDistance::NONE;
    for &[ax, ay, bx, by] in edges {
        let (a, b) = (wide([ax, ay]), wide([bx, by]));
        n.offer(closest_on_segment(point, a, (b.0 - a.0, b.1 - a.1)).1);
    }
    n.distance()
}

/// The even-odd parity of `point` from `edges` (x, y of both ends, as stored), starting from
/// `parity`: the test [`MapView::polygon_distances`] makes, edge by edge.
pub fn edges_parity(edges: &[[f32; 4]], point: (f64, f64), parity: bool) -> bool {
    edges.iter().fold(parity, |inside, &[ax, ay, bx, by]| inside ^ crosses_ray(wide([ax, ay]), wide([bx, by]), point))
}

/// Whether the edge a–b crosses the ray from `p` towards +x (the even-odd rule's test).
/// Without branches (they would be mispredicted): where the edge is level the quotient is
/// not finite and the first test is false anyway.
fn crosses_ray(a: (f64, f64), b: (f64, f64), (x, y): (f64, f64)) -> bool {
    let straddles = (a.1 > y) != (b.1 > y);
    straddles & (x < a.0 + (y - a.1) * (b.0 - a.0) / (b.1 - a.1))
}

/// Stored coordinates as the f64 every distance is worked in.
fn wide(p: [f32; 2]) -> (f64, f64) {
    (f64::from(p[0]), f64::from(p[1]))
}

/// The box of stored points (finite, checked at parse: plain compares).
fn bounding_box(points: &[StoredPoint]) -> ([f32; 2], [f32; 2]) {
    let (mut lo, mut hi) = ([f32::INFINITY; 2], [f32::NEG_INFINITY; 2]);
    // Selects rather than branches (or `f32::min`, which also handles NaN): the compiler
    // makes them `minss`/`maxss`, where branches would be mispredicted half the time.
    for [x, y] in points.iter().map(xy) {
        lo = [if x < lo[0] { x } else { lo[0] }, if y < lo[1] { y } else { lo[1] }];
        hi = [if x > hi[0] { x } else { hi[0] }, if y > hi[1] { y } else { hi[1] }];
    }
    (lo, hi)
}

/// The box of a point and stored points.
fn bounding_box_from(first: [f32; 2], points: &[StoredPoint]) -> ([f32; 2], [f32; 2]) {
    let (lo, hi) = bounding_box(points);
    ([lo[0].min(first[0]), lo[1].min(first[1])], [hi[0].max(first[0]), hi[1].max(first[1])])
}

/// The distance from a point to its nearest polygon edge, found by squared distances.
///
/// Only the winner's `hypot` is taken, plus one for each edge that comes within a relative
/// 1e-9 of the nearest in squared distance (a vertex ends two edges, whose rounded
/// residuals may differ): the distance is the least of those, so it does not depend on the
/// order the edges come in.
#[derive(Clone, Copy, Debug)]
struct EdgeDistance {
    squared: f64,
    residual: (f64, f64),
    found: bool,
    ties: f64,
    inside: bool,
    /// An edge this near (squared) is near enough: the search for this point stops.
    enough: f64,
}

impl EdgeDistance {
    const NONE: EdgeDistance = EdgeDistance {
        squared: f64::INFINITY,
        residual: (0.0, 0.0),
        found: false,
        ties: f64::INFINITY,
        inside: false,
        enough: 0.0,
    };

    fn offer(&mut self, residual: (f64, f64)) {
        let squared = residual.0 * residual.0 + residual.1 * residual.1;
        if squared < self.squared {
            if self.found && self.squared <= squared * (1.0 + 1e-9) {
                self.ties = self.ties.min(libm::hypot(self.residual.0, self.residual.1));
            }
            (self.squared, self.residual, self.found) = (squared, residual, true);
        } else if self.found && squared <= self.squared * (1.0 + 1e-9) && residual != self.residual {
            // (The same residual again — the vertex two edges share — has the same hypot.)
            self.ties = self.ties.min(libm::hypot(residual.0, residual.1));
        }
    }

    /// Infinite when no edge was within the limit.
    fn distance(&self) -> f64 {
        if self.found {
            libm::hypot(self.residual.0, self.residual.1).min(self.ties)
        } else {
            f64::INFINITY
        }
    }
}

/// Segments [`Centreline::nearest_segments`] reads at a time (and may skip at once).
pub const CHUNK: usize = 16;

/// The segment of a centreline nearest to a point (what the projection needs besides is
/// worked out again for the winner alone).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    squared: f64,
    residual: (f64, f64),
    segment: u32,
}

impl Nearest {
    /// No segment yet.
    pub const NONE: Nearest = Nearest { squared: f64::INFINITY, residual: (0.0, 0.0), segment: u32::MAX };

    /// No segment yet, and none farther than `distance` wanted (with a little slack, so
    /// that rounding never drops one at the limit).
    pub fn within(distance: f64) -> Nearest {
        let d = distance * (1.0 + 1e-9) + 1e-9;
        Nearest { squared: d * d, ..Nearest::NONE }
    }

    /// Distance from the point to the segment, m (infinite when there is none).
    pub fn distance(&self) -> f64 {
        if self.segment == u32::MAX {
            f64::INFINITY
        } else {
            libm::hypot(self.residual.0, self.residual.1)
        }
    }
}

/// Where a point lies relative to a lane's centreline.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projection {
    /// Distance to the centreline, m.
    pub distance: f64,
    /// Heading of the nearest segment (driving direction), rad.
    pub heading: f64,
    /// Arc length from the lane's start to the nearest point, m.
    pub along: f64,
}

/// Distance from `p` to the segment `a`–`b`.
pub fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    let (_, (rx, ry)) = closest_on_segment(p, a, (b.0 - a.0, b.1 - a.1));
    libm::hypot(rx, ry)
}

/// The point of the segment from `a` along `direction` nearest to `p`: its parameter t
/// (0 at `a`, 1 at the end) and the residual `p` − that point.
fn closest_on_segment(p: (f64, f64), a: (f64, f64), direction: (f64, f64)) -> (f64, (f64, f64)) {
    let (dx, dy) = direction;
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 { (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (t, (p.0 - (a.0 + t * dx), p.1 - (a.1 + t * dy)))
}

/// What a grid entry names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Item {
    /// A lane index.
    Lane(u32),
    /// A drivable polygon index.
    Polygon(u32),
}

/// A validated tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapView<'a> {
    bytes: &'a [u8],
    header: Header,
    layout: [usize; 8],
}

impl<'a> MapView<'a> {
    /// Check `bytes` completely and view them.
    pub fn parse(bytes: &'a [u8]) -> Result<Self, MapError> {
        if bytes.len() < HEADER_LEN {
            return Err(MapError::TooShort);
        }
        if bytes.get(..6) != Some(&MAGIC[..]) {
            return Err(MapError::BadMagic);
        }
        let major = bytes.get(6).copied().unwrap_or(0);
        if !(1..=VERSION_MAJOR).contains(&major) {
            return Err(MapError::UnsupportedVersion(major));
        }
        let header = Header::read(bytes);
        let layout = header.layout().ok_or(MapError::BadLength)?;
        if layout[7] != bytes.len() {
            return Err(MapError::BadLength);
        }
        if body_checksum(bytes) != u32_at(bytes, CRC_AT) {
            return Err(MapError::BadChecksum);
        }
        let view = MapView { bytes, header, layout };
        view.validate()?;
        Ok(view)
    }

    fn validate(&self) -> Result<(), MapError> {
        let h = &self.header;
        let [lat, lon, height] = h.origin;
        if !((-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon) && height.is_finite()) {
            return Err(MapError::BadValue("origin", 0));
        }
        if !(h.cell_size.is_finite() && h.cell_size > 0.0 && h.grid_min.iter().all(|v| v.is_finite())) {
            return Err(MapError::BadValue("grid", 0));
        }
        for i in 0..h.points {
            let at = self.layout[0] + i as usize * POINT_LEN;
            if !(f32_at(self.bytes, at).is_finite() && f32_at(self.bytes, at + 4).is_finite()) {
                return Err(MapError::BadValue("point", i));
            }
        }
        for i in 0..h.lanes {
            let at = self.layout[1] + i as usize * LANE_LEN;
            let (first, count) = (u32_at(self.bytes, at), u32::from(u16_at(self.bytes, at + 4)));
            let neighbours = [u32_at(self.bytes, at + 12), u32_at(self.bytes, at + 16)];
            let (succ_first, succ_count) = (u32_at(self.bytes, at + 20), u32::from(u16_at(self.bytes, at + 24)));
            let points_ok = count >= 2 && first.checked_add(count).is_some_and(|end| end <= h.points);
            let succ_ok = succ_first.checked_add(succ_count).is_some_and(|end| end <= h.successors);
            let neighbours_ok = neighbours.iter().all(|&n| n == NONE || n < h.lanes);
            if !(points_ok && succ_ok && neighbours_ok) {
                return Err(MapError::BadReference("lane", i));
            }
            if u16_at(self.bytes, at + 6) == 0 {
                return Err(MapError::BadValue("lane", i));
            }
            let area = u32::from(u16_at(self.bytes, at + 26));
            if area > h.polygons {
                return Err(MapError::BadReference("lane", i));
            }
        }
        for i in 0..h.successors {
            if u32_at(self.bytes, self.layout[2] + i as usize * 4) >= h.lanes {
                return Err(MapError::BadReference("successor", i));
            }
        }
        for i in 0..h.polygons {
            let at = self.layout[3] + i as usize * POLYGON_LEN;
            let (first, count) = (u32_at(self.bytes, at), u32_at(self.bytes, at + 4));
            if !(count >= 3 && first.checked_add(count).is_some_and(|end| end <= h.points)) {
                return Err(MapError::BadReference("polygon", i));
            }
        }
        let mut previous = 0;
        for c in 0..=h.cells() {
            let start = u32_at(self.bytes, self.layout[4] + c * 4);
            let last = c == h.cells();
            if start < previous || start > h.grid_entries || (last && start != h.grid_entries) {
                return Err(MapError::BadReference("grid cell", c as u32));
            }
            previous = start;
        }
        for i in 0..h.grid_entries {
            let e = u32_at(self.bytes, self.layout[5] + i as usize * 4);
            let ok = if e & POLYGON_BIT != 0 { (e & !POLYGON_BIT) < h.polygons } else { e < h.lanes };
            if !ok {
                return Err(MapError::BadReference("grid entry", i));
            }
        }
        if h.boxes {
            self.validate_boxes()?;
        }
        Ok(())
    }

    /// Every box holds its item's area: a lane's centreline grown by half its width (or its
    /// polygon), a polygon's ring. A box that did not would make the check pass over a lane
    /// it should measure, so a tile whose boxes lie is refused like any other bad value.
    fn validate_boxes(&self) -> Result<(), MapError> {
        let h = &self.header;
        let holds = |(lo, hi): ([f32; 2], [f32; 2]), points: &[StoredPoint], margin: f64| {
            points.iter().map(|p| wide(xy(p))).all(|(x, y)| {
                f64::from(lo[0]) <= x - margin
                    && f64::from(lo[1]) <= y - margin
                    && x + margin <= f64::from(hi[0])
                    && y + margin <= f64::from(hi[1])
            })
        };
        for i in 0..h.lanes {
            let ok = match (self.stored_box(i as usize), self.lane_area(i)) {
                (Some(b), Some(LaneArea::Buffered(c))) => holds(b, c.points, c.width / 2.0),
                (Some(b), Some(LaneArea::Polygon(j))) => self.polygon_points(j).is_some_and(|ring| holds(b, ring, 0.0)),
                _ => false,
            };
            if !ok {
                return Err(MapError::BadValue("lane box", i));
            }
        }
        for j in 0..h.polygons {
            let b = self.stored_box(h.lanes as usize + j as usize);
            if !b.zip(self.polygon_points(j)).is_some_and(|(b, ring)| holds(b, ring, 0.0)) {
                return Err(MapError::BadValue("polygon box", j));
            }
        }
        Ok(())
    }

    /// Box `index` of the boxes section (lanes first, then polygons); none in format 1.
    fn stored_box(&self, index: usize) -> Option<([f32; 2], [f32; 2])> {
        if !self.header.boxes {
            return None;
        }
        let at = self.layout[6].checked_add(index.checked_mul(BOX_LEN)?)?;
        let b = self.bytes.get(at..at.checked_add(BOX_LEN)?)?;
        Some(([f32_at(b, 0), f32_at(b, 4)], [f32_at(b, 8), f32_at(b, 12)]))
    }

    /// The bounding box of an item's area (lo, hi), as stored (format 2).
    pub fn item_box(&self, item: Item) -> Option<([f32; 2], [f32; 2])> {
        match item {
            Item::Lane(i) if i < self.header.lanes => self.stored_box(i as usize),
            Item::Polygon(i) if i < self.header.polygons => self.stored_box(self.header.lanes as usize + i as usize),
            _ => None,
        }
    }

    /// Whether any of `points` may lie within its limit (0 or less: in) of `item`'s area,
    /// judged by the item's box alone — `false` is certain, so the item need not be read;
    /// always `true` without boxes (format 1).
    pub fn item_reaches<const N: usize>(&self, item: Item, points: &[(f64, f64); N], limits: &[f64; N]) -> bool {
        let Some((lo, hi)) = self.item_box(item) else { return true };
        points
            .iter()
            .zip(limits)
            .any(|(&point, &limit)| box_reaches(lo, hi, point, Nearest::within(limit.max(0.0)).squared))
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Tile length in bytes.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// Always false: a valid tile has at least a header.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Point `i` (ENU metres).
    pub fn point(&self, i: u32) -> Option<(f64, f64)> {
        (i < self.header.points).then(|| {
            let at = self.layout[0] + i as usize * POINT_LEN;
            (f64::from(f32_at(self.bytes, at)), f64::from(f32_at(self.bytes, at + 4)))
        })
    }

    fn successor(&self, i: u32) -> Option<u32> {
        (i < self.header.successors).then(|| u32_at(self.bytes, self.layout[2] + i as usize * 4))
    }

    /// Lane `i`.
    pub fn lane(&self, i: u32) -> Option<Lane<'a>> {
        if i >= self.header.lanes {
            return None;
        }
        let at = self.layout[1] + i as usize * LANE_LEN;
        let b = self.bytes;
        let speed = u16_at(b, at + 8);
        let neighbour = |v: u32| (v != NONE).then_some(v);
        Some(Lane {
            view: *self,
            index: i,
            first_point: u32_at(b, at),
            point_count: u16_at(b, at + 4),
            width: f64::from(u16_at(b, at + 6)) / 100.0,
            speed_limit: (speed != 0).then(|| f64::from(speed) / 100.0),
            class: b.get(at + 10).copied().unwrap_or(0),
            left: neighbour(u32_at(b, at + 12)),
            right: neighbour(u32_at(b, at + 16)),
            successor_first: u32_at(b, at + 20),
            successor_count: u16_at(b, at + 24),
            area: u16_at(b, at + 26).checked_sub(1).map(u32::from),
        })
    }

    /// The area of lane `i`: the cheap way to a lane's distances, without building a
    /// [`Lane`].
    pub fn lane_area(&self, i: u32) -> Option<LaneArea<'a>> {
        if i >= self.header.lanes {
            return None;
        }
        let at = self.layout[1] + i as usize * LANE_LEN;
        if let Some(polygon) = u16_at(self.bytes, at + 26).checked_sub(1) {
            return Some(LaneArea::Polygon(u32::from(polygon)));
        }
        let points = self.stored_points(u32_at(self.bytes, at), usize::from(u16_at(self.bytes, at + 4)));
        Some(LaneArea::Buffered(Centreline { points, width: f64::from(u16_at(self.bytes, at + 6)) / 100.0 }))
    }

    /// `count` points from point `first` as stored (lane and polygon ranges were checked
    /// when the tile was parsed, anything else reads as no points).
    fn stored_points(&self, first: u32, count: usize) -> &'a [StoredPoint] {
        let start = self.layout[0] + first as usize * POINT_LEN;
        let bytes = self.bytes.get(start..start + count * POINT_LEN).unwrap_or(&[]);
        bytes.as_chunks().0
    }

    /// The points of polygon `i` as stored (a ring, implicitly closed; at least three).
    fn polygon_points(&self, i: u32) -> Option<&'a [StoredPoint]> {
        if i >= self.header.polygons {
            return None;
        }
        let at = self.layout[3] + i as usize * POLYGON_LEN;
        let ring = self.stored_points(u32_at(self.bytes, at), u32_at(self.bytes, at + 4) as usize);
        (ring.len() >= 3).then_some(ring)
    }

    /// Points of polygon `i` (a ring, implicitly closed).
    pub fn polygon(&self, i: u32) -> Option<impl Iterator<Item = (f64, f64)> + 'a> {
        Some(self.polygon_points(i)?.iter().map(|p| wide(xy(p))))
    }

    /// Signed distance from (x, y) to polygon `i`: negative inside.
    pub fn polygon_distance(&self, i: u32, x: f64, y: f64) -> Option<f64> {
        let mut d = [0.0];
        self.polygon_distances(i, &[(x, y)], &[f64::INFINITY], &mut d)?;
        Some(d[0])
    }

    /// Signed distances from `points` to polygon `i` (negative inside), in one walk of its
    /// edges, each wanted exactly only below its limit: a distance below the limit is
    /// exact; one at or above it comes back as a value at or above it of the right sign
    /// (infinite outside; between the limit and 0 inside), which is cheaper to find. A
    /// limit of −∞ asks only whether the point is inside; +∞ for every distance exact.
    ///
    /// Points farther than their limit from the polygon's box are outside and done first.
    /// One walk of the edges then gives the others their inside/outside parity and those
    /// whose distance is wanted their nearest edge, until one is nearer than a negative
    /// limit's depth; a long ring is walked in runs of [`CHUNK`] edges, a run skipped for a
    /// point where its box cannot hold a nearer edge.
    pub fn polygon_distances<const N: usize>(
        &self,
        i: u32,
        points: &[(f64, f64); N],
        limits: &[f64; N],
        out: &mut [f64; N],
    ) -> Option<()> {
        let ring = self.polygon_points(i)?;
        out.fill(f64::INFINITY);
        let (lo, hi) = self.item_box(Item::Polygon(i)).unwrap_or_else(|| bounding_box(ring));
        let mut nearest = [EdgeDistance::NONE; N];
        let (mut active, mut measured) = (0u64, 0u64);
        for (k, ((&point, &limit), n)) in points.iter().zip(limits).zip(nearest.iter_mut()).enumerate() {
            n.enough = if limit < 0.0 { limit * limit } else { 0.0 };
            if k < 64 && box_reaches(lo, hi, point, Nearest::within(limit.max(0.0)).squared) {
                active |= 1 << k;
                if limit > f64::NEG_INFINITY {
                    measured |= 1 << k;
                }
            }
        }
        if active == 0 {
            return Some(());
        }
        // One walk: the even-odd parity of every active point, the nearest edge of those
        // whose distance is wanted (inside or not is known only at the end).
        let mut a32 = xy(ring.last()?);
        for chunk in ring.chunks(CHUNK) {
            let (lo, hi) = if ring.len() > CHUNK { bounding_box_from(a32, chunk) } else { (lo, hi) };
            let reachable = points.iter().zip(&nearest).enumerate().fold(0u64, |mask, (k, (&point, n))| {
                let wanted = k < 64 && measured & 1 << k != 0 && n.squared > n.enough;
                if wanted && box_reaches(lo, hi, point, n.squared) {
                    mask | 1 << k
                } else {
                    mask
                }
            });
            for b32 in chunk.iter().map(xy) {
                let (a, b) = (wide(a32), wide(b32));
                let direction = (b.0 - a.0, b.1 - a.1);
                for (k, (&(x, y), n)) in points.iter().zip(nearest.iter_mut()).enumerate() {
                    if k >= 64 || active & 1 << k == 0 {
                        continue;
                    }
                    n.inside ^= crosses_ray(a, b, (x, y));
                    if reachable & 1 << k != 0 {
                        n.offer(closest_on_segment((x, y), a, direction).1);
                    }
                }
                a32 = b32;
            }
        }
        for ((d, n), &limit) in out.iter_mut().zip(&nearest).zip(limits) {
            *d = match (n.inside, n.found) {
                (true, true) => -n.distance(),
                // Inside, and only that was asked.
                (true, false) => -0.0,
                // Outside: exact up to the limit.
                (false, _) => Some(n.distance()).filter(|&d| d <= limit).unwrap_or(f64::INFINITY),
            };
        }
        Some(())
    }

    /// Every grid entry in the cells that the square of half-side `radius` around
    /// (x, y) touches (an item may come more than once).
    pub fn for_each_near(&self, x: f64, y: f64, radius: f64, mut f: impl FnMut(Item)) {
        let h = &self.header;
        let size = f64::from(h.cell_size);
        let cell = |v: f64, min: f32, n: u16| -> Option<i64> {
            let c = libm::floor((v - f64::from(min)) / size);
            c.is_finite().then(|| (c as i64).clamp(-1, i64::from(n)))
        };
        let (Some(c0), Some(c1), Some(r0), Some(r1)) = (
            cell(x - radius, h.grid_min[0], h.grid_size[0]),
            cell(x + radius, h.grid_min[0], h.grid_size[0]),
            cell(y - radius, h.grid_min[1], h.grid_size[1]),
            cell(y + radius, h.grid_min[1], h.grid_size[1]),
        ) else {
            return;
        };
        let cols = i64::from(h.grid_size[0]);
        for row in r0.max(0)..=r1.min(i64::from(h.grid_size[1]) - 1) {
            for col in c0.max(0)..=c1.min(cols - 1) {
                let c = (row * cols + col) as usize;
                let (start, end) =
                    (u32_at(self.bytes, self.layout[4] + c * 4), u32_at(self.bytes, self.layout[4] + c * 4 + 4));
                for i in start..end {
                    let e = u32_at(self.bytes, self.layout[5] + i as usize * 4);
                    f(if e & POLYGON_BIT != 0 { Item::Polygon(e & !POLYGON_BIT) } else { Item::Lane(e) });
                }
            }
        }
    }

    /// Signed distance from (x, y) to the drivable area (the union of lane areas and
    /// drivable polygons accepted by `drivable`): ≤ 0 inside. `None` when nothing
    /// drivable lies within `radius`.
    pub fn distance_to_drivable(&self, x: f64, y: f64, radius: f64, drivable: impl Fn(Item) -> bool) -> Option<f64> {
        let mut best: Option<f64> = None;
        self.for_each_near(x, y, radius, |item| {
            if !drivable(item) {
                return;
            }
            let d = match item {
                Item::Lane(i) => self.lane(i).map(|l| l.distance_outside(x, y)),
                Item::Polygon(i) => self.polygon_distance(i, x, y),
            };
            if let Some(d) = d.filter(|d| *d <= radius) {
                best = Some(best.map_or(d, |b: f64| b.min(d)));
            }
        });
        best
    }
}
