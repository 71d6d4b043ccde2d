//! The comma2k19 anchoring scenario: a synthetic VO track made from the real fused
//! poses, anchored online with the real u-blox fixes and the real CAN speed.

use std::path::Path;

use dash2sim_core::anchor::{AnchorConfig, Observability};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_linux::trajectory::{Format, Trajectory};
pub use dash2sim_sim::scenario::vo::VoModel;
use dash2sim_verify::anchoring::{self, FrameEstimate};

/// The real inputs of the scenario.
#[derive(Clone, Debug)]
pub struct Inputs {
    /// Fused camera poses in ENU (truth), 20 Hz.
    pub truth: Trajectory,
    /// u-blox fixes in the same ENU frame, stamped at receive time.
    pub gnss: Trajectory,
    /// CAN vehicle speed (mean of the wheel speeds), m/s.
    pub speed: Vec<(f64, f64)>,
}

/// Load the comma2k19 inputs from the data folder.
pub fn load(dir: &Path) -> Inputs {
    let truth = Trajectory::read(&dir.join("expected/global_pose_camera_enu.tum"), Format::Tum).expect("poses");
    let gnss = Trajectory::read(&dir.join("expected/gnss_ublox_enu.tum"), Format::Tum).expect("gnss");
    let speed = anchoring::read_speed_csv(&dir.join("expected/can_speed_mps.csv")).expect("speed");
    Inputs { truth, gnss, speed }
}

/// What one run measured.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// Per VO frame: the online estimate.
    pub frames: Vec<FrameEstimate>,
    /// Seconds from the first frame until the estimate was reported observable.
    pub observable_after_s: Option<f64>,
    /// Online anchored positions (None before observable).
    pub anchored: Vec<Option<Vector3<f64>>>,
    /// RMS of anchored − truth over anchored frames, m.
    pub ate_rmse_m: f64,
    /// Relative scale error per frame (None before observable).
    pub scale_error: Vec<Option<f64>>,
}

/// Run the anchorer over the scenario.
pub fn run(inputs: &Inputs, model: &VoModel, gnss: &Trajectory, use_speed: bool, config: AnchorConfig) -> Outcome {
    let vo = model.make_vo(&inputs.truth);
    let speed: &[(f64, f64)] = if use_speed { &inputs.speed } else { &[] };
    let frames = anchoring::replay(&vo, gnss, speed, 2.5, config).expect("replay");
    let t0 = vo.stamps[0];
    let observable_after_s =
        frames.iter().find(|f| f.quality.observability == Observability::Observable).map(|f| f.t - t0);
    let anchored: Vec<_> =
        frames.iter().zip(&vo.poses).map(|(f, p)| f.estimate.map(|t| t.transform_point(&p.translation))).collect();
    let (mut sse, mut n) = (0.0, 0);
    for (a, truth) in anchored.iter().zip(&inputs.truth.poses) {
        if let Some(a) = a {
            sse += (a - truth.translation).norm_squared();
            n += 1;
        }
    }
    let scale_error = frames.iter().map(|f| f.estimate.map(|t| t.scale / model.scale_at(f.t - t0) - 1.0)).collect();
    Outcome { frames, observable_after_s, anchored, ate_rmse_m: (sse / n.max(1) as f64).sqrt(), scale_error }
}

/// The scale error at `seconds` after the start (nearest frame).
pub fn scale_error_at(outcome: &Outcome, seconds: f64) -> Option<f64> {
    let t0 = outcome.frames.first()?.t;
    let k = outcome.frames.iter().position(|f| f.t - t0 >= seconds).unwrap_or(outcome.frames.len() - 1);
    outcome.scale_error[k]
}

/// Largest |scale error| from `seconds` on.
pub fn worst_scale_error_after(outcome: &Outcome, seconds: f64) -> f64 {
    let t0 = outcome.frames[0].t;
    outcome
        .frames
        .iter()
        .zip(&outcome.scale_error)
        .filter(|(f, _)| f.t - t0 >= seconds)
        .filter_map(|(_, e)| e.map(f64::abs))
        .fold(0.0, f64::max)
}
