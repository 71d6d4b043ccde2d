//! Verdicts that carry the log's uncertainty: nuPlan's score as `verify` computes it, and
//! beside it the same drive scored twice more — once giving the ego the benefit of `k` of its
//! stated σ, once holding that doubt against it (`dash2sim_core::score::Doubt`). The two
//! bound the score for an ego moved sideways within its doubt (its speed and path shape as
//! logged) and objects anywhere within theirs; the log is **verified** when even the worst
//! of them verifies, **rejected** when even the best does not, and **undecided** otherwise:
//! the evidence cannot tell, and a fleet sends such a log for anchoring rather than throw a
//! good drive away. How it is computed, and what it leaves out: `docs/verify.md`.

use serde::Serialize;

use dash2sim_core::obb::OrientedBox;
use dash2sim_core::score::{Agent, AgentKind, Scores, HOLE_S};

use super::StatedUncertainty;

/// Default `--decide-at`: the doubt is this many of the stated σ.
pub const DEFAULT_DECIDE_AT: f64 = 2.0;

/// Default σ of the place relative to the ego of an object whose log states none, m (along
/// one axis): none. `verify` does not invent one — an object's place relative to the ego is
/// the camera's measurement (the ego's own error moves it with the ego), and `finish` states
/// it for every track it keeps (`TrackCovariance`); a device's log or an objects file states
/// none, and `--object-sigma` gives them one.
pub const DEFAULT_OBJECT_SIGMA_M: f64 = 0.0;

/// How much doubt a verdict allows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DoubtSettings {
    /// The doubt is this many σ (`--decide-at K`).
    pub decide_at: f64,
    /// σ of the place relative to the ego of each object whose log states none, m along
    /// one axis (`--object-sigma`).
    pub object_sigma_m: f64,
}

/// How far an object's place is in doubt, m on every side of its box: `k` σ across the
/// path of an ego heading `heading` (rad) — how far it could stand nearer the ego's path or
/// further from it — of the covariance its log states (`stated`: xx, xy, yy, m²) or, where
/// it states none, `--object-sigma`. Along the path a place in doubt moves where the ego
/// passes it, not how near.
pub fn object_doubt(settings: DoubtSettings, stated: Option<&[f64; 3]>, heading: f64) -> f64 {
    let sigma = match stated {
        Some([xx, xy, yy]) => {
            let (nx, ny) = (-heading.sin(), heading.cos());
            (xx * nx * nx + 2.0 * xy * nx * ny + yy * ny * ny).max(0.0).sqrt()
        }
        None => settings.object_sigma_m,
    };
    if sigma.is_finite() {
        settings.decide_at * sigma
    } else {
        0.0
    }
}

impl Default for DoubtSettings {
    fn default() -> Self {
        DoubtSettings { decide_at: DEFAULT_DECIDE_AT, object_sigma_m: DEFAULT_OBJECT_SIGMA_M }
    }
}

pub use dash2sim_core::score::Decision;

/// The decision and the score's interval of `decided`; without one (no doubt was asked
/// for), nuPlan's verdict of `score` and the point itself.
pub fn decision_or_point(decided: Option<&Decided>, score: f64) -> (Decision, [f64; 2]) {
    decided.map_or((Decision::of_interval(score, score), [score; 2]), |d| (d.decision, d.score_interval))
}

/// A verdict with its doubt.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Decided {
    /// Verified, rejected or undecided.
    pub decision: Decision,
    /// The least and the greatest score within the doubt (the point score lies between).
    pub score_interval: [f64; 2],
    /// The doubt: its σ multiple and the objects' σ.
    pub settings: DoubtSettings,
    /// The ego's stated horizontal σ: median over the poses, m (0 when the source states
    /// none, a TUM trajectory: then the verdict is decided as nuPlan's).
    pub ego_sigma_median_m: f64,
    /// Poses whose σ the log states.
    pub poses_with_sigma: u32,
    /// The tracks' stated horizontal σ (DRMS, of the covariance the log states): median
    /// over the tracks that state one, m (0 with none).
    pub track_sigma_median_m: f64,
    /// Tracks whose covariance the log states (`TrackCovariance`).
    pub tracks_with_sigma: u32,
    /// Each metric whose outcome could flip within the doubt, explained in words.
    pub in_doubt: Vec<String>,
    /// Stretches with no ego pose longer than [`HOLE_S`] (a VO session `finish` could not anchor) (from, to; s): what the ego did
    /// there is not in the log, so the verdict cannot vouch for it ([`decided`]).
    pub holes: Vec<[f64; 2]>,
}

/// The holes of `times` (increasing, s): each gap longer than [`HOLE_S`], the core's.
pub fn holes(times: impl Iterator<Item = f64>) -> Vec<[f64; 2]> {
    let mut previous: Option<f64> = None;
    let mut out = Vec::new();
    for t in times {
        if let Some(p) = previous.filter(|p| t - p > HOLE_S) {
            out.push([p, t]);
        }
        previous = Some(t);
    }
    out
}

