//! Plane geometry of lanes and map layers: polylines offset, cut and measured; bands,
//! capsules, hulls; point-in-polygon. Metres in a plane (a tile's ENU frame, nuPlan's UTM).
//! A leaf: map tiles, the nuPlan export and the plot share it.
//!
//! The small measures called per segment in the map lookups (`length`, `point_at`,
//! `heading_at`, `segment_distance`, `nearest_arc`, `contains`) are `#[inline]`: since issue
//! #56 their callers live in other crates (verify, export, sim), where a non-generic function
//! is not inlined without it (perf showed `segment_distance` called, not inlined, in verify).

/// The polyline `points` moved `offset` metres to its left (miter joins, limited to 4×).
pub fn offset_polyline(points: &[(f64, f64)], offset: f64) -> Vec<(f64, f64)> {
    let normal = |a: (f64, f64), b: (f64, f64)| {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len = dx.hypot(dy).max(1e-12);
        (-dy / len, dx / len)
    };
    (0..points.len())
        .map(|k| {
            let before = k.checked_sub(1).map(|j| normal(points[j], points[k]));
            let after = points.get(k + 1).map(|&n| normal(points[k], n));
            let (nx, ny) = match (before, after) {
                (Some(a), Some(b)) => {
                    let (sx, sy) = (a.0 + b.0, a.1 + b.1);
                    let len = sx.hypot(sy);
                    if len < 1e-9 {
                        a
                    } else {
                        // Scale so that both neighbouring segments sit at `offset`.
                        let cos_half = (sx * a.0 + sy * a.1) / len;
                        let scale = 1.0 / cos_half.max(0.25);
                        (sx / len * scale, sy / len * scale)
                    }
                }
                (Some(a), None) | (None, Some(a)) => a,
                (None, None) => (0.0, 0.0),
            };
            (points[k].0 + nx * offset, points[k].1 + ny * offset)
        })
        .collect()
}

/// Points on a half circle of a capsule.
const CAP_POINTS: usize = 16;

/// A polyline or polygon ring, projected metres.
pub type Line = Vec<(f64, f64)>;

/// Arc length of `line`.
#[inline]
pub fn length(line: &[(f64, f64)]) -> f64 {
    line.windows(2).map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1)).sum()
}

/// The part of `line` between arc lengths `from` and `to`.
pub fn cut(line: &[(f64, f64)], from: f64, to: f64) -> Line {
    let mut out = Vec::new();
    let mut s = 0.0;
    for w in line.windows(2) {
        let (a, b) = (w[0], w[1]);
        let l = (b.0 - a.0).hypot(b.1 - a.1);
        let at = |d: f64| {
            let f = if l > 0.0 { ((d - s) / l).clamp(0.0, 1.0) } else { 0.0 };
            (a.0 + (b.0 - a.0) * f, a.1 + (b.1 - a.1) * f)
        };
        if s + l >= from && s <= to {
            if out.is_empty() {
                out.push(at(from.max(s)));
            }
            out.push(at(to.min(s + l)));
        }
        s += l;
    }
    out.dedup();
    if out.len() == 1 {
        out.push(out[0]);
    }
    out
}

/// The polygon between a centreline's two offsets.
pub fn band(line: &[(f64, f64)], half_width: f64) -> (Line, Line, Line) {
    let left = offset_polyline(line, half_width);
    let right = offset_polyline(line, -half_width);
    let mut ring = left.clone();
    ring.extend(right.iter().rev());
    (ring, left, right)
}

/// A segment's capsule (round caps), as a polygon.
pub fn capsule(a: (f64, f64), b: (f64, f64), r: f64) -> Line {
    let heading = (b.1 - a.1).atan2(b.0 - a.0);
    let mut ring = Vec::with_capacity(2 * CAP_POINTS + 2);
    for (centre, start) in [(b, heading - std::f64::consts::FRAC_PI_2), (a, heading + std::f64::consts::FRAC_PI_2)] {
        for k in 0..=CAP_POINTS {
            let angle = start + std::f64::consts::PI * k as f64 / CAP_POINTS as f64;
            ring.push((centre.0 + r * angle.cos(), centre.1 + r * angle.sin()));
        }
    }
    ring
}

