//! `dash2sim finish`: the arguments, the refused anchors on stderr and the report rendered.

use std::path::PathBuf;

use clap::Args;
use dash2sim_finish::windows::{DriveVerification, Verdict};
use dash2sim_finish::{self as finish, FinishRequest, FinishedFile};
use dash2sim_linux::log::signing;

use crate::record::DeviceArgs;
use dash2sim_linux::Result;

/// `dash2sim finish`.
#[derive(Debug, Args)]
pub struct FinishArgs {
    /// The device's log.
    pub log: PathBuf,
    /// The finished log.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Geo-referenced anchors: CSV with the header `t,lat,lon,alt,sigma_m` (rear axle at log
    /// time t, UTC s) or `x,y,z,lat,lon,alt,sigma_m` (a VO-frame point).
    #[arg(long)]
    pub anchors: Option<PathBuf>,
    /// A map tile: verify the finished drive per 15 s window and as a whole.
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// The dashcam as given to `record`.
    #[command(flatten)]
    pub device: DeviceArgs,
    /// Keyframe spacing of the re-anchoring, s.
    #[arg(long, default_value_t = finish::DEFAULT_KEYFRAME_S)]
    pub keyframe: f64,
    /// Refuse the log unless every segment is signed by this public key (64 hex digits, or
    /// the `.pub` file of `dash2sim keygen`), unaltered and in an unbroken chain.
    #[arg(long, value_name = "PUB")]
    pub require_signed: Option<String>,
    /// Also write the problem the re-anchoring solved (each VO session's variables, factors,
    /// noise models and robust kernels, the values it started from and ended at) as JSON,
    /// for an outside solver such as GTSAM (`scripts/gtsam_check.py`, docs/finishing.md).
    /// It solves the drive a second time.
    #[arg(long, value_name = "JSON")]
    pub factor_graph: Option<PathBuf>,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `dash2sim finish`: [`finish::finish_file`], the refused anchors on stderr, the report on
/// stdout.
pub fn run(args: &FinishArgs) -> Result<()> {
    let request = FinishRequest {
        log: args.log.clone(),
        output: args.output.clone(),
        anchors: args.anchors.clone(),
        map: args.map.clone(),
        device: args.device.clone().into(),
        keyframe: args.keyframe,
        require_signed: args.require_signed.as_deref().map(signing::read_public).transpose()?,
        factor_graph: args.factor_graph.clone(),
    };
    let finished = finish::finish_file(&request)?;
    let anchors = &finished.report.anchors;
    for refused in &anchors.refused {
        eprintln!("{}:{}: {}", anchors.file.as_deref().unwrap_or_default(), refused.line, refused.reason);
    }
    if args.json {
        println!("{}", crate::render::json_of(&finished)?);
    } else {
        print_report(&finished);
    }
    Ok(())
}

fn print_report(f: &FinishedFile) {
    let r = &f.report;
    let a = &r.anchoring;
    println!("{} → {} ({} records, {} bytes)", r.log, f.output, r.records, f.bytes);
    println!(
        "  anchoring     {} keyframes, {} iterations: scale {:.6} ± {:.4} %, positions ± {:.2} m, GNSS latency {:.0} ms (the log's UTC moved {:+.0} ms), wheel factor {:.4}",
        a.keyframes,
        a.iterations,
        a.scale,
        100.0 * a.scale_sigma_relative,
        a.position_sigma_m,
        1000.0 * a.gnss_latency_s,
        1000.0 * r.utc_shift_s,
        a.wheel_factor,
    );
    println!(
        "  inputs        GNSS {} of {} fixes used, {} speed samples{}, anchors {} used, {} refused",
        r.gnss.used,
        r.gnss.fixes,
        r.speed_samples,
        r.wheel_latency_s.map_or(String::new(), |l| format!(" ({:.0} ms late)", 1000.0 * l)),
        r.anchors.used,
        r.anchors.refused.len()
    );
    let t = &r.tracks;
    println!(
        "  tracks        {} states: {} moving tracks smoothed, {} static objects merged, {} states without an ego pose dropped",
        t.states, t.smoothed, t.static_merged, t.unplaced
    );
    if let Some(v) = &r.verification {
        print_verification(v);
    }
    if r.damage.stretches > 0 {
        println!(
            "  damage        {} stretches ({} bytes) of the source log were lost",
            r.damage.stretches, r.damage.bytes
        );
    }
}

/// The verification lines of the human report.
fn print_verification(v: &DriveVerification) {
    let line = |s: &Verdict| format!("{:.2} ({})", s.score, if s.verified { "verified" } else { "not verified" });
    println!(
        "  verification  drive {} channel-insensitive, {} channel-sensitive",
        line(&v.drive.channel_insensitive),
        line(&v.drive.channel_sensitive)
    );
    for w in &v.windows {
        println!(
            "                {:>6.1}–{:<6.1} s  {} / {}",
            w.start_s,
            w.end_s,
            line(&w.channel_insensitive),
            line(&w.channel_sensitive)
        );
    }
}