/// Where the doubt held against the ego first took it off the drivable area.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OffRoadInDoubt {
    /// The pose's time, s.
    pub t: f64,
    /// Its worst corner, m outside (≤ 0: inside).
    pub worst_corner_m: f64,
    /// The ego's doubt there, m (k σ).
    pub ego_doubt_m: f64,
}

/// The pass nearest a collision once each object's doubt is held against the ego: the least
/// gap between the ego's footprint and an object's box grown by its doubt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestPass {
    /// The pose's time, s.
    pub t: f64,
    /// The object's track id.
    pub id: u32,
    /// What it is.
    pub kind: AgentKind,
    /// The gap between its box as placed and the ego's footprint, m (0: they overlap).
    pub gap_m: f64,
    /// The same with its box grown by its doubt, m.
    pub gap_in_doubt_m: f64,
    /// Its doubt there, m on every side ([`object_doubt`]).
    pub doubt_m: f64,
}

impl NearestPass {
    /// Boxes further apart than this (centre to centre, m) are never the nearest pass.
    const WITHIN_M: f64 = 15.0;

    /// The pass of `agent` at `t` by the ego's footprint `ego`, its doubt `doubt_m` (none
    /// when they are far apart).
    pub fn of(t: f64, ego: &OrientedBox, agent: &Agent, doubt_m: f64) -> Option<Self> {
        let a = &agent.bbox;
        if (a.centre.x - ego.centre.x).hypot(a.centre.y - ego.centre.y) > Self::WITHIN_M {
            return None;
        }
        let gap = |b: &OrientedBox| {
            if b.overlaps(ego) {
                0.0
            } else {
                dash2sim_linux::geometry::convex_gap(&b.corners(), &ego.corners())
            }
        };
        Some(NearestPass {
            t,
            id: agent.id,
            kind: agent.kind,
            gap_m: gap(a),
            gap_in_doubt_m: gap(&agent.grown(doubt_m).bbox),
            doubt_m,
        })
    }

    /// Whether this pass is nearer a collision than `other`: in doubt, then as placed.
    pub fn nearer_than(&self, other: &NearestPass) -> bool {
        (self.gap_in_doubt_m, self.gap_m) < (other.gap_in_doubt_m, other.gap_m)
    }

    /// In words: "track 45 (an object) 0.31 m clear of the ego at t = … s, 0.02 m with its
    /// place ± 0.28 m (2σ)".
    fn words(&self, k: f64) -> String {
        let kind = match self.kind {
            AgentKind::Object => "an object",
            AgentKind::Vehicle => "a vehicle",
            AgentKind::Vru => "a pedestrian or cyclist",
        };
        format!(
            "the nearest pass: track {} ({kind}) {:.2} m clear of the ego at t = {:.2} s, {:.2} m with its place ± {:.2} m ({k}σ)",
            self.id, self.gap_m, self.t, self.gap_in_doubt_m, self.doubt_m
        )
    }
}