/// Convex hull (Andrew's monotone chain), counter-clockwise.
pub fn hull(mut points: Vec<(f64, f64)>) -> Line {
    points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0);
    let mut lower: Line = Vec::new();
    for &p in &points {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Line = Vec::new();
    for &p in points.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

/// The point at arc length `s` along `line` (clamped to its ends).
#[inline]
pub fn point_at(line: &[(f64, f64)], s: f64) -> (f64, f64) {
    let mut at = 0.0;
    for w in line.windows(2) {
        let l = (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
        if at + l >= s && l > 0.0 {
            let f = ((s - at) / l).clamp(0.0, 1.0);
            return (w[0].0 + (w[1].0 - w[0].0) * f, w[0].1 + (w[1].1 - w[0].1) * f);
        }
        at += l;
    }
    line.last().copied().unwrap_or((0.0, 0.0))
}

/// The direction of travel at arc length `s`, rad (that of the segment holding `s`).
#[inline]
pub fn heading_at(line: &[(f64, f64)], s: f64) -> f64 {
    let mut at = 0.0;
    let mut heading = 0.0;
    for w in line.windows(2) {
        let l = (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
        if l > 0.0 {
            heading = (w[1].1 - w[0].1).atan2(w[1].0 - w[0].0);
            if at + l >= s {
                break;
            }
        }
        at += l;
    }
    heading
}

/// Distance from `p` to the segment `a`–`b`, and the fraction along it of the nearest point.
#[inline]
pub fn segment_distance(p: (f64, f64), a: (f64, f64), b: (f64, f64)) -> (f64, f64) {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let l2 = dx * dx + dy * dy;
    let f = if l2 > 0.0 { (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
    ((p.0 - a.0 - dx * f).hypot(p.1 - a.1 - dy * f), f)
}

/// The gap between two closed convex rings that do not overlap (`a`, `b`: their corners in
/// order): the least distance from a corner of either to an edge of the other.
pub fn convex_gap(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    let to_edges = |points: &[(f64, f64)], ring: &[(f64, f64)]| {
        let edges = ring.iter().zip(ring.iter().cycle().skip(1));
        let mut least = f64::INFINITY;
        for (p, q) in edges {
            for c in points {
                least = least.min(segment_distance(*c, *p, *q).0);
            }
        }
        least
    };
    to_edges(a, b).min(to_edges(b, a))
}

/// Arc length along `line` of the point nearest `p`.
#[inline]
pub fn nearest_arc(line: &[(f64, f64)], p: (f64, f64)) -> f64 {
    let (mut best, mut best_s, mut at) = (f64::INFINITY, 0.0, 0.0);
    for w in line.windows(2) {
        let l = (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1);
        let (d, f) = segment_distance(p, w[0], w[1]);
        if d < best {
            (best, best_s) = (d, at + f * l);
        }
        at += l;
    }
    best_s
}

/// Whether `p` lies inside the ring (even-odd rule; the ring need not be closed).
#[inline]
pub fn contains(ring: &[(f64, f64)], p: (f64, f64)) -> bool {
    let mut inside = false;
    let n = ring.len();
    for k in 0..n {
        let (a, b) = (ring[k], ring[(k + 1) % n]);
        if (a.1 > p.1) != (b.1 > p.1) && p.0 < a.0 + (p.1 - a.1) / (b.1 - a.1) * (b.0 - a.0) {
            inside = !inside;
        }
    }
    inside
}

/// Whether the ring (implicitly closed) is simple: no two of its edges cross, except
/// neighbours at their shared point.
pub fn is_simple(ring: &[(f64, f64)]) -> bool {
    let n = ring.len();
    let cross = |o: (f64, f64), a: (f64, f64), b: (f64, f64)| (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0);
    for i in 0..n {
        let (a, b) = (ring[i], ring[(i + 1) % n]);
        for j in i + 2..n {
            if (j + 1) % n == i {
                continue;
            }
            let (c, d) = (ring[j], ring[(j + 1) % n]);
            let (d1, d2) = (cross(a, b, c), cross(a, b, d));
            let (d3, d4) = (cross(c, d, a), cross(c, d, b));
            if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
                return false;
            }
        }
    }
    true
}

/// A cubic Bézier curve from `a` leaving along `heading_a` to `b` arriving along
/// `heading_b`, as `points` points: the shape of a turn through a junction.
pub fn bezier(a: (f64, f64), heading_a: f64, b: (f64, f64), heading_b: f64, points: usize) -> Line {
    let reach = 0.4 * (b.0 - a.0).hypot(b.1 - a.1);
    let c1 = (a.0 + reach * heading_a.cos(), a.1 + reach * heading_a.sin());
    let c2 = (b.0 - reach * heading_b.cos(), b.1 - reach * heading_b.sin());
    (0..points)
        .map(|k| {
            let t = k as f64 / (points - 1).max(1) as f64;
            let u = 1.0 - t;
            let (w0, w1, w2, w3) = (u * u * u, 3.0 * u * u * t, 3.0 * u * t * t, t * t * t);
            (w0 * a.0 + w1 * c1.0 + w2 * c2.0 + w3 * b.0, w0 * a.1 + w1 * c1.1 + w2 * c2.1 + w3 * b.1)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cutting_bands_and_capsules() {
        let line = vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)];
        assert_eq!(cut(&line, 2.0, 12.0), vec![(2.0, 0.0), (10.0, 0.0), (10.0, 2.0)]);
        // A band around a right-angle corner: its left side's corner point at (9, 1).
        let (_, left, right) = band(&line, 1.0);
        assert!((left[1].0 - 9.0).abs() < 1e-12 && (left[1].1 - 1.0).abs() < 1e-12, "{left:?}");
        assert!((right[1].0 - 11.0).abs() < 1e-12 && (right[1].1 + 1.0).abs() < 1e-12, "{right:?}");
        let c = capsule((0.0, 0.0), (4.0, 0.0), 1.0);
        assert!(c.iter().all(|p| {
            let d = if p.0 < 0.0 {
                p.0.hypot(p.1)
            } else if p.0 > 4.0 {
                (p.0 - 4.0).hypot(p.1)
            } else {
                p.1.abs()
            };
            (d - 1.0).abs() < 1e-12
        }));
        assert_eq!(hull(vec![(0.0, 0.0), (1.0, 0.0), (0.5, 0.2), (1.0, 1.0), (0.0, 1.0)]).len(), 4);
    }

    #[test]
    fn the_gap_between_two_boxes_is_corner_to_edge_either_way() {
        let square = |x: f64, y: f64| vec![(x, y), (x + 1.0, y), (x + 1.0, y + 1.0), (x, y + 1.0)];
        // Side by side, 0.3 m apart: a corner of either meets the other's edge.
        assert!((convex_gap(&square(0.0, 0.0), &square(1.3, 0.2)) - 0.3).abs() < 1e-12);
        // A diamond's tip 0.25 m from the square's edge: only the diamond's corner sees it.
        let diamond = vec![(1.25, 0.5), (1.75, 0.0), (2.25, 0.5), (1.75, 1.0)];
        assert!((convex_gap(&square(0.0, 0.0), &diamond) - 0.25).abs() < 1e-12);
        assert!((convex_gap(&diamond, &square(0.0, 0.0)) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn points_headings_and_nearest_arcs_along_a_bend() {
        let line = vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0)];
        assert_eq!(point_at(&line, 12.0), (10.0, 2.0));
        assert_eq!(point_at(&line, 99.0), (10.0, 10.0));
        assert!((heading_at(&line, 5.0)).abs() < 1e-12);
        assert!((heading_at(&line, 15.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!((nearest_arc(&line, (12.0, 4.0)) - 14.0).abs() < 1e-12);
        assert!(contains(&[(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)], (1.0, 1.0)));
        assert!(!contains(&[(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)], (3.0, 1.0)));
        assert!(is_simple(&[(0.0, 0.0), (2.0, 0.0), (2.0, 2.0), (0.0, 2.0)]));
        assert!(!is_simple(&[(0.0, 0.0), (2.0, 2.0), (2.0, 0.0), (0.0, 2.0)]), "a bow tie");
        // The band of a turn tighter than its half width folds over on the inside.
        let tight = bezier((0.0, 0.0), 0.0, (0.0, 2.0), std::f64::consts::PI, 12);
        assert!(!is_simple(&band(&tight, 1.75).0));
        // A right turn: leaves east, arrives south, ends where asked.
        let turn = bezier((0.0, 0.0), 0.0, (5.0, -5.0), -std::f64::consts::FRAC_PI_2, 9);
        assert_eq!((turn[0], turn[8]), ((0.0, 0.0), (5.0, -5.0)));
        assert!(turn[1].1.abs() < turn[1].0 && (turn[7].0 - 5.0).abs() < (turn[7].1 + 5.0).abs());
    }
}
