//! Plane geometry of a tile's stored points: distances from points to a lane's buffered
//! centreline and to polygon edges, projections, and the box culls that skip what is far.

use super::wire::{xy, StoredPoint};

/// A lane's centreline (its points as stored: x, y f32 pairs, range checked when the tile
/// was parsed) and width: the area is the centreline buffered by half the width.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Centreline<'a> {
    pub(super) points: &'a [StoredPoint],
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
pub(super) fn box_reaches(lo: [f32; 2], hi: [f32; 2], point: (f64, f64), squared: f64) -> bool {
    let (x, y) = (point.0 as Cull, point.1 as Cull);
    let slack = CULL_SLACK as Cull;
    let dx = (lo[0] as Cull - x).max(x - hi[0] as Cull).max(slack) - slack;
    let dy = (lo[1] as Cull - y).max(y - hi[1] as Cull).max(slack) - slack;
    dx * dx + dy * dy <= squared as Cull * 1.001
}

/// Margin on a box in the culls, m: f32 rounding of map coordinates (tiles span a few km)
/// is below a millimetre.
const CULL_SLACK: f32 = 0.01;

/// Distance from `point` to the nearest of `edges` (x, y of both ends, as stored), found as
/// [`MapView::polygon_distances`](super::MapView::polygon_distances) finds it; infinite for none.
pub fn edges_distance(edges: &[[f32; 4]], point: (f64, f64)) -> f64 {
    let mut n = EdgeDistance::NONE;
    for &[ax, ay, bx, by] in edges {
        let (a, b) = (wide([ax, ay]), wide([bx, by]));
        n.offer(closest_on_segment(point, a, (b.0 - a.0, b.1 - a.1)).1);
    }
    n.distance()
}

/// Distance from `point` to a centreline through the nearest of `segments` (x, y of both
/// ends, as stored, in driving order), found as [`Centreline::nearest_segments`] finds it:
/// the first of the nearest by squared distance, then its length. Infinite for none.
pub fn segments_distance(segments: impl IntoIterator<Item = [f32; 4]>, point: (f64, f64)) -> f64 {
    let mut best = Nearest::NONE;
    for [ax, ay, bx, by] in segments {
        let (a, b) = (wide([ax, ay]), wide([bx, by]));
        let (_, residual) = closest_on_segment(point, a, (b.0 - a.0, b.1 - a.1));
        let squared = residual.0 * residual.0 + residual.1 * residual.1;
        if squared < best.squared {
            best = Nearest { squared, residual, segment: 0 };
        }
    }
    best.distance()
}

/// The even-odd parity of `point` from `edges` (x, y of both ends, as stored), starting from
/// `parity`: the test [`MapView::polygon_distances`](super::MapView::polygon_distances) makes, edge by edge.
pub fn edges_parity(edges: &[[f32; 4]], point: (f64, f64), parity: bool) -> bool {
    edges.iter().fold(parity, |inside, &[ax, ay, bx, by]| inside ^ crosses_ray(wide([ax, ay]), wide([bx, by]), point))
}

/// Whether the edge a–b crosses the ray from `p` towards +x (the even-odd rule's test).
/// Without branches (they would be mispredicted): where the edge is level the quotient is
/// not finite and the first test is false anyway.
pub(super) fn crosses_ray(a: (f64, f64), b: (f64, f64), (x, y): (f64, f64)) -> bool {
    let straddles = (a.1 > y) != (b.1 > y);
    straddles & (x < a.0 + (y - a.1) * (b.0 - a.0) / (b.1 - a.1))
}

/// Stored coordinates as the f64 every distance is worked in.
pub(super) fn wide(p: [f32; 2]) -> (f64, f64) {
    (f64::from(p[0]), f64::from(p[1]))
}

/// The box of stored points (finite, checked at parse: plain compares).
pub(super) fn bounding_box(points: &[StoredPoint]) -> ([f32; 2], [f32; 2]) {
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
pub(super) fn bounding_box_from(first: [f32; 2], points: &[StoredPoint]) -> ([f32; 2], [f32; 2]) {
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
pub(super) struct EdgeDistance {
    pub(super) squared: f64,
    residual: (f64, f64),
    pub(super) found: bool,
    ties: f64,
    pub(super) inside: bool,
    /// An edge this near (squared) is near enough: the search for this point stops.
    pub(super) enough: f64,
}

impl EdgeDistance {
    pub(super) const NONE: EdgeDistance = EdgeDistance {
        squared: f64::INFINITY,
        residual: (0.0, 0.0),
        found: false,
        ties: f64::INFINITY,
        inside: false,
        enough: 0.0,
    };

    pub(super) fn offer(&mut self, residual: (f64, f64)) {
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
    pub(super) fn distance(&self) -> f64 {
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
    pub(super) squared: f64,
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
pub(super) fn closest_on_segment(p: (f64, f64), a: (f64, f64), direction: (f64, f64)) -> (f64, (f64, f64)) {
    let (dx, dy) = direction;
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 { (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (t, (p.0 - (a.0 + t * dx), p.1 - (a.1 + t * dy)))
}
