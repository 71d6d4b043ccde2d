//! Drivable-area compliance: where a vehicle footprint lies relative to the lanes of a map
//! tile.
//!
//! For each pose (rear axle, as nuPlan) the check gives the signed distance of every
//! footprint corner to the drivable area (≤ 0 inside), the lanes the footprint occupies and
//! the lane its centre is in. A pose complies when no corner is outside by
//! [`TOLERANCE`] or more — nuPlan's `drivable_area_compliance` with its 0.3 m.
//!
//! Two readings of "drivable", as in the Dash2Sim paper:
//! * **channel-insensitive** — every mapped lane (and drivable polygon);
//! * **channel-sensitive** — only the lanes near the route actually driven: a lane is on
//!   the channel when the footprint centre comes within [`CHANNEL_RADIUS`] of its area
//!   while heading its way (within 90°). Parallel lanes of the same direction stay
//!   drivable; the opposing lanes and side roads do not, so swinging into the oncoming
//!   lane to pass a closure is penalised here and not in the insensitive mode. The channel
//!   is collected in a first pass over the drive ([`LaneSet::add_route_pose`]).

#[cfg(feature = "fine-index")]
use crate::lane_index::LaneIndex;
use crate::map::{Item, LaneArea, MapView, Nearest, Projection};
use crate::obb::{Footprint, Pose2};
#[cfg(feature = "fine-index")]
use crate::polygon_index::PolygonIndex;

/// A corner outside the drivable area by this much or more breaks compliance, m.
pub const TOLERANCE: f64 = 0.3;
/// How far from a corner the check looks for drivable area, m; farther is "none near".
pub const SEARCH_RADIUS: f64 = 10.0;
/// A lane is on the channel when the footprint centre passes this close to its area, m.
pub const CHANNEL_RADIUS: f64 = 2.0;
/// Lanes recorded per pose as occupied.
pub const MAX_OCCUPIED: usize = 8;

/// A set of lane indices in caller-sized storage (32 lanes per word).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LaneSet<const WORDS: usize> {
    bits: [u32; WORDS],
    overflowed: bool,
}

impl<const WORDS: usize> Default for LaneSet<WORDS> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const WORDS: usize> LaneSet<WORDS> {
    /// An empty set.
    pub const fn new() -> Self {
        LaneSet { bits: [0; WORDS], overflowed: false }
    }

    /// Lanes it can hold: indices below `32 × WORDS`.
    pub const fn capacity() -> usize {
        32 * WORDS
    }

    /// Add lane `i`; false (and remembered) when `i` is beyond the capacity.
    pub fn insert(&mut self, i: u32) -> bool {
        match self.bits.get_mut((i / 32) as usize) {
            Some(word) => {
                *word |= 1 << (i % 32);
                true
            }
            None => {
                self.overflowed = true;
                false
            }
        }
    }

    /// Whether lane `i` is in the set.
    pub fn contains(&self, i: u32) -> bool {
        self.bits.get((i / 32) as usize).is_some_and(|w| w & (1 << (i % 32)) != 0)
    }

    /// Number of lanes in the set.
    pub fn len(&self) -> usize {
        self.bits.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// True when no lane is in the set.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether a lane beyond the capacity was ever inserted (the set is then incomplete).
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }

    /// Record the lanes near one pose of the route actually driven (channel-sensitive
    /// mode): lanes within [`CHANNEL_RADIUS`] of the footprint centre whose direction is
    /// within 90° of the heading.
    pub fn add_route_pose(&mut self, map: &MapView<'_>, footprint: &Footprint, pose: &Pose2) {
        let centre = footprint.at(pose).centre;
        map.for_each_near(centre.x, centre.y, CHANNEL_RADIUS, |item| {
            let Item::Lane(i) = item else { return };
            let Some(lane) = map.lane(i) else { return };
            let heading = lane.project(centre.x, centre.y).heading;
            if lane.distance_outside(centre.x, centre.y) <= CHANNEL_RADIUS && libm::cos(heading - pose.heading) > 0.0 {
                self.insert(i);
            }
        });
    }
}

