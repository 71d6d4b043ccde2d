//! Axis-aligned image boxes and their overlap measures.
//!
//! Boxes are `(left, top, width, height)` in pixels, as MOTChallenge files write them.
//! IoU follows motmetrics' `boxiou` (negative extents count as zero, disjoint boxes give
//! exactly 0), so distances computed here equal the evaluation tool's.

/// An image box.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Box2d {
    /// Left edge.
    pub x: f64,
    /// Top edge.
    pub y: f64,
    /// Width.
    pub w: f64,
    /// Height.
    pub h: f64,
}

/// Why a box from outside cannot be used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BoxError {
    /// A coordinate is NaN or infinite.
    NotFinite,
    /// Width or height is zero or negative.
    Empty,
}

impl core::fmt::Display for BoxError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BoxError::NotFinite => write!(f, "box coordinate is not finite"),
            BoxError::Empty => write!(f, "box has zero or negative size"),
        }
    }
}

impl core::error::Error for BoxError {}

impl Box2d {
    /// A validated box: finite, positive width and height.
    pub fn new(x: f64, y: f64, w: f64, h: f64) -> Result<Self, BoxError> {
        if ![x, y, w, h].iter().all(|v| v.is_finite()) {
            return Err(BoxError::NotFinite);
        }
        if w <= 0.0 || h <= 0.0 {
            return Err(BoxError::Empty);
        }
        Ok(Box2d { x, y, w, h })
    }

    /// Right edge.
    pub fn right(&self) -> f64 {
        self.x + self.w
    }

    /// Bottom edge.
    pub fn bottom(&self) -> f64 {
        self.y + self.h
    }

    /// Area (zero for negative extents).
    pub fn area(&self) -> f64 {
        self.w.max(0.0) * self.h.max(0.0)
    }

    /// Area of the intersection.
    pub fn intersection(&self, other: &Box2d) -> f64 {
        let w = (self.right().min(other.right()) - self.x.max(other.x)).max(0.0);
        let h = (self.bottom().min(other.bottom()) - self.y.max(other.y)).max(0.0);
        w * h
    }

    /// Intersection over union, in [0, 1]; 0 for disjoint or degenerate boxes.
    pub fn iou(&self, other: &Box2d) -> f64 {
        let inter = self.intersection(other);
        if inter == 0.0 {
            return 0.0;
        }
        let union = self.area() + other.area() - inter;
        if union > 0.0 {
            inter / union
        } else {
            0.0
        }
    }

    /// Generalized IoU (Rezatofighi et al. 2019), in [−1, 1]: IoU minus the share of the
    /// smallest enclosing box that neither box covers. Unlike IoU it still ranks disjoint
    /// boxes by how far apart they are.
    pub fn giou(&self, other: &Box2d) -> f64 {
        let inter = self.intersection(other);
        let union = self.area() + other.area() - inter;
        let hull_w = self.right().max(other.right()) - self.x.min(other.x);
        let hull_h = self.bottom().max(other.bottom()) - self.y.min(other.y);
        let hull = hull_w.max(0.0) * hull_h.max(0.0);
        if union <= 0.0 || hull <= 0.0 {
            return 0.0;
        }
        inter / union - (hull - union) / hull
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x: f64, y: f64, w: f64, h: f64) -> Box2d {
        Box2d::new(x, y, w, h).expect("valid box")
    }

    #[test]
    fn iou_of_overlapping_identical_and_disjoint_boxes() {
        let a = b(0.0, 0.0, 2.0, 2.0);
        assert_eq!(a.iou(&a), 1.0);
        assert_eq!(a.iou(&b(1.0, 1.0, 2.0, 2.0)), 1.0 / 7.0);
        assert_eq!(a.iou(&b(2.0, 0.0, 2.0, 2.0)), 0.0, "touching edges");
        assert_eq!(a.iou(&b(5.0, 5.0, 1.0, 1.0)), 0.0);
    }

    #[test]
    fn giou_ranks_disjoint_boxes_by_distance() {
        let a = b(0.0, 0.0, 2.0, 2.0);
        assert_eq!(a.giou(&a), 1.0);
        let near = a.giou(&b(3.0, 0.0, 2.0, 2.0));
        let far = a.giou(&b(10.0, 0.0, 2.0, 2.0));
        assert!(far < near && near < 0.0 && far > -1.0, "{near} {far}");
        // Hull 5×2 = 10, union 8: GIoU = 0 − 2/10.
        assert!((near + 0.2).abs() < 1e-15);
        let overlap = b(1.0, 1.0, 2.0, 2.0);
        assert!((a.giou(&overlap) - (1.0 / 7.0 - 2.0 / 9.0)).abs() < 1e-15);
    }

    #[test]
    fn bad_boxes_are_rejected() {
        assert_eq!(Box2d::new(f64::NAN, 0.0, 1.0, 1.0), Err(BoxError::NotFinite));
        assert_eq!(Box2d::new(0.0, 0.0, f64::INFINITY, 1.0), Err(BoxError::NotFinite));
        assert_eq!(Box2d::new(0.0, 0.0, 0.0, 1.0), Err(BoxError::Empty));
        assert_eq!(Box2d::new(0.0, 0.0, 1.0, -1.0), Err(BoxError::Empty));
    }
}