/// The decision over a replay scored at its point (`point`), with the doubt for the ego
/// (`lenient`) and against it (`strict`); `off_road` is where the doubt held against it
/// first took it off the drivable area, `nearest` its nearest pass of an object (for the
/// words). A log with `holes` is never verified: anything may have happened in them, so
/// the score's interval reaches down to 0 and the verdict is at best undecided.
#[allow(clippy::too_many_arguments)] // each is one piece of evidence; a struct would only rename them
pub fn decided(
    point: &Scores,
    lenient: &Scores,
    strict: &Scores,
    settings: DoubtSettings,
    sigmas: &StatedUncertainty,
    off_road: OffRoadInDoubt,
    nearest: Option<NearestPass>,
    holes: Vec<[f64; 2]>,
) -> Decided {
    let low = if holes.is_empty() { point.score.min(strict.score).min(lenient.score) } else { 0.0 };
    let high = point.score.max(strict.score).max(lenient.score);
    let (median, poses_with_sigma) = median_stated(sigmas.ego.iter().copied());
    let (track_median, tracks_with_sigma) = median_stated(sigmas.tracks.values().map(|c| (c[0] + c[2]).sqrt()));
    let k = settings.decide_at;
    let each = if tracks_with_sigma > 0 {
        format!("by {k}σ of its stated place across the ego's path (the tracks' σ median {track_median:.2} m)")
    } else {
        format!("by {:.2} m on every side", k * settings.object_sigma_m)
    };
    // The ego's doubt along one axis at its median σ (the log's σ is DRMS, both axes).
    let ego_median_doubt = k * median / core::f64::consts::SQRT_2;
    let mut in_doubt = Vec::new();
    let flips = |m: fn(&Scores) -> f64| m(strict) != m(lenient);
    let pass = nearest.map_or_else(String::new, |n| format!("; {}", n.words(k)));
    if flips(|s| s.drivable_area) {
        let corner = if off_road.worst_corner_m > 0.0 {
            format!("{:.2} m outside", off_road.worst_corner_m)
        } else {
            format!("{:.2} m inside", -off_road.worst_corner_m)
        };
        in_doubt.push(format!(
            "drivable area: at t = {:.2} s a corner is {corner} the drivable area (nuPlan allows 0.30 m outside) and the ego's position is ± {:.2} m ({k}σ)",
            off_road.t,
            off_road.ego_doubt_m
        ));
    }
    if flips(|s| s.no_at_fault_collisions) {
        in_doubt.push(format!(
            "collisions: {} at fault as the objects are placed, {} with each larger {each}, {} with each as much smaller{pass}",
            point.collisions.0 + point.collisions.1,
            strict.collisions.0 + strict.collisions.1,
            lenient.collisions.0 + lenient.collisions.1,
        ));
    }
    if flips(|s| s.ttc) {
        let secs = |s: &Scores| if s.min_ttc.is_finite() { format!("{:.2} s", s.min_ttc) } else { "none".to_owned() };
        in_doubt.push(format!(
            "time to collision: least {} (nuPlan fails at ≤ 0.95 s), {} with each object larger {each}, {} with each as much smaller{pass}",
            secs(point),
            secs(strict),
            secs(lenient)
        ));
    }
    if flips(|s| s.driving_direction) {
        in_doubt.push(format!(
            "driving direction: {:.1} m against the lane's direction within a second (nuPlan: 2 m halves the metric, 6 m fails it), {:.1} m taking the nearest lane headed the ego's way within {:.2} m",
            -point.min_direction_progress,
            -lenient.min_direction_progress,
            ego_median_doubt
        ));
    }
    if flips(|s| s.speed_limit) {
        in_doubt.push(format!(
            "speed limit: {:.1} m over the limit (integrated) in the lanes the ego is in, {:.1} m in the nearest lanes headed its way within {:.2} m",
            strict.overspeed_integral,
            lenient.overspeed_integral,
            ego_median_doubt
        ));
    }
    if let (Some(first), Some(last)) = (holes.first(), holes.last()) {
        let seconds: f64 = holes.iter().map(|[a, b]| b - a).sum();
        let more = if holes.len() > 1 {
            format!(" and {} more, {seconds:.1} s in all, the last to t = {:.2} s", holes.len() - 1, last[1])
        } else {
            String::new()
        };
        in_doubt.push(format!(
            "a hole in the log: no ego pose from t = {:.2} s to {:.2} s ({:.1} s{more}); what the ego did there is not in the log, so it cannot be verified",
            first[0],
            first[1],
            first[1] - first[0]
        ));
    }
    Decided {
        decision: Decision::of_interval(low, high),
        score_interval: [low, high],
        settings,
        ego_sigma_median_m: median,
        poses_with_sigma,
        track_sigma_median_m: track_median,
        tracks_with_sigma,
        in_doubt,
        holes,
    }
}

/// The median of the stated (finite, > 0) σ of `sigmas`, and how many there are.
fn median_stated(sigmas: impl Iterator<Item = f64>) -> (f64, u32) {
    let mut stated: Vec<f64> = sigmas.filter(|s| s.is_finite() && *s > 0.0).collect();
    stated.sort_by(f64::total_cmp);
    (stated.get(stated.len() / 2).copied().unwrap_or(0.0), u32::try_from(stated.len()).unwrap_or(u32::MAX))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interval_decides_only_when_all_of_it_is_on_one_side_of_ninety() {
        assert_eq!(Decision::of_interval(90.5, 100.0), Decision::Verified);
        assert_eq!(Decision::of_interval(50.0, 90.0), Decision::Rejected);
        assert_eq!(Decision::of_interval(0.0, 100.0), Decision::Undecided);
        assert_eq!(Decision::of_interval(90.0, 90.0), Decision::Rejected, "nuPlan verifies above 90, not at it");
    }

    /// A place known to 0.1 m across the road and 0.5 m along it: an ego heading along the
    /// road passes it with 2 × 0.1 m of doubt, one crossing the road meets 2 × 0.5 m; an
    /// object that states nothing has `--object-sigma`'s.
    #[test]
    fn an_objects_doubt_is_its_place_across_the_egos_path() {
        let settings = DoubtSettings { decide_at: 2.0, object_sigma_m: 0.05 };
        // The road runs north-east (45°): its covariance in east and north.
        let (along, across) = (0.5f64 * 0.5, 0.1f64 * 0.1);
        let place = [(along + across) / 2.0, (along - across) / 2.0, (along + across) / 2.0];
        let north_east = std::f64::consts::FRAC_PI_4;
        assert!((object_doubt(settings, Some(&place), north_east) - 0.2).abs() < 1e-12);
        assert!((object_doubt(settings, Some(&place), north_east + std::f64::consts::PI) - 0.2).abs() < 1e-12);
        assert!((object_doubt(settings, Some(&place), -north_east) - 1.0).abs() < 1e-12);
        assert_eq!(object_doubt(settings, None, 0.0), 0.1);
        assert_eq!(object_doubt(settings, Some(&[f64::NAN; 3]), 0.0), 0.0, "not finite: none");
    }
}
