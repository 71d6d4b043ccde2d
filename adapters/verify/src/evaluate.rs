//! `traj ape` / `traj rpe`: read, associate, align, measure — evo's pipeline.

use std::path::Path;

use dash2sim_core::sim3::{AlignError, AlignMode, Moments, Pose, Sim3};
use dash2sim_core::traj::{self, PoseRelation, RpePairs, Statistics, TrajError};

use dash2sim_linux::sync;
use dash2sim_linux::trajectory::{Format, Trajectory, TrajectoryError};

/// Fewer matched poses than this cannot be aligned or meaningfully evaluated.
pub const MIN_MATCHED_POSES: usize = 3;

/// How the estimate is aligned to the reference before measuring.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Align {
    /// No alignment.
    None,
    /// Rotation and translation (evo `-a`).
    Se3,
    /// Rotation, translation and scale (evo `-as`).
    Sim3,
    /// Scale only (evo `-s`).
    Scale,
}

/// Which pose error is measured (evo `-r`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Relation {
    /// Translation part, m.
    Trans,
    /// Full transformation, unit-less.
    Full,
    /// Rotation angle, degrees.
    AngleDeg,
    /// Rotation angle, radians.
    AngleRad,
}

impl Relation {
    fn core(self) -> PoseRelation {
        match self {
            Relation::Trans => PoseRelation::TranslationPart,
            Relation::Full => PoseRelation::FullTransformation,
            Relation::AngleDeg => PoseRelation::RotationAngleDeg,
            Relation::AngleRad => PoseRelation::RotationAngleRad,
        }
    }
}

/// What went wrong evaluating.
#[derive(Debug)]
pub enum EvalError {
    /// A file could not be read or parsed.
    File(TrajectoryError),
    /// Too few poses matched by timestamp (or KITTI files of different length).
    TooFewMatches {
        /// Poses matched.
        matched: usize,
        /// Poses in the reference.
        reference: usize,
        /// Poses in the estimate.
        estimate: usize,
        /// The first and last stamp of each file as read, s (none for KITTI files or an
        /// empty file): what makes a wrong time base visible.
        spans: Option<Spans>,
        /// The offset that was added to the estimate's stamps, s.
        t_offset: f64,
    },
    /// The alignment failed.
    Align(AlignError),
    /// The metric failed.
    Metric(TrajError),
}

impl std::fmt::Display for EvalError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            EvalError::File(e) => write!(f, "{e}"),
            EvalError::TooFewMatches { matched, reference, estimate, spans, t_offset } => {
                write!(
                    f,
                    "only {matched} poses matched (reference {reference}, estimate {estimate}); at least {MIN_MATCHED_POSES} are needed"
                )?;
                if let Some(spans) = spans {
                    spans.explain(f, *t_offset)?;
                }
                Ok(())
            }
            EvalError::Align(e) => write!(f, "alignment failed: {e}"),
            EvalError::Metric(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for EvalError {}

impl From<TrajectoryError> for EvalError {
    fn from(e: TrajectoryError) -> Self {
        EvalError::File(e)
    }
}

/// The first and last stamps of the two files, s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spans {
    /// The reference's.
    pub reference: (f64, f64),
    /// The estimate's, as read (before any offset).
    pub estimate: (f64, f64),
}

impl Spans {
    fn of(reference: &Trajectory, estimate: &Trajectory) -> Option<Self> {
        let span = |t: &Trajectory| Some((*t.stamps.first()?, *t.stamps.last()?));
        Some(Self { reference: span(reference)?, estimate: span(estimate)? })
    }

    /// The spans, and when they do not overlap the offset that would line up the first poses
    /// (the usual cause: one file counts from the drive's start, the other is in UTC).
    fn explain(&self, f: &mut std::fmt::Formatter<'_>, t_offset: f64) -> std::fmt::Result {
        let ((r0, r1), (e0, e1)) = (self.reference, self.estimate);
        write!(f, ". The reference spans {r0:.3}–{r1:.3} s, the estimate {e0:.3}–{e1:.3} s")?;
        if t_offset != 0.0 {
            write!(f, " (then {:.3}–{:.3} s with the time offset {t_offset} s)", e0 + t_offset, e1 + t_offset)?;
        }
        if e1 + t_offset < r0 || e0 + t_offset > r1 {
            write!(f, ": they do not overlap. If the files count time from different starts, ")?;
            if e1 - e0 <= r1 - r0 {
                write!(
                    f,
                    "any time offset from {:.3} to {:.3} s (added to the estimate's times) puts the estimate inside the reference's span",
                    r0 - e0,
                    r1 - e1
                )?;
            } else {
                write!(
                    f,
                    "a time offset of {:.3} s (added to the estimate's times) lines up their first poses",
                    r0 - e0
                )?;
            }
        }
        Ok(())
    }
}

/// How poses are paired by time (evo's `--t_max_diff` and `--t_offset`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Association {
    /// Largest stamp difference of a pair, s.
    pub max_diff: f64,
    /// Added to the estimate's stamps before pairing, s.
    pub t_offset: f64,
}

