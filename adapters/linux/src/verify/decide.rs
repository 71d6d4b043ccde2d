//! Verdicts that carry the log's uncertainty: nuPlan's score as `verify` computes it, and
//! beside it the same drive scored twice more — once giving the ego the benefit of `k` of its
//! stated σ, once holding that doubt against it (`dash2sim_core::score::Doubt`). The two
//! bound the score for an ego moved sideways within its doubt (its speed and path shape as
//! logged) and objects anywhere within theirs; the log is **verified** when even the worst
//! of them verifies, **rejected** when even the best does not, and **undecided** otherwise:
//! the evidence cannot tell, and a fleet sends such a log for anchoring rather than throw a
//! good drive away. How it is computed, and what it leaves out: `docs/verify.md`.

use serde::Serialize;

use dash2sim_core::score::{Scores, VERIFIED_ABOVE};

/// Default `--decide-at`: the doubt is this many of the stated σ.
pub const DEFAULT_DECIDE_AT: f64 = 2.0;

/// Default σ of an object's place relative to the ego, m: none. A log's 3D tracks state no
/// σ, and `verify` does not invent one: by default the decision carries the ego's stated σ
/// alone (an object's place relative to the ego is the camera's measurement; the ego's own
/// error moves it with the ego). `--object-sigma` states one.
pub const DEFAULT_OBJECT_SIGMA_M: f64 = 0.0;

/// How much doubt a verdict allows.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DoubtSettings {
    /// The doubt is this many σ (`--decide-at K`).
    pub decide_at: f64,
    /// σ of each object's place relative to the ego, m (`--object-sigma`).
    pub object_sigma_m: f64,
}

impl Default for DoubtSettings {
    fn default() -> Self {
        DoubtSettings { decide_at: DEFAULT_DECIDE_AT, object_sigma_m: DEFAULT_OBJECT_SIGMA_M }
    }
}

/// What the evidence decides.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Decision {
    /// Verified anywhere within the doubt.
    Verified,
    /// Rejected anywhere within the doubt.
    Rejected,
    /// Verified somewhere within it and rejected elsewhere.
    Undecided,
}

impl Decision {
    /// Its name, as the JSON and the text say it.
    pub fn name(self) -> &'static str {
        match self {
            Decision::Verified => "verified",
            Decision::Rejected => "rejected",
            Decision::Undecided => "undecided",
        }
    }

    /// The decision of a score interval: verified when all of it is above nuPlan's 90,
    /// rejected when none of it is.
    pub fn of_interval(low: f64, high: f64) -> Self {
        if low > VERIFIED_ABOVE {
            Decision::Verified
        } else if high > VERIFIED_ABOVE {
            Decision::Undecided
        } else {
            Decision::Rejected
        }
    }
}

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
    /// Each metric whose outcome could flip within the doubt, explained in words.
    pub in_doubt: Vec<String>,
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

/// The decision over a replay scored at its point (`point`), with the doubt for the ego
/// (`lenient`) and against it (`strict`); `off_road` is where the doubt held against it
/// first took it off the drivable area (for the words).
pub fn decided(
    point: &Scores,
    lenient: &Scores,
    strict: &Scores,
    settings: DoubtSettings,
    sigmas: &[f64],
    off_road: OffRoadInDoubt,
) -> Decided {
    let low = point.score.min(strict.score).min(lenient.score);
    let high = point.score.max(strict.score).max(lenient.score);
    let mut stated: Vec<f64> = sigmas.iter().copied().filter(|s| s.is_finite() && *s > 0.0).collect();
    stated.sort_by(f64::total_cmp);
    let median = stated.get(stated.len() / 2).copied().unwrap_or(0.0);
    let k = settings.decide_at;
    let object = k * settings.object_sigma_m;
    // The ego's doubt along one axis at its median σ (the log's σ is DRMS, both axes).
    let ego_median_doubt = k * median / core::f64::consts::SQRT_2;
    let mut in_doubt = Vec::new();
    let flips = |m: fn(&Scores) -> f64| m(strict) != m(lenient);
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
            "collisions: {} at fault as the objects are placed, {} with each {object:.2} m larger on every side, {} with each {object:.2} m smaller (an object's place relative to the ego ± {object:.2} m, {k}σ)",
            point.collisions.0 + point.collisions.1,
            strict.collisions.0 + strict.collisions.1,
            lenient.collisions.0 + lenient.collisions.1,
        ));
    }
    if flips(|s| s.ttc) {
        let secs = |s: &Scores| if s.min_ttc.is_finite() { format!("{:.2} s", s.min_ttc) } else { "none".to_owned() };
        in_doubt.push(format!(
            "time to collision: least {} (nuPlan fails at ≤ 0.95 s), {} with the objects {object:.2} m larger, {} with them {object:.2} m smaller",
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
    Decided {
        decision: Decision::of_interval(low, high),
        score_interval: [low, high],
        settings,
        ego_sigma_median_m: median,
        poses_with_sigma: u32::try_from(stated.len()).unwrap_or(u32::MAX),
        in_doubt,
    }
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
}
