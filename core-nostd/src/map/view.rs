//! The validated tile ([`MapView::parse`] checks it whole, once) and its queries: lanes,
//! polygons, the grid, the distance to the drivable area.

use super::geometry::{
    bounding_box, bounding_box_from, box_reaches, closest_on_segment, crosses_ray, wide, Centreline, EdgeDistance,
    Nearest, Projection, CHUNK,
};
use super::wire::{
    body_checksum, f32_at, u16_at, u32_at, xy, Header, MapError, StoredPoint, BOX_LEN, CRC_AT, HEADER_LEN, LANE_LEN,
    MAGIC, NONE, POINT_LEN, POLYGON_BIT, POLYGON_LEN, VERSION_MAJOR,
};

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
