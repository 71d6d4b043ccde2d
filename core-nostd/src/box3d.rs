//! Oriented 3D boxes (yaw about the vertical axis) and their overlap: 3D IoU and 3D GIoU
//! as AB3DMOT computes them (docs/tracking.md) — bird's-eye-view polygons clipped exactly, the
//! enclosing volume from the convex hull of both footprints times the joint height.
//!
//! Frame: x, y horizontal, z up; `z` is the box centre; `yaw` turns the length axis from
//! +x towards +y. Polygons have at most 8 vertices here, so everything is fixed-size.

use libm::{cos, sin};

/// An oriented box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Box3d {
    /// Centre x.
    pub x: f64,
    /// Centre y.
    pub y: f64,
    /// Centre z.
    pub z: f64,
    /// Heading, radians.
    pub yaw: f64,
    /// Length (along the heading).
    pub l: f64,
    /// Width.
    pub w: f64,
    /// Height.
    pub h: f64,
}

/// A convex polygon of at most 8 vertices, counter-clockwise.
#[derive(Clone, Copy, Debug, Default)]
struct Polygon {
    points: [(f64, f64); 8],
    len: usize,
}

impl Polygon {
    fn push(&mut self, p: (f64, f64)) {
        if let Some(slot) = self.points.get_mut(self.len) {
            *slot = p;
            self.len += 1;
        }
    }

    fn vertices(&self) -> &[(f64, f64)] {
        &self.points[..self.len]
    }

    /// Shoelace area (positive for counter-clockwise).
    fn area(&self) -> f64 {
        let v = self.vertices();
        let mut twice = 0.0;
        for i in 0..v.len() {
            let (a, b) = (v[i], v[(i + 1) % v.len()]);
            twice += a.0 * b.1 - b.0 * a.1;
        }
        twice.abs() / 2.0
    }
}

fn cross(o: (f64, f64), a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
}

impl Box3d {
    /// Bird's-eye footprint, counter-clockwise.
    fn footprint(&self) -> Polygon {
        let (c, s) = (cos(self.yaw), sin(self.yaw));
        let (hl, hw) = (self.l / 2.0, self.w / 2.0);
        let mut p = Polygon::default();
        for (dl, dw) in [(hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw)] {
            p.push((self.x + dl * c - dw * s, self.y + dl * s + dw * c));
        }
        p
    }

    /// Volume.
    pub fn volume(&self) -> f64 {
        self.l.max(0.0) * self.w.max(0.0) * self.h.max(0.0)
    }

    fn vertical_overlap(&self, other: &Box3d) -> f64 {
        let top = (self.z + self.h / 2.0).min(other.z + other.h / 2.0);
        let bottom = (self.z - self.h / 2.0).max(other.z - other.h / 2.0);
        (top - bottom).max(0.0)
    }

    /// Intersection volume (0 when either box is degenerate).
    pub fn intersection(&self, other: &Box3d) -> f64 {
        if self.volume() <= 0.0 || other.volume() <= 0.0 {
            return 0.0;
        }
        clip(&self.footprint(), &other.footprint()).area() * self.vertical_overlap(other)
    }

    /// 3D intersection over union, in [0, 1].
    pub fn iou(&self, other: &Box3d) -> f64 {
        let inter = self.intersection(other);
        let union = self.volume() + other.volume() - inter;
        if union > 0.0 {
            inter / union
        } else {
            0.0
        }
    }

    /// 3D generalized IoU, in [−1, 1]: IoU minus the share of the enclosing volume (hull of
    /// both footprints × joint height) that the union leaves empty.
    pub fn giou(&self, other: &Box3d) -> f64 {
        let inter = self.intersection(other);
        let union = self.volume() + other.volume() - inter;
        let top = (self.z + self.h / 2.0).max(other.z + other.h / 2.0);
        let bottom = (self.z - self.h / 2.0).min(other.z - other.h / 2.0);
        let (a, b) = (self.footprint(), other.footprint());
        let mut all = [(0.0, 0.0); 8];
        all[..4].copy_from_slice(a.vertices());
        all[4..].copy_from_slice(b.vertices());
        let enclosing = hull(&mut all).area() * (top - bottom);
        if union <= 0.0 || enclosing <= 0.0 {
            return 0.0;
        }
        inter / union - (enclosing - union) / enclosing
    }

    /// Horizontal distance between centres.
    pub fn centre_distance(&self, other: &Box3d) -> f64 {
        libm::hypot(self.x - other.x, self.y - other.y)
    }
}

/// Sutherland–Hodgman: `subject` clipped by the convex, counter-clockwise `clipper`.
fn clip(subject: &Polygon, clipper: &Polygon) -> Polygon {
    let mut out = *subject;
    let c = clipper.vertices();
    for i in 0..c.len() {
        let (a, b) = (c[i], c[(i + 1) % c.len()]);
        // Points within rounding of the edge count as on it: coincident edges (identical
        // or touching boxes) must not produce slivers from sign noise.
        let eps = 1e-12 * ((b.0 - a.0) * (b.0 - a.0) + (b.1 - a.1) * (b.1 - a.1)).max(1e-300);
        let input = out;
        out = Polygon::default();
        let v = input.vertices();
        for j in 0..v.len() {
            let (p, q) = (v[j], v[(j + 1) % v.len()]);
            let (dp, dq) = (cross(a, b, p), cross(a, b, q));
            if dp >= -eps {
                out.push(p);
            }
            if (dp > eps && dq < -eps) || (dp < -eps && dq > eps) {
                let t = dp / (dp - dq);
                out.push((p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1)));
            }
        }
        if out.len == 0 {
            break;
        }
    }
    out
}

