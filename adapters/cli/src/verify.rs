//! `dash2sim verify`: the arguments, and the report rendered.

use std::path::{Path, PathBuf};

use dash2sim_core::obb::CORNER_NAMES;
use dash2sim_linux::{Error, Result};
use dash2sim_verify::{self as verify, Verification};

#[derive(Debug, clap::Args)]
pub struct VerifyArgs {
    /// A 4D log: its ego poses are replayed, its 3D tracks are the agents.
    #[arg(required_unless_present = "ego", conflicts_with = "ego")]
    log: Option<PathBuf>,
    /// The map tile (`dash2sim map build`).
    #[arg(long)]
    map: PathBuf,
    /// Instead of a log: an ego trajectory, TUM, in the map's ENU frame (x east, y north,
    /// the pose at the rear axle, heading from the quaternion).
    #[arg(long)]
    ego: Option<PathBuf>,
    /// Other road users and objects (the scenario `objects.csv` format), as non-reactive
    /// agents (replaces a log's tracks).
    #[arg(long)]
    objects: Option<PathBuf>,
    /// Only lanes near the route actually driven are drivable (not the opposing lanes or
    /// side roads); default: every mapped lane.
    #[arg(long)]
    channel_sensitive: bool,
    /// Ego width, m (default: nuPlan's Pacifica).
    #[arg(long, default_value_t = dash2sim_core::obb::PACIFICA.width)]
    width: f64,
    /// Rear axle → front bumper, m.
    #[arg(long, default_value_t = dash2sim_core::obb::PACIFICA.front)]
    front: f64,
    /// Rear axle → rear bumper, m.
    #[arg(long, default_value_t = dash2sim_core::obb::PACIFICA.rear)]
    rear: f64,
    /// Write the per-pose checks (corner distances, lanes, speed, TTC) to this CSV.
    #[arg(long)]
    poses: Option<PathBuf>,
    /// Only the poses from this time on (the log's time, s: UTC for a log).
    #[arg(long, allow_hyphen_values = true)]
    from: Option<f64>,
    /// Only the poses up to this time.
    #[arg(long, allow_hyphen_values = true)]
    to: Option<f64>,
    /// Print the report as JSON: each metric's score, the aggregate, `verified`, and the
    /// decision with its doubt (`decided`).
    #[arg(long)]
    json: bool,
    /// Decide with this many σ of doubt: the log is verified when it verifies anywhere
    /// within K of the ego's stated σ (and of the objects'), rejected when it verifies
    /// nowhere within it, undecided otherwise (docs/verify.md).
    #[arg(long, value_name = "K", default_value_t = verify::decide::DEFAULT_DECIDE_AT)]
    decide_at: f64,
    /// σ of the place relative to the ego of each object whose log states none, m along one axis (a finished log states one for every track: `TrackCovariance`; a device's log and `--objects` state none)
    #[arg(long, value_name = "M", default_value_t = verify::decide::DEFAULT_OBJECT_SIGMA_M)]
    object_sigma: f64,
}

/// `dash2sim verify`: a damaged log's warning on stderr, the report on stdout.
pub fn run(a: &VerifyArgs) -> Result<()> {
    let footprint = dash2sim_core::obb::Footprint { width: a.width, front: a.front, rear: a.rear };
    let valid = footprint.width > 0.0
        && footprint.front + footprint.rear > 0.0
        && [footprint.width, footprint.front, footprint.rear].iter().all(|v| v.is_finite());
    let ego = match (&a.log, &a.ego) {
        (Some(log), _) => verify::EgoSource::Log(log),
        (None, Some(tum)) => verify::EgoSource::Tum(tum),
        (None, None) => return Err(Error::invalid("give a LOG or --ego TRAJ.tum")),
    };
    let request = verify::VerifyRequest {
        map: &a.map,
        ego,
        objects: a.objects.as_deref(),
        channel_sensitive: a.channel_sensitive,
        footprint,
        poses: a.poses.as_deref(),
        window: (a.from.unwrap_or(f64::NEG_INFINITY), a.to.unwrap_or(f64::INFINITY)),
        doubt: verify::decide::DoubtSettings { decide_at: a.decide_at, object_sigma_m: a.object_sigma },
    };
    if !valid {
        return Err(Error::invalid("--width and --front + --rear must be positive"));
    }
    if !(a.decide_at.is_finite() && a.decide_at >= 0.0 && a.object_sigma.is_finite() && a.object_sigma >= 0.0) {
        return Err(Error::invalid("--decide-at and --object-sigma must be finite and ≥ 0"));
    }
    let (v, name) = verify::evaluate(&request, &mut |warning| eprintln!("warning: {warning}"))?;
    if a.json {
        // Through `Value`, whose keys are sorted (the output's order since the start).
        println!("{}", crate::render::json_of(&verify::report(&v, request.channel_sensitive))?);
        return Ok(());
    }
    render(&v, name, request.channel_sensitive);
    Ok(())
}

/// The report, one metric a line.
fn render(v: &Verification, name: &Path, channel_sensitive: bool) {
    let s = &v.scores;
    let mode = if channel_sensitive { "channel-sensitive" } else { "channel-insensitive" };
    println!("{}: {} poses over {:.1} s, {mode}", name.display(), s.poses, s.duration);
    let rows = [
        ("no at-fault collisions", s.no_at_fault_collisions, "multiplier"),
        ("drivable-area compliance", s.drivable_area, "multiplier"),
        ("driving-direction compliance", s.driving_direction, "multiplier"),
        ("ego is making progress", s.making_progress, "multiplier"),
        ("progress along expert route", s.progress, "weight 5"),
        ("time to collision within bound", s.ttc, "weight 5"),
        ("speed-limit compliance", s.speed_limit, "weight 4"),
        ("comfort", s.comfort, "weight 2"),
    ];
    for (name, value, role) in rows {
        println!("  {name:<32} {value:>6.3}  ({role})");
    }
    if let Some((t, _, r)) = v.steps.iter().find(|(_, _, r)| !r.check.compliant()) {
        let worst = r
            .check
            .corners
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.unwrap_or(f64::INFINITY).total_cmp(&b.1.unwrap_or(f64::INFINITY)));
        if let Some((k, d)) = worst {
            let d = d.map_or_else(|| "nothing drivable within 10 m".to_owned(), |d| format!("{d:.2} m outside"));
            println!("  first off the drivable area at t = {t:.2} s: {} corner {d}", CORNER_NAMES[k]);
        }
    }
    println!("score {:.2} → {}", s.score, if s.verified { "verified" } else { "NOT verified (needs > 90)" });
    if let Some(d) = &v.decided {
        let k = d.settings.decide_at;
        if d.poses_with_sigma == 0 && d.tracks_with_sigma == 0 && d.settings.object_sigma_m == 0.0 {
            println!("no σ stated for the ego or the objects: decided as nuPlan's verdict → {}", d.decision.name());
        } else {
            let objects = if d.tracks_with_sigma > 0 {
                format!("the tracks' median {:.2} m over {}", d.track_sigma_median_m, d.tracks_with_sigma)
            } else {
                format!("objects' {:.2} m", d.settings.object_sigma_m)
            };
            println!(
                "with {k}σ of doubt (the ego's σ median {:.2} m over {} poses, {objects}): score {:.2}–{:.2} → {}",
                d.ego_sigma_median_m,
                d.poses_with_sigma,
                d.score_interval[0],
                d.score_interval[1],
                d.decision.name()
            );
        }
        for why in &d.in_doubt {
            println!("  {}: {why}", d.decision.name());
        }
    }
}