/// Which lanes count as drivable.
#[derive(Clone, Copy, Debug)]
pub enum Channel<'s, const WORDS: usize> {
    /// Every lane and drivable polygon.
    Insensitive,
    /// Only these lanes (no free-standing polygons).
    Sensitive(&'s LaneSet<WORDS>),
}

impl<const WORDS: usize> Channel<'_, WORDS> {
    /// Whether `item` is drivable in this mode.
    pub fn allows(&self, item: Item) -> bool {
        match (self, item) {
            (Channel::Insensitive, _) => true,
            (Channel::Sensitive(set), Item::Lane(i)) => set.contains(i),
            (Channel::Sensitive(_), Item::Polygon(_)) => false,
        }
    }
}

/// The lane the footprint centre is in.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CentreLane {
    /// Lane index.
    pub lane: u32,
    /// Arc length of the centre's projection along the lane, m.
    pub along: f64,
    /// Lane direction there, rad.
    pub heading: f64,
    /// Speed limit, m/s, if mapped.
    pub speed_limit: Option<f64>,
}

/// What the check found for one pose.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseCheck {
    /// Signed distance of each corner (front left, front right, rear right, rear left) to
    /// the drivable area, m, ≤ 0 inside; `None` when nothing drivable lies within
    /// [`SEARCH_RADIUS`].
    pub corners: [Option<f64>; 4],
    /// Lanes that contain the centre or a corner (any mode), up to [`MAX_OCCUPIED`].
    pub occupied: heapless::Vec<u32, MAX_OCCUPIED>,
    /// The lane the centre is in, if any.
    pub centre_lane: Option<CentreLane>,
}

impl PoseCheck {
    /// Nothing found yet: no corner near anything, no lane occupied.
    fn nothing() -> Self {
        PoseCheck { corners: [None; 4], occupied: heapless::Vec::new(), centre_lane: None }
    }

    /// How far the worst corner is outside the drivable area, m (≤ 0: all inside;
    /// infinite when a corner has nothing drivable near).
    pub fn worst(&self) -> f64 {
        self.corners.iter().map(|c| c.unwrap_or(f64::INFINITY)).fold(f64::NEG_INFINITY, f64::max)
    }

    /// nuPlan's verdict: no corner outside by [`TOLERANCE`] or more.
    pub fn compliant(&self) -> bool {
        self.compliant_within(0.0)
    }

    /// The verdict for a pose in doubt by `margin` m: no corner outside by [`TOLERANCE`]
    /// and `margin` more ([`crate::score::Scorer::step_in_doubt`]).
    pub fn compliant_within(&self, margin: f64) -> bool {
        self.worst() < TOLERANCE + margin
    }
}

/// Checks footprints against one map tile.
#[derive(Clone, Copy, Debug)]
pub struct Checker<'a> {
    map: MapView<'a>,
    footprint: Footprint,
    #[cfg(feature = "fine-index")]
    index: Option<FineIndex<'a>>,
}

