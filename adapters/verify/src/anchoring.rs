//! Offline anchoring: replay VO, GNSS and speed files through the core [`Anchorer`] in
//! time order, exactly as the device would see them live, and write the anchored track.

use std::path::{Path, PathBuf};

use dash2sim_core::anchor::{AnchorConfig, Anchorer, Observability, Quality};
use dash2sim_core::sim3::Sim3;
use dash2sim_core::time::Timestamp;
use serde::Serialize;

use crate::evaluate::Alignment;
use dash2sim_linux::record::VoFrame;
use dash2sim_linux::trajectory::{self, Format, Trajectory};
use dash2sim_linux::{Error, Field, Result};

/// Anchoring of trajectory files (`dash2sim anchor`).
#[derive(Clone, Debug)]
pub struct AnchorRequest {
    /// VO trajectory (TUM; any frame, unknown scale).
    pub vo: PathBuf,
    /// GNSS positions in the local ENU frame (TUM; orientation ignored).
    pub gnss: PathBuf,
    /// Vehicle speed CSV: `t,speed_mps` per line (a header line is allowed).
    pub speed: Option<PathBuf>,
    /// 1-σ horizontal GNSS error, m.
    pub sigma: f64,
    /// The VO frame: any orientation (7-DoF Sim(3)) or gravity-aligned.
    pub mode: VoFrame,
    /// Forgetting time constant, s (`inf` never forgets).
    pub forget: f64,
    /// Write the anchored trajectory (TUM) here; frames before the estimate is observable
    /// are left out.
    pub output: Option<PathBuf>,
}

/// What anchoring the files gave.
#[derive(Clone, Copy, Debug)]
pub struct AnchorSummary {
    /// VO frames.
    pub frames: usize,
    /// Frames with an anchored pose.
    pub anchored_frames: usize,
    /// Seconds from the first VO frame to the first observable estimate.
    pub observable_after_s: Option<f64>,
    /// The estimate at the last frame.
    pub estimate: Option<Sim3>,
    /// Its quality.
    pub quality: Quality,
}

/// How `dash2sim anchor --json` gives the summary: the quality's figures beside the counts.
impl Serialize for AnchorSummary {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> std::result::Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Summary {
            frames: usize,
            anchored_frames: usize,
            observable_after_s: Option<f64>,
            estimate: Option<Alignment>,
            observability: String,
            anchors_used: u32,
            anchors_rejected: u32,
            anchors_dropped: u32,
            rms_residual_m: f64,
            rotation_sigma_deg: f64,
            scale_rel_sigma: f64,
            latency_s: Option<f64>,
            wheel_factor: Option<f64>,
        }
        let q = &self.quality;
        Summary {
            frames: self.frames,
            anchored_frames: self.anchored_frames,
            observable_after_s: self.observable_after_s,
            estimate: self.estimate.as_ref().map(Alignment::from),
            observability: format!("{:?}", q.observability),
            anchors_used: q.anchors_used,
            anchors_rejected: q.anchors_rejected,
            anchors_dropped: q.anchors_dropped,
            rms_residual_m: q.rms_residual_m,
            rotation_sigma_deg: q.rotation_sigma_rad.to_degrees(),
            scale_rel_sigma: q.scale_rel_sigma,
            latency_s: q.latency_s,
            wheel_factor: q.wheel_factor,
        }
        .serialize(serializer)
    }
}

/// The estimate the device had at one VO frame.
#[derive(Clone, Copy, Debug)]
pub struct FrameEstimate {
    /// VO frame time, s.
    pub t: f64,
    /// The VO → ENU transform in force (after any anchor up to this frame).
    pub estimate: Option<Sim3>,
    /// Quality after the latest anchor.
    pub quality: Quality,
}

/// Read a `t,value` CSV (first line may be a header); errors name the line.
pub fn read_speed_csv(path: &Path) -> Result<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::file(path, e))?;
    let mut rows = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut fields = line.split(',').map(str::trim);
        let parsed = (fields.next().map(str::parse::<f64>), fields.next().map(str::parse::<f64>));
        match parsed {
            (Some(Ok(t)), Some(Ok(v))) if t.is_finite() && v.is_finite() => {
                if rows.last().is_some_and(|&(prev, _)| t < prev) {
                    return Err(Error::line(path, i + 1, format!("timestamp {t} is earlier than the previous one")));
                }
                rows.push((t, v));
            }
            _ if i == 0 => {} // header
            _ => return Err(Error::line(path, i + 1, "expected `t,speed` with finite numbers")),
        }
    }
    if rows.is_empty() {
        return Err(Error::file(path, "no speed samples"));
    }
    Ok(rows)
}