/// Convex hull (Andrew's monotone chain) of up to 8 points.
fn hull(points: &mut [(f64, f64); 8]) -> Polygon {
    points.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    let mut h = [(0.0, 0.0); 16];
    let mut k = 0;
    for &p in points.iter() {
        while k >= 2 && cross(h[k - 2], h[k - 1], p) <= 0.0 {
            k -= 1;
        }
        h[k] = p;
        k += 1;
    }
    let lower = k + 1;
    for &p in points.iter().rev().skip(1) {
        while k >= lower && cross(h[k - 2], h[k - 1], p) <= 0.0 {
            k -= 1;
        }
        h[k] = p;
        k += 1;
    }
    let mut out = Polygon::default();
    for &p in &h[..k.saturating_sub(1)] {
        out.push(p);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::FRAC_PI_4;

    fn b(x: f64, y: f64, yaw: f64, l: f64, w: f64) -> Box3d {
        Box3d { x, y, z: 0.0, yaw, l, w, h: 2.0 }
    }

    #[test]
    fn axis_aligned_overlap() {
        let a = b(0.0, 0.0, 0.0, 4.0, 2.0);
        assert!((a.iou(&a) - 1.0).abs() < 1e-12);
        // Shifted by 2 m along x: intersection 2×2×2 = 8, union 16 + 16 − 8.
        assert!((a.iou(&b(2.0, 0.0, 0.0, 4.0, 2.0)) - 8.0 / 24.0).abs() < 1e-12);
        // Same footprint, 1 m tall, centred at 1 m: 0.5 m of it inside [−1, 1].
        let lifted = Box3d { z: 1.0, h: 1.0, ..a };
        assert!((a.intersection(&lifted) - 8.0 * 0.5).abs() < 1e-12);
    }

    #[test]
    fn rotated_squares() {
        // A 2×2 square and the same turned 45°: overlap is the regular
        // octagon of area 8(√2 − 1).
        let a = b(0.0, 0.0, 0.0, 2.0, 2.0);
        let r = b(0.0, 0.0, FRAC_PI_4, 2.0, 2.0);
        let octagon = 8.0 * (core::f64::consts::SQRT_2 - 1.0);
        assert!((a.intersection(&r) - octagon * 2.0).abs() < 1e-12);
        // Turning by π gives the same box.
        assert!((a.iou(&b(0.0, 0.0, core::f64::consts::PI, 2.0, 2.0)) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn giou_goes_negative_with_distance() {
        let a = b(0.0, 0.0, 0.0, 4.0, 2.0);
        assert!((a.giou(&a) - 1.0).abs() < 1e-12);
        let near = a.giou(&b(6.0, 0.0, 0.0, 4.0, 2.0));
        let far = a.giou(&b(20.0, 0.0, 0.0, 4.0, 2.0));
        // Hull 10 × 2 × 2 = 40, union 32: GIoU = −8/40.
        assert!((near + 0.2).abs() < 1e-12, "{near}");
        assert!(far < near && far > -1.0);
        assert_eq!(a.centre_distance(&b(3.0, 4.0, 1.0, 1.0, 1.0)), 5.0);
    }

    #[test]
    fn disjoint_and_degenerate() {
        let a = b(0.0, 0.0, 0.3, 4.0, 2.0);
        assert_eq!(a.iou(&b(100.0, 0.0, 0.0, 4.0, 2.0)), 0.0);
        assert_eq!(a.iou(&b(0.0, 0.0, 0.0, 0.0, 0.0)), 0.0);
        assert!(a.giou(&b(0.0, 0.0, 0.0, 0.0, 0.0)).is_finite());
    }

    fn inside(b: &Box3d, x: f64, y: f64) -> bool {
        let (c, s) = (cos(b.yaw), sin(b.yaw));
        let (dx, dy) = (x - b.x, y - b.y);
        (dx * c + dy * s).abs() <= b.l / 2.0 && (-dx * s + dy * c).abs() <= b.w / 2.0
    }

    proptest::proptest! {
        #[test]
        fn overlap_is_symmetric_bounded_and_matches_a_grid_count(
            x in -3.0f64..3.0, y in -3.0f64..3.0, yaw_a in -3.2f64..3.2, yaw_b in -3.2f64..3.2,
            l in 0.5f64..5.0, w in 0.5f64..3.0,
        ) {
            let a = b(0.0, 0.0, yaw_a, 4.0, 2.0);
            let c = b(x, y, yaw_b, l, w);
            let (iou, giou) = (a.iou(&c), a.giou(&c));
            proptest::prop_assert!((iou - c.iou(&a)).abs() < 1e-9);
            proptest::prop_assert!((0.0..=1.0 + 1e-12).contains(&iou));
            proptest::prop_assert!(giou <= iou + 1e-12 && giou >= -1.0 - 1e-12);
            // Footprint intersection against counting a 200 × 200 grid over [−6, 6]².
            let n = 200;
            let cell = 12.0 / n as f64;
            let mut count = 0u32;
            for i in 0..n {
                for j in 0..n {
                    let (px, py) = (-6.0 + (i as f64 + 0.5) * cell, -6.0 + (j as f64 + 0.5) * cell);
                    count += u32::from(inside(&a, px, py) && inside(&c, px, py));
                }
            }
            let grid = f64::from(count) * cell * cell;
            let exact = a.intersection(&c) / 2.0;
            proptest::prop_assert!((grid - exact).abs() < 0.25, "grid {grid} vs {exact}");
        }
    }
}
