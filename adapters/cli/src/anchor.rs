//! `dash2sim anchor`: the arguments and the summary rendered.

use std::path::PathBuf;

use clap::Args;
use dash2sim_linux::record::VoFrame;
use dash2sim_linux::Result;
use dash2sim_verify::anchoring::{self, AnchorRequest};

/// Arguments of `dash2sim anchor`.
#[derive(Debug, Args)]
pub struct AnchorArgs {
    /// VO trajectory (TUM; any frame, unknown scale).
    #[arg(long)]
    vo: PathBuf,
    /// GNSS positions in the local ENU frame (TUM; orientation ignored).
    #[arg(long)]
    gnss: PathBuf,
    /// Vehicle speed CSV: `t,speed_mps` per line (a header line is allowed).
    #[arg(long)]
    speed: Option<PathBuf>,
    /// 1-σ horizontal GNSS error, m (HDOP × UERE when the receiver reports HDOP).
    #[arg(long, default_value_t = 2.5)]
    sigma: f64,
    /// `full`: 7-DoF Sim(3); `gravity`: VO z is vertical, estimate yaw/scale/translation.
    #[arg(long, value_parser = ["full", "gravity"], default_value = "full")]
    mode: String,
    /// Forgetting time constant, s (`inf` never forgets).
    #[arg(long, default_value_t = 12.0)]
    forget: f64,
    /// Write the anchored trajectory (TUM) here; frames before the estimate is
    /// observable are left out.
    #[arg(long, short = 'o')]
    output: Option<PathBuf>,
    /// Print a JSON summary on stdout.
    #[arg(long)]
    json: bool,
}

/// `dash2sim anchor`.
pub fn run(args: &AnchorArgs) -> Result<()> {
    let summary = anchoring::anchor_files(&AnchorRequest {
        vo: args.vo.clone(),
        gnss: args.gnss.clone(),
        speed: args.speed.clone(),
        sigma: args.sigma,
        mode: if args.mode == "gravity" { VoFrame::Gravity } else { VoFrame::Full },
        forget: args.forget,
        output: args.output.clone(),
    })?;
    if args.json {
        println!("{}", crate::render::json_of(&summary)?);
        return Ok(());
    }
    let q = &summary.quality;
    println!("anchored {} of {} VO frames", summary.anchored_frames, summary.frames);
    match summary.observable_after_s {
        Some(s) => println!("observable after {s:.2} s"),
        None => println!("never observable: {:?}", q.observability),
    }
    if let Some(t) = &summary.estimate {
        println!("final scale {:.6} (±{:.3} %)", t.scale, 100.0 * q.scale_rel_sigma);
    }
    println!("anchors: {} used, {} rejected, {} dropped", q.anchors_used, q.anchors_rejected, q.anchors_dropped);
    if let Some(l) = q.latency_s {
        println!("GNSS latency estimate {:.0} ms", l * 1e3);
    }
    if let Some(f) = q.wheel_factor {
        println!("wheel speed factor {f:.5}");
    }
    Ok(())
}