/// The fine index a checker reads beside its tile, whichever its lanes need.
#[cfg(feature = "fine-index")]
#[derive(Clone, Copy, Debug)]
enum FineIndex<'a> {
    Polygons(PolygonIndex<'a>),
    Lanes(LaneIndex<'a>),
}

impl<'a> Checker<'a> {
    /// A checker for vehicles of `footprint` on `map`.
    pub fn new(map: MapView<'a>, footprint: Footprint) -> Self {
        Checker {
            map,
            footprint,
            #[cfg(feature = "fine-index")]
            index: None,
        }
    }

    #[cfg(feature = "fine-index")]
    /// The same checker reading `index` (built for this map's polygons) in the
    /// channel-insensitive mode, with the same answers: each point's cell says which
    /// polygons may hold it and which edges may be nearest, instead of every polygon the
    /// grid lists around the footprint.
    pub fn with_index(self, index: PolygonIndex<'a>) -> Self {
        Checker { index: Some(FineIndex::Polygons(index)), ..self }
    }

    #[cfg(feature = "fine-index")]
    /// The same checker reading `index` (built for this map's buffered lanes), in both
    /// channel modes, with the same answers: each point's cell says which lanes may hold it
    /// or be nearest to it, and which of their segments may be nearest, instead of every
    /// lane the grid lists around the footprint.
    pub fn with_lane_index(self, index: LaneIndex<'a>) -> Self {
        Checker { index: Some(FineIndex::Lanes(index)), ..self }
    }

    /// The five points a check measures: the footprint's centre and its corners (front
    /// left, front right, rear right, rear left) with its rear axle at `pose`.
    fn points(&self, pose: &Pose2) -> [(f64, f64); 5] {
        let footprint = self.footprint.at(pose);
        let corners = footprint.corners();
        [(footprint.centre.x, footprint.centre.y), corners[0], corners[1], corners[2], corners[3]]
    }

    /// The map.
    pub fn map(&self) -> &MapView<'a> {
        &self.map
    }

    /// The footprint.
    pub fn footprint(&self) -> &Footprint {
        &self.footprint
    }

    /// Of the lanes whose area comes within `within` m of the footprint centre at `pose` and
    /// that head the pose's way (within 90°), the nearest to the centre: the lane a pose
    /// whose position is in doubt by `within` may as well be in
    /// ([`crate::score::Scorer::step_in_doubt`]). `within` is clamped to [`SEARCH_RADIUS`].
    pub fn lane_headed_within(&self, pose: &Pose2, within: f64) -> Option<CentreLane> {
        let centre = self.footprint.at(pose).centre;
        let within = within.min(SEARCH_RADIUS);
        let mut best: Option<(f64, CentreLane)> = None;
        self.map.for_each_near(centre.x, centre.y, within, |item| {
            let Item::Lane(i) = item else { return };
            let Some(lane) = self.map.lane(i) else { return };
            let outside = lane.distance_outside(centre.x, centre.y).max(0.0);
            if outside > within || best.is_some_and(|(d, _)| d <= outside) {
                return;
            }
            let p = lane.project(centre.x, centre.y);
            if libm::cos(p.heading - pose.heading) > 0.0 {
                let found = CentreLane { lane: i, along: p.along, heading: p.heading, speed_limit: lane.speed_limit };
                best = Some((outside, found));
            }
        });
        best.map(|(_, lane)| lane)
    }

    /// Check the footprint with its rear axle at `pose`. `previous` is the centre's lane at
    /// the pose before: where lanes overlap (junctions) the centre stays in it, as nuPlan
    /// keeps ego on the lane it is following.
    ///
    /// Two grid queries gather the lanes and polygons near the footprint (the cells under
    /// it, then farther as far as the corners still outside need). Each item is measured
    /// once for the centre and the four corners together (one pass over its centreline or
    /// ring), each point's distance wanted only while it could change the answer, and an
    /// item whose box is beyond that is passed over unread; the per-point lookups that
    /// follow reuse what the pass found.
    pub fn check<const WORDS: usize>(
        &self,
        pose: &Pose2,
        channel: Channel<'_, WORDS>,
        previous: Option<u32>,
    ) -> PoseCheck {
        #[cfg(feature = "fine-index")]
        match (&self.index, &channel) {
            (Some(FineIndex::Polygons(index)), Channel::Insensitive) => {
                return self.check_indexed(index, pose, previous)
            }
            (Some(FineIndex::Lanes(index)), _) => {
                if let Some(check) = self.check_lanes_indexed(index, pose, channel, previous) {
                    return check;
                }
            }
            _ => {}
        }
        self.check_by_grid(pose, channel, previous)
    }

    /// [`Checker::check`] through the tile's grid.
    fn check_by_grid<const WORDS: usize>(
        &self,
        pose: &Pose2,
        channel: Channel<'_, WORDS>,
        previous: Option<u32>,
    ) -> PoseCheck {
        let points = self.points(pose);
        let centre = points[0];
        let mut check = PoseCheck::nothing();

        // The footprint's box, as a square around its middle.
        let (lo, hi) = points
            .iter()
            .fold(((f64::INFINITY, f64::INFINITY), (f64::NEG_INFINITY, f64::NEG_INFINITY)), |(lo, hi), p| {
                ((lo.0.min(p.0), lo.1.min(p.1)), (hi.0.max(p.0), hi.1.max(p.1)))
            });
        let (middle, half) = (((lo.0 + hi.0) / 2.0, (lo.1 + hi.1) / 2.0), 0.5 * (hi.0 - lo.0).max(hi.1 - lo.1));
        let mut candidates: heapless::Vec<u32, CANDIDATES> = heapless::Vec::new();
        // Lanes containing the centre, with its projection on each (more are projected again).
        let mut centre_lanes: heapless::Vec<(u32, Projection), 4> = heapless::Vec::new();
        let mut measured: heapless::Vec<(u32, u8), CANDIDATES> = heapless::Vec::new();
        let mut measure = |check: &mut PoseCheck, item: Item| -> u8 {
            // Below what each point's distance is wanted: the centre's not at all, only
            // whether it is inside; a corner's while it would lower the corner's distance
            // so far (or the search radius).
            let mut limits = [f64::NEG_INFINITY; 5];
            if channel.allows(item) {
                for (limit, corner) in limits[1..].iter_mut().zip(&check.corners) {
                    *limit = corner.unwrap_or(SEARCH_RADIUS);
                }
            }
            let mut d = [f64::INFINITY; 5];
            if !self.map.item_reaches(item, &points, &limits) {
                // Its box is farther than any point's limit: nothing in it is wanted.
                return 0;
            }
            match item {
                Item::Lane(i) => match self.map.lane_area(i) {
                    Some(LaneArea::Buffered(centreline)) => {
                        let mut nearest = [Nearest::NONE; 5];
                        centreline.nearest_within(&points, &limits, &mut nearest);
                        for (d, n) in d.iter_mut().zip(&nearest) {
                            *d = centreline.outside(n);
                        }
                        if d[0] <= 0.0 {
                            // The centre's lane is among these: its projection is at hand.
                            let _ = centre_lanes.push((i, centreline.projection(centre, &nearest[0])));
                        }
                    }
                    Some(LaneArea::Polygon(polygon)) => {
                        let _ = self.map.polygon_distances(polygon, &points, &limits, &mut d);
                    }
                    None => {}
                },
                Item::Polygon(i) => {
                    let _ = self.map.polygon_distances(i, &points, &limits, &mut d);
                }
            }
            if channel.allows(item) {
                for (corner, &d) in check.corners.iter_mut().zip(&d[1..]) {
                    if d <= SEARCH_RADIUS {
                        *corner = Some(corner.map_or(d, |c: f64| c.min(d)));
                    }
                }
            }
            d.iter().enumerate().fold(0u8, |inside, (k, &d)| if d <= 0.0 { inside | 1 << k } else { inside })
        };
        // Two rounds. The cells under the footprint list every lane that contains one of its
        // points (a lane is listed wherever its area's box reaches), so after the first round
        // every point knows whether it is inside and most corners are done. The second round
        // looks farther, as far as the corners still outside need, at what they may use.
        let mut complete = true;
        let mut reach = 0.0;
        for round in 0..2 {
            candidates.clear();
            self.map.for_each_near(middle.0, middle.1, half + reach, |item| {
                if round == 1 && !channel.allows(item) {
                    return;
                }
                if candidates.push(key(item)).is_err() {
                    // More than the list holds: measured at once (duplicates then cost twice).
                    complete = false;
                    measure(&mut check, item);
                }
            });
            candidates.sort_unstable();
            let near = measured.len();
            let mut last = None;
            for &k in &candidates {
                let seen = measured.get(..near).is_some_and(|first| first.binary_search_by_key(&k, |m| m.0).is_ok());
                if last != Some(k) && !seen {
                    last = Some(k);
                    let inside = measure(&mut check, item(k));
                    if measured.push((k, inside)).is_err() {
                        // Not remembered: occupancy is then looked up point by point.
                        complete = false;
                    }
                }
            }
            // How far a corner still outside needs to look (0 when all are inside).
            reach = check.corners.iter().map(|c| c.map_or(SEARCH_RADIUS, |c| c.max(0.0))).fold(0.0, f64::max);
            if reach <= 0.0 {
                break;
            }
        }
        measured.sort_unstable_by_key(|m| m.0);

        // The lanes each point is in, in the grid's order (lanes by index: the occupied list
        // keeps that order), and the centre's lane.
        let mut best: Option<(bool, f64, CentreLane)> = None;
        let mut occupy = |k: usize, i: u32, lane: &crate::map::Lane<'_>| {
            if !check.occupied.contains(&i) {
                // Full: the first MAX_OCCUPIED lanes are kept.
                let _ = check.occupied.push(i);
            }
            if k == 0 {
                let known = centre_lanes.iter().find(|(lane, _)| *lane == i).map(|&(_, p)| p);
                let p = known.unwrap_or_else(|| lane.project(centre.0, centre.1));
                prefer_centre_lane(&mut best, previous, i, lane, &p);
            }
        };
        for (k, &(x, y)) in points.iter().enumerate() {
            if complete {
                // Every lane containing the point was measured: its bit says so.
                for &(key, inside) in &measured {
                    if let (Item::Lane(i), true) = (item(key), inside & (1 << k) != 0) {
                        if let Some(lane) = self.map.lane(i) {
                            occupy(k, i, &lane);
                        }
                    }
                }
            } else {
                self.map.for_each_near(x, y, 0.0, |item| {
                    let Item::Lane(i) = item else { return };
                    let Some(lane) = self.map.lane(i) else { return };
                    if lane.distance_outside(x, y) <= 0.0 {
                        occupy(k, i, &lane);
                    }
                });
            }
        }
        check.centre_lane = best.map(|(_, _, lane)| lane);
        check
    }

    #[cfg(feature = "fine-index")]
    /// [`Checker::check`] on a map of buffered lanes through its index: per point, the runs
    /// of its cell (a lane and its segments that may be nearest), each lane's distance from
    /// the first of its nearest segments as the centreline's own search finds it — the
    /// lanes holding the point (occupancy, the centre's lane), a corner's distance the least
    /// of the lanes allowed. `None` when a corner's distance in the channel-sensitive mode
    /// is beyond what its cell knows exactly ([`LaneIndex::exact_below`]): the grid answers.
    fn check_lanes_indexed<const WORDS: usize>(
        &self,
        index: &LaneIndex<'_>,
        pose: &Pose2,
        channel: Channel<'_, WORDS>,
        previous: Option<u32>,
    ) -> Option<PoseCheck> {
        let points = self.points(pose);
        let centre = points[0];
        let mut check = PoseCheck::nothing();
        let mut best: Option<(bool, f64, CentreLane)> = None;
        for (k, &point) in points.iter().enumerate() {
            let Some(c) = index.cell_of(point.0, point.1) else { continue };
            let mut nearest = f64::INFINITY;
            for run in index.runs(c) {
                let d = crate::map::segments_distance(run.segments(), point) - run.half_width;
                if d <= 0.0 {
                    self.occupy(&mut check, &mut best, previous, k == 0, run.lane, centre);
                }
                if k > 0 && channel.allows(Item::Lane(run.lane)) {
                    nearest = nearest.min(d);
                }
            }
            let Some(corner) = k.checked_sub(1).and_then(|k| check.corners.get_mut(k)) else { continue };
            let exact_below = index.exact_below(c);
            if nearest > exact_below && exact_below < SEARCH_RADIUS {
                return None;
            }
            if nearest <= SEARCH_RADIUS {
                *corner = Some(nearest);
            }
        }
        check.centre_lane = best.map(|(_, _, lane)| lane);
        Some(check)
    }

    #[cfg(feature = "fine-index")]
    /// Lane `i` holds a point of the footprint: it is occupied and, when the point is the
    /// `centre`, a candidate for the centre's lane (`best`, the lane of the pose before first).
    fn occupy(
        &self,
        check: &mut PoseCheck,
        best: &mut Option<(bool, f64, CentreLane)>,
        previous: Option<u32>,
        is_centre: bool,
        i: u32,
        centre: (f64, f64),
    ) {
        if !check.occupied.contains(&i) {
            // Full: the first MAX_OCCUPIED lanes are kept.
            let _ = check.occupied.push(i);
        }
        if is_centre {
            if let Some(lane) = self.map.lane(i) {
                prefer_centre_lane(best, previous, i, &lane, &lane.project(centre.0, centre.1));
            }
        }
    }

    #[cfg(feature = "fine-index")]
    /// [`Checker::check`] on a map of polygons, channel-insensitive, through its index: per
    /// point, the polygons of its cell that hold it (occupancy, the centre's lane, a corner's
    /// depth: the deepest), else its distance to the nearest of the cell's edges.
    fn check_indexed(&self, index: &PolygonIndex<'_>, pose: &Pose2, previous: Option<u32>) -> PoseCheck {
        let points = self.points(pose);
        let centre = points[0];
        let mut check = PoseCheck::nothing();
        let mut best: Option<(bool, f64, CentreLane)> = None;
        for (k, &point) in points.iter().enumerate() {
            let Some(c) = index.cell_of(point.0, point.1) else { continue };
            let mut depth: Option<f64> = None;
            // The polygon of the area before, whether it holds the point, and its depth
            // there: a two-way lanelet's lanes share their polygon.
            let mut last: Option<(u32, bool, f64)> = None;
            for area in index.areas(c) {
                let (holds, d) = match last {
                    Some((polygon, holds, d)) if polygon == area.polygon => (holds, d),
                    _ => {
                        let holds =
                            area.whole || crate::map::edges_parity(index.area_edges(area.crossing), point, area.parity);
                        let d = if holds && k > 0 {
                            -crate::map::edges_distance(index.area_edges(area.nearest), point)
                        } else {
                            f64::INFINITY
                        };
                        last = Some((area.polygon, holds, d));
                        (holds, d)
                    }
                };
                if !holds {
                    continue;
                }
                if k > 0 {
                    depth = Some(depth.map_or(d, |m: f64| m.min(d)));
                }
                if let Item::Lane(i) = item(area.key) {
                    self.occupy(&mut check, &mut best, previous, k == 0, i, centre);
                }
            }
            let Some(corner) = k.checked_sub(1).and_then(|k| check.corners.get_mut(k)) else { continue };
            if depth.is_some() {
                *corner = depth;
                continue;
            }
            let nearest = crate::map::edges_distance(index.edges(c), point);
            if nearest <= SEARCH_RADIUS {
                *corner = Some(nearest);
            }
        }
        check.centre_lane = best.map(|(_, _, lane)| lane);
        check
    }
}