fn stamp(t: f64) -> Result<Timestamp> {
    Timestamp::from_secs_f64(t).ok_or_else(|| Error::invalid(format!("timestamp {t} is out of range")))
}

/// Feed the three streams through an anchorer in time order; one estimate per VO frame.
pub fn replay(
    vo: &Trajectory,
    gnss: &Trajectory,
    speed: &[(f64, f64)],
    sigma_m: f64,
    config: AnchorConfig,
) -> Result<Vec<FrameEstimate>> {
    replay_with_sigmas(vo, gnss, &vec![sigma_m; gnss.len()], speed, config)
}

/// [`replay`] with a σ per fix (as receivers report it, e.g. HDOP × UERE).
pub fn replay_with_sigmas(
    vo: &Trajectory,
    gnss: &Trajectory,
    sigmas: &[f64],
    speed: &[(f64, f64)],
    config: AnchorConfig,
) -> Result<Vec<FrameEstimate>> {
    if sigmas.len() != gnss.len() {
        return Err(Error::invalid(format!("{} σ for {} fixes", sigmas.len(), gnss.len())));
    }
    if vo.stamps.is_empty() || gnss.stamps.is_empty() {
        return Err(Error::invalid("VO and GNSS trajectories need timestamps (TUM format)"));
    }
    let mut anchorer: Anchorer = Anchorer::new(config);
    let (mut i_speed, mut i_gnss) = (0, 0);
    let mut frames = Vec::with_capacity(vo.len());
    for (&t_vo, pose) in vo.stamps.iter().zip(&vo.poses) {
        // Everything that happened up to this frame, speed before GNSS at equal times.
        while let Some(&(t, v)) = speed.get(i_speed).filter(|(t, _)| *t <= t_vo) {
            anchorer.push_speed(stamp(t)?, v).map_err(|e| Error::refused(format!("speed at {t}"), e))?;
            i_speed += 1;
        }
        while let Some(&t) = gnss.stamps.get(i_gnss).filter(|&&t| t <= t_vo) {
            let p = gnss.poses[i_gnss].translation;
            anchorer.push_gnss(stamp(t)?, p, sigmas[i_gnss]).map_err(|e| Error::refused(format!("GNSS at {t}"), e))?;
            i_gnss += 1;
        }
        anchorer.push_vo(stamp(t_vo)?, pose.translation).map_err(|e| Error::refused(format!("VO at {t_vo}"), e))?;
        frames.push(FrameEstimate { t: t_vo, estimate: anchorer.estimate().copied(), quality: *anchorer.quality() });
    }
    Ok(frames)
}

/// The anchored trajectory: each VO pose mapped with the estimate of its time.
pub fn anchored_trajectory(vo: &Trajectory, frames: &[FrameEstimate]) -> Trajectory {
    let mut out = Trajectory::default();
    for (pose, f) in vo.poses.iter().zip(frames) {
        if let Some(t) = f.estimate {
            out.stamps.push(f.t);
            out.poses.push(t.transform_pose(pose));
        }
    }
    out
}

/// Anchor the VO file to the GNSS (and speed) files, write the anchored trajectory if asked.
pub fn anchor_files(args: &AnchorRequest) -> Result<AnchorSummary> {
    if !(args.sigma.is_finite() && args.sigma > 0.0) {
        return Err(Error::request(Field::Sigma, format!("{} must be a positive number of metres", args.sigma)));
    }
    if args.forget.is_nan() || args.forget <= 0.0 {
        return Err(Error::request(Field::Forget, format!("{} must be positive (or inf)", args.forget)));
    }
    let vo = Trajectory::read(&args.vo, Format::Tum).map_err(Error::other)?;
    let gnss = Trajectory::read(&args.gnss, Format::Tum).map_err(Error::other)?;
    let speed = match &args.speed {
        Some(p) => read_speed_csv(p)?,
        None => Vec::new(),
    };
    let config = AnchorConfig {
        mode: args.mode.anchor_mode(),
        forgetting_time_constant_s: args.forget,
        ..AnchorConfig::default()
    };
    let frames = replay(&vo, &gnss, &speed, args.sigma, config)?;
    let anchored = anchored_trajectory(&vo, &frames);
    if let Some(out) = &args.output {
        trajectory::write_file(&anchored, out, Format::Tum).map_err(|e| Error::file(out, e))?;
    }
    let observable_after_s =
        frames.iter().find(|f| f.quality.observability == Observability::Observable).map(|f| f.t - vo.stamps[0]);
    let last = frames.last().ok_or_else(|| Error::invalid("no VO frames"))?;
    Ok(AnchorSummary {
        frames: vo.len(),
        anchored_frames: anchored.len(),
        observable_after_s,
        estimate: last.estimate,
        quality: last.quality,
    })
}
