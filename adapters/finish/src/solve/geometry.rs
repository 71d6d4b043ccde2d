//! The trajectory an estimate describes: keyframes, their positions and the segments'
//! similarities over the VO path — where a time falls on it, the camera's position and
//! velocity there, and the Jacobian rows of a position measured there.

use dash2sim_core::nalgebra::{Matrix3, Vector3};

use super::normal::Normal;
use super::{VoSample, BLOCK};
use crate::timeline::index_after;

/// Where a time falls: its segment, the fraction through it, the VO path's deviation
/// from the segment's chord, and the VO velocity's deviation from the chord's.
pub(super) struct Place {
    pub(super) k: usize,
    pub(super) alpha: f64,
    pub(super) w: Vector3<f64>,
    pub(super) w_dot: Vector3<f64>,
    pub(super) vo_rotation: Matrix3<f64>,
}

pub(super) fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Interpolated VO position and velocity at `t` (the samples are in time order).
pub(super) fn vo_at(vo: &[VoSample], t: f64) -> Option<(Vector3<f64>, Vector3<f64>, Matrix3<f64>)> {
    let j = index_after(vo, t, |s| s.t);
    let (a, b) = (vo.get(j.checked_sub(1)?)?, vo.get(j).or_else(|| vo.get(j - 1).filter(|s| s.t == t))?);
    if b.t == a.t {
        let before = vo.get(j.checked_sub(2)?)?;
        let v = (a.position - before.position) / (a.t - before.t);
        return Some((a.position, v, a.rotation));
    }
    let f = (t - a.t) / (b.t - a.t);
    let v = (b.position - a.position) / (b.t - a.t);
    let rotation = if f < 0.5 { a.rotation } else { b.rotation };
    Some((a.position + (b.position - a.position) * f, v, rotation))
}

/// A position residual, its σ per axis and its weight.
#[derive(Clone, Copy)]
pub(super) struct Measured {
    pub(super) residual: Vector3<f64>,
    pub(super) sigma: Vector3<f64>,
    pub(super) weight: f64,
}

/// The trajectory an estimate describes: keyframes, their positions and the segments'
/// similarities over the VO path.
#[derive(Clone, Copy)]
pub(super) struct Geometry<'a> {
    pub(super) vo: &'a [VoSample],
    pub(super) keyframe_vo: &'a [usize],
    pub(super) keyframe_t: &'a [f64],
    pub(super) p: &'a [Vector3<f64>],
    pub(super) rho: &'a [f64],
    pub(super) rotation: &'a [Matrix3<f64>],
}

impl Geometry<'_> {
    pub(super) fn scale_rotation(&self, k: usize) -> Matrix3<f64> {
        self.rotation[k] * self.rho[k].exp()
    }

    pub(super) fn place(&self, t: f64) -> Option<Place> {
        let last = *self.keyframe_t.last()?;
        if !(t >= self.keyframe_t[0] && t <= last) || self.keyframe_t.len() < 2 {
            return None;
        }
        let k = index_after(self.keyframe_t, t, |&kt| kt).saturating_sub(1).min(self.keyframe_t.len() - 2);
        let (t0, t1) = (self.keyframe_t[k], self.keyframe_t[k + 1]);
        let alpha = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
        let x0 = self.vo[self.keyframe_vo[k]].position;
        let x1 = self.vo[self.keyframe_vo[k + 1]].position;
        let (x, x_dot, vo_rotation) = vo_at(self.vo, t)?;
        let chord = x1 - x0;
        Some(Place { k, alpha, w: x - x0 - chord * alpha, w_dot: x_dot - chord / (t1 - t0), vo_rotation })
    }

    pub(super) fn camera(&self, at: &Place) -> Vector3<f64> {
        self.p[at.k] * (1.0 - at.alpha) + self.p[at.k + 1] * at.alpha + self.scale_rotation(at.k) * at.w
    }

    pub(super) fn velocity(&self, at: &Place) -> Vector3<f64> {
        let dt = self.keyframe_t[at.k + 1] - self.keyframe_t[at.k];
        (self.p[at.k + 1] - self.p[at.k]) / dt + self.scale_rotation(at.k) * at.w_dot
    }

    /// The rear axle's offset from the camera in the world, for the camera-frame `lever`.
    pub(super) fn lever(&self, at: &Place, lever: &Vector3<f64>) -> Vector3<f64> {
        self.rotation[at.k] * at.vo_rotation * lever
    }

    /// Jacobian columns of the camera position at `at`: p_k (3), p_{k+1} (3), ρ_k, φ_k (3).
    pub(super) fn camera_jacobian(&self, at: &Place) -> [Vector3<f64>; 10] {
        let sw = self.scale_rotation(at.k) * at.w;
        let minus_skew = -skew(&sw);
        let (a, b) = (1.0 - at.alpha, at.alpha);
        [
            Vector3::new(a, 0.0, 0.0),
            Vector3::new(0.0, a, 0.0),
            Vector3::new(0.0, 0.0, a),
            Vector3::new(b, 0.0, 0.0),
            Vector3::new(0.0, b, 0.0),
            Vector3::new(0.0, 0.0, b),
            sw,
            minus_skew.column(0).into(),
            minus_skew.column(1).into(),
            minus_skew.column(2).into(),
        ]
    }

    /// The three rows of a position residual at `at` (with the rear axle's lever when the
    /// rear axle is what is measured) and any further Jacobian blocks.
    pub(super) fn add_position_rows(
        &self,
        normal: &mut Normal,
        at: &Place,
        measured: Measured,
        extra: &[(usize, &[Vector3<f64>])],
        lever: Option<Vector3<f64>>,
    ) {
        let mut j = self.camera_jacobian(at);
        if let Some(l) = lever {
            // b = c − R·l: ∂/∂φ of −Exp(φ)·R̂·l is +[R̂·l]×.
            let s = skew(&l);
            for c in 0..3 {
                j[7 + c] += Vector3::from(s.column(c));
            }
        }
        let k = at.k * BLOCK;
        let mut blocks: Vec<(usize, &[Vector3<f64>])> =
            vec![(k, &j[0..3]), (k + BLOCK, &j[3..6]), (k + 3, &j[6..7]), (k + 4, &j[7..10])];
        blocks.extend_from_slice(extra);
        normal.push3(&measured.residual, &measured.sigma, &blocks, measured.weight);
    }
}