/// Keep lane `i` (the centre projected on it at `p`) as the centre's lane if it beats
/// `best`: the lane of the pose before first, then the one whose centreline is nearest.
fn prefer_centre_lane(
    best: &mut Option<(bool, f64, CentreLane)>,
    previous: Option<u32>,
    i: u32,
    lane: &crate::map::Lane<'_>,
    p: &Projection,
) {
    let candidate = (
        previous == Some(i),
        p.distance,
        CentreLane { lane: i, along: p.along, heading: p.heading, speed_limit: lane.speed_limit },
    );
    let better = match best {
        None => true,
        Some((was_previous, distance, _)) => {
            (candidate.0 && !*was_previous) || (candidate.0 == *was_previous && candidate.1 < *distance)
        }
    };
    if better {
        *best = Some(candidate);
    }
}

/// Items one check remembers (grid entries near a footprint, duplicates included); more
/// are measured without being remembered. 1.5 KiB of stack.
const CANDIDATES: usize = 128;

/// An item as one sortable number (the grid's own encoding).
fn key(item: Item) -> u32 {
    match item {
        Item::Lane(i) => i,
        Item::Polygon(i) => i | crate::map::POLYGON_BIT,
    }
}

fn item(key: u32) -> Item {
    if key & crate::map::POLYGON_BIT != 0 {
        Item::Polygon(key & !crate::map::POLYGON_BIT)
    } else {
        Item::Lane(key)
    }
}