impl Association {
    /// Pairs within `max_diff`, no offset.
    pub fn within(max_diff: f64) -> Self {
        Self { max_diff, t_offset: 0.0 }
    }
}

/// The result of an APE or RPE evaluation.
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// The transform applied to the estimate (identity for `--align none`).
    pub alignment: Sim3,
    /// Error statistics.
    pub stats: Statistics,
    /// Number of errors (poses for APE, pairs for RPE).
    pub n: usize,
    /// Matched poses.
    pub matched: usize,
}

/// Reference and estimate, read and associated (the estimate's stamps shifted by the
/// association's offset first, as evo does). KITTI files pair by index.
pub fn load_pair(
    reference: &Path,
    estimate: &Path,
    format: Format,
    association: Association,
) -> Result<(Trajectory, Trajectory), EvalError> {
    let traj_ref = Trajectory::read(reference, format)?;
    let est_format = if format == Format::Euroc { Format::Tum } else { format };
    let mut traj_est = Trajectory::read(estimate, est_format)?;
    let (n_ref, n_est) = (traj_ref.len(), traj_est.len());
    let spans = Spans::of(&traj_ref, &traj_est);
    let t_offset = association.t_offset;
    let too_few = |matched| EvalError::TooFewMatches { matched, reference: n_ref, estimate: n_est, spans, t_offset };
    let (r, e) = if format == Format::Kitti {
        if traj_ref.len() != traj_est.len() {
            return Err(too_few(0));
        }
        (traj_ref, traj_est)
    } else {
        traj_est.stamps.iter_mut().for_each(|t| *t += t_offset);
        sync::associate(&traj_ref, &traj_est, association.max_diff)
    };
    if r.len() < MIN_MATCHED_POSES {
        return Err(too_few(r.len()));
    }
    Ok((r, e))
}

/// The Umeyama transform estimate → reference for `align`.
pub fn alignment(reference: &Trajectory, estimate: &Trajectory, align: Align) -> Result<Sim3, EvalError> {
    let mode = match align {
        Align::None => return Ok(Sim3::identity()),
        Align::Se3 => AlignMode::Se3,
        Align::Sim3 => AlignMode::Sim3,
        Align::Scale => AlignMode::ScaleOnly,
    };
    let mut moments = Moments::new();
    for (x, y) in estimate.positions().zip(reference.positions()) {
        moments.push(x, y, 1.0).map_err(EvalError::Align)?;
    }
    moments.align(mode).map_err(EvalError::Align)
}

/// Align the estimate, let `metric` write one error per value into a buffer of
/// `reference.len()` (the most either metric produces: every RPE pair has a distinct
/// first index), and summarise.
fn evaluate(
    reference: &Trajectory,
    estimate: &Trajectory,
    align: Align,
    metric: impl FnOnce(&[Pose], &mut [f64]) -> Result<usize, TrajError>,
) -> Result<Evaluation, EvalError> {
    let t = alignment(reference, estimate, align)?;
    let est: Vec<Pose> = estimate.poses.iter().map(|p| t.transform_pose(p)).collect();
    let mut errors = vec![0.0; reference.len()];
    let n = metric(&est, &mut errors).map_err(EvalError::Metric)?;
    let stats = Statistics::from_errors(&mut errors[..n]).map_err(EvalError::Metric)?;
    Ok(Evaluation { alignment: t, stats, n, matched: reference.len() })
}

/// Absolute pose error of associated trajectories.
pub fn ape(
    reference: &Trajectory,
    estimate: &Trajectory,
    align: Align,
    relation: Relation,
) -> Result<Evaluation, EvalError> {
    evaluate(reference, estimate, align, |est, errors| traj::ape(&reference.poses, est, relation.core(), errors))
}

/// Relative pose error of associated trajectories.
pub fn rpe(
    reference: &Trajectory,
    estimate: &Trajectory,
    align: Align,
    relation: Relation,
    pairs: RpePairs,
) -> Result<Evaluation, EvalError> {
    let mut scratch = vec![0.0; reference.len()];
    evaluate(reference, estimate, align, |est, errors| {
        traj::rpe(&reference.poses, est, pairs, relation.core(), &mut scratch, errors)
    })
}

/// A similarity as `traj --json` and `anchor --json` give it: `{"R": [[..]], "t": [..], "s": ..}`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Alignment {
    /// Rotation, row by row.
    #[serde(rename = "R")]
    pub rotation: [[f64; 3]; 3],
    /// Translation.
    #[serde(rename = "t")]
    pub translation: [f64; 3],
    /// Scale.
    #[serde(rename = "s")]
    pub scale: f64,
}

impl From<&Sim3> for Alignment {
    fn from(t: &Sim3) -> Self {
        let r = &t.rotation;
        Self {
            rotation: core::array::from_fn(|i| core::array::from_fn(|j| r[(i, j)])),
            translation: [t.translation.x, t.translation.y, t.translation.z],
            scale: t.scale,
        }
    }
}
