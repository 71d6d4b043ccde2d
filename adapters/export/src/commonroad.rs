//! `dash2sim export LOG --commonroad F.xml --map MAP|OSM [--scenario-seconds S]`: a 4D log
//! and its roads as CommonRoad scenarios (the 2020a XML format, `docs/commonroad.md`), for
//! CommonRoad's planners, drivability checker and criticality measures.
//!
//! * **Lanelets**: the pieces and connectors of [`super::road`] — the lanes nuPlan's map and
//!   `verify` see — with their left and right bounds (neighbours share theirs), predecessors,
//!   successors and same-direction neighbours.
//! * **The ego** as the planning problem (its state at the window's first step, a goal region
//!   around where it is at the last) and as a solution trajectory beside the scenario
//!   (`F.solution.xml`, a kinematic single-track trajectory of the vehicle's centre).
//! * **Objects**: every moving track as a dynamic obstacle (its rectangle, a state per step it
//!   was seen; a track unseen for a step goes on as a new obstacle), every static one (cones,
//!   drums, barriers, signs, parked vehicles) as a static obstacle where it stands.
//!
//! The frame is local and metric: the UTM zone of the map's origin, less the origin's UTM
//! coordinates, which the `location` element carries as the geo-transformation (projected =
//! local + translation). Everything is written under temporary names and renamed at the end.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use dash2sim_core::geo::Geodetic;

use super::partial::Cleanup;
use super::projection::Projection;
use super::request::ScenarioRequest;
use super::road::{road, Connector, Road};
use super::ticks::{
    agents_at_ticks, by_track, on_map, runs, standing, stands_still, windows, AgentTick, EgoTick, OnMap,
};
use dash2sim_core::class::name_of as class_name;
use dash2sim_linux::geometry::{band, is_simple, Line};
use dash2sim_linux::{Error, Result};

/// CommonRoad's time step here: the log's ego poses are at 10 Hz, s.
pub const TIME_STEP_S: f64 = 0.1;
/// A scenario needs at least this many steps (a planning problem and somewhere to go).
const MIN_STEPS: usize = 10;
/// The goal region: a rectangle this long (m) around the ego's last position, as wide as a
/// lane and a half, and the steps around the last one it may be reached in.
const GOAL_LENGTH_M: f64 = 10.0;
const GOAL_WIDTH_M: f64 = 5.0;
const GOAL_STEPS: usize = 10;
/// Ids: lanelets 1…, static obstacles, dynamic obstacles and the planning problem above them.
const OBSTACLE_BASE: usize = 100_000;
const PLANNING_PROBLEM_BASE: usize = 900_000;
/// The ego's wheelbase for its steering angle, m (nuPlan's Pacifica, whose footprint `verify`
/// uses).
const WHEELBASE_M: f64 = 3.089;

/// One scenario written.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The scenario file.
    pub path: PathBuf,
    /// The ego's solution trajectory beside it.
    pub solution: PathBuf,
    /// Its benchmark id.
    pub id: String,
    /// Time steps (the ego's states).
    pub steps: usize,
    /// Dynamic obstacles.
    pub dynamic: usize,
    /// Static obstacles.
    pub r#static: usize,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct CommonRoadExport {
    /// Every scenario, in time order.
    pub scenarios: Vec<Scenario>,
    /// Lanelets in each (the same network).
    pub lanelets: usize,
    /// EPSG code of the projected frame.
    pub epsg: i32,
}

/// Export `request` (its `out` the scenario file `F.xml`; with windows `F-001.xml`, `F-002.xml`,
/// …). Errors name what is wrong; nothing is left behind on an error.
pub fn export(request: &ScenarioRequest<'_>) -> Result<CommonRoadExport> {
    let OnMap { view, map_origin, map_projection, log_projection, ticks } =
        on_map(request.log, request.log_name, request.tile, 1.0 / TIME_STEP_S)?;
    let windows = windows(ticks.len(), request.window_s, TIME_STEP_S, MIN_STEPS, "CommonRoad", request.log_name)?;
    let road = road(&view, &map_projection, -0.01)?;
    // The local frame: the map origin at (0, 0).
    let origin = map_projection.project(&[(0.0, 0.0, 0.0)]).first().copied().unwrap_or_default();
    let agents = agents_at_ticks(request.log, &ticks, &log_projection);
    let lanelets = lanelet_xml(&road, origin);
    let location = location_xml(map_origin, &map_projection, origin);

    let stem = request.out.file_stem().and_then(|s| s.to_str()).unwrap_or("scenario");
    let folder = request.out.parent().unwrap_or(Path::new(""));
    let mut scenarios = Vec::new();
    let mut cleanup = Cleanup(Vec::new());
    let mut written = Vec::new();
    for (k, &(from, to)) in windows.iter().enumerate() {
        let name = if request.window_s.is_some() { format!("{stem}-{:03}", k + 1) } else { stem.to_string() };
        let id = format!("ZAM_Dash2sim-1_{}_T-1", k + 1);
        let path = folder.join(format!("{name}.xml"));
        let solution = folder.join(format!("{name}.solution.xml"));
        let date = dash2sim_linux::utc::iso8601(ticks[from].t_us);
        let window_agents: Vec<&AgentTick> = agents.iter().filter(|a| a.tick >= from && a.tick < to).collect();
        let (obstacles, dynamic, r#static) = obstacles_xml(&window_agents, from, origin);
        let ego = &ticks[from..to];
        let mut xml = format!(
            "<?xml version='1.0' encoding='UTF-8'?>\n<commonRoad timeStepSize=\"{TIME_STEP_S}\" commonRoadVersion=\"2020a\" author=\"dash2sim\" affiliation=\"dash2sim\" source=\"dash2sim export --commonroad: {}\" benchmarkID=\"{id}\" date=\"{}\">\n",
            super::xml_escape(request.log_name),
            &date[..10]
        );
        xml.push_str(&location);
        xml.push_str("  <scenarioTags/>\n");
        xml.push_str(&lanelets);
        xml.push_str(&obstacles);
        xml.push_str(&planning_problem_xml(ego, origin));
        xml.push_str("</commonRoad>\n");
        for (p, text) in [(&path, xml), (&solution, solution_xml(ego, origin, &id, &date))] {
            let partial = p.with_extension("partial");
            cleanup.0.push(partial.clone());
            std::fs::write(&partial, text).map_err(|e| Error::file(&partial, e))?;
            written.push((partial, p.clone()));
        }
        scenarios.push(Scenario { path, solution, id, steps: to - from, dynamic, r#static });
    }
    for (from, to) in &written {
        std::fs::rename(from, to).map_err(|e| Error::file(to, e))?;
    }
    cleanup.0.clear();
    Ok(CommonRoadExport { scenarios, lanelets: road.pieces.len() + road.connectors.len(), epsg: map_projection.epsg() })
}

fn point(out: &mut String, indent: &str, (x, y): (f64, f64), origin: (f64, f64)) {
    let _ = writeln!(out, "{indent}<point><x>{:.3}</x><y>{:.3}</y></point>", x - origin.0, y - origin.1);
}

fn location_xml(map_origin: Geodetic, projection: &Projection, origin: (f64, f64)) -> String {
    let south = if projection.north { "" } else { " +south" };
    format!(
        "  <location>\n    <geoNameId>-999</geoNameId>\n    <gpsLatitude>{:.7}</gpsLatitude>\n    <gpsLongitude>{:.7}</gpsLongitude>\n    <geoTransformation>\n      <geoReference>+proj=utm +zone={}{south} +datum=WGS84 +units=m +no_defs</geoReference>\n      <additionalTransformation>\n        <xTranslation>{:.3}</xTranslation>\n        <yTranslation>{:.3}</yTranslation>\n        <zRotation>0</zRotation>\n        <scaling>1</scaling>\n      </additionalTransformation>\n    </geoTransformation>\n  </location>\n",
        map_origin.lat_deg, map_origin.lon_deg, projection.zone, origin.0, origin.1
    )
}

/// Every piece (ids 1…) and connector (after them) as a lanelet.
fn lanelet_xml(road: &Road, origin: (f64, f64)) -> String {
    let pieces = road.pieces.len();
    let connector_id = |k: usize| pieces + 1 + k;
    let mut out = String::new();
    let mut lanelet = |id: usize,
                       left: &[(f64, f64)],
                       right: &[(f64, f64)],
                       predecessors: &[usize],
                       successors: &[usize],
                       neighbours: (Option<(usize, &str)>, Option<usize>),
                       kind: &str| {
        let _ = writeln!(out, "  <lanelet id=\"{id}\">");
        for (name, bound) in [("leftBound", left), ("rightBound", right)] {
            let _ = writeln!(out, "    <{name}>");
            for &p in bound {
                point(&mut out, "      ", p, origin);
            }
            let _ = writeln!(out, "    </{name}>");
        }
        for p in predecessors {
            let _ = writeln!(out, "    <predecessor ref=\"{p}\"/>");
        }
        for s in successors {
            let _ = writeln!(out, "    <successor ref=\"{s}\"/>");
        }
        if let Some((n, direction)) = neighbours.0 {
            let _ = writeln!(out, "    <adjacentLeft ref=\"{}\" drivingDir=\"{direction}\"/>", n + 1);
        }
        if let Some(n) = neighbours.1 {
            let _ = writeln!(out, "    <adjacentRight ref=\"{}\" drivingDir=\"same\"/>", n + 1);
        }
        let _ = writeln!(out, "    <laneletType>{kind}</laneletType>\n  </lanelet>");
    };
    let opposite = road.opposite_neighbours();
    for (i, piece) in road.pieces.iter().enumerate() {
        let left = piece.left_neighbour.map(|n| (n, "same")).or(opposite[i].map(|n| (n, "opposite")));
        let into: Vec<usize> =
            road.connectors.iter().enumerate().filter(|(_, c)| c.to == i).map(|(k, _)| connector_id(k)).collect();
        let out_of: Vec<usize> =
            road.connectors.iter().enumerate().filter(|(_, c)| c.from == i).map(|(k, _)| connector_id(k)).collect();
        lanelet(i + 1, &piece.left, &piece.right, &into, &out_of, (left, piece.right_neighbour), "unknown");
    }
    for (k, c) in road.connectors.iter().enumerate() {
        let (mut left, mut right) = unfolded(c);
        // A lanelet begins where its predecessor ends, to the point: a hair's gap between the
        // two is a slit in the union of the lanes, and an edge across the road to the
        // drivability checker.
        let (from, to) = (&road.pieces[c.from], &road.pieces[c.to]);
        for (bound, before, after) in [(&mut left, &from.left, &to.left), (&mut right, &from.right, &to.right)] {
            if let (Some(first), Some(&end)) = (bound.first_mut(), before.last()) {
                *first = end;
            }
            if let (Some(last), Some(&start)) = (bound.last_mut(), after.first()) {
                *last = start;
            }
        }
        lanelet(connector_id(k), &left, &right, &[c.from + 1], &[c.to + 1], (None, None), "intersection");
    }
    out
}

/// A connector's bounds, narrowed (by a fifth at a time, down to a fifth of its width) until
/// they do not cross: a turn tighter than half the lane's width folds its band over on the
/// inside, and a lanelet whose bounds cross is not a polygon — the drivability checker's union
/// of the lanes would cut the road open there.
fn unfolded(c: &Connector) -> (Line, Line) {
    let mut half = c.width / 2.0;
    while half > 0.1 * c.width {
        let (ring, left, right) = band(&c.centre, half);
        if is_simple(&ring) {
            return (left, right);
        }
        half *= 0.8;
    }
    let (_, left, right) = band(&c.centre, half);
    (left, right)
}

/// The CommonRoad obstacle type of a dash2sim class.
fn obstacle_type(class: &str, is_static: bool) -> &'static str {
    match class {
        "car" if is_static => "parkedVehicle",
        "car" => "car",
        "truck" => "truck",
        "bus" => "bus",
        "motorcycle" => "motorcycle",
        "bicycle" => "bicycle",
        "pedestrian" => "pedestrian",
        "cone" | "drum" | "barricade" | "barrier" | "sign" | "arrow_board" => "constructionZone",
        _ => "unknown",
    }
}

fn state_xml(out: &mut String, indent: &str, step: usize, a: &AgentTick, origin: (f64, f64), moving: bool) {
    let _ = writeln!(out, "{indent}<time><exact>{step}</exact></time>");
    let _ = writeln!(out, "{indent}<position>");
    point(out, &format!("{indent}  "), (a.x, a.y), origin);
    let _ = writeln!(out, "{indent}</position>");
    let _ = writeln!(out, "{indent}<orientation><exact>{:.6}</exact></orientation>", a.heading);
    if moving {
        // CommonRoad's velocity is along the orientation (signed).
        let (s, c) = a.heading.sin_cos();
        let _ = writeln!(out, "{indent}<velocity><exact>{:.4}</exact></velocity>", c * a.velocity.0 + s * a.velocity.1);
    }
}

/// The window's tracks (`agents`, ticks from `from` on) as obstacles: (XML, dynamic, static).
fn obstacles_xml(agents: &[&AgentTick], from: usize, origin: (f64, f64)) -> (String, usize, usize) {
    let (mut statics, mut dynamics) = (String::new(), String::new());
    let (mut n_static, mut n_dynamic) = (0, 0);
    let mut id = OBSTACLE_BASE;
    for states in by_track(agents).values() {
        let Some(first) = states.first() else { continue };
        let class = class_name(first.track.class);
        let (l, w) = (first.track.l_mm as f64 * 1e-3, first.track.w_mm as f64 * 1e-3);
        let shape = format!(
            "    <shape>\n      <rectangle>\n        <length>{:.3}</length>\n        <width>{:.3}</width>\n      </rectangle>\n    </shape>\n",
            l.max(0.01),
            w.max(0.01)
        );
        if stands_still(states) {
            let at = standing(states);
            id += 1;
            n_static += 1;
            let _ = write!(
                statics,
                "  <staticObstacle id=\"{id}\">\n    <type>{}</type>\n{shape}    <initialState>\n",
                obstacle_type(class, true)
            );
            state_xml(&mut statics, "      ", 0, &at, origin, false);
            statics.push_str("    </initialState>\n  </staticObstacle>\n");
            continue;
        }
        // CommonRoad's trajectories have no gaps: a track missed for up to a second is
        // bridged, a longer gap starts a new obstacle.
        let runs = runs(states);
        for run in runs.iter().filter(|r| r.len() >= 2) {
            id += 1;
            n_dynamic += 1;
            let _ = write!(
                dynamics,
                "  <dynamicObstacle id=\"{id}\">\n    <type>{}</type>\n{shape}    <initialState>\n",
                obstacle_type(class, false)
            );
            state_xml(&mut dynamics, "      ", run[0].tick - from, &run[0], origin, true);
            dynamics.push_str("    </initialState>\n    <trajectory>\n");
            for a in &run[1..] {
                dynamics.push_str("      <state>\n");
                state_xml(&mut dynamics, "        ", a.tick - from, a, origin, true);
                dynamics.push_str("      </state>\n");
            }
            dynamics.push_str("    </trajectory>\n  </dynamicObstacle>\n");
        }
    }
    statics.push_str(&dynamics);
    (statics, n_dynamic, n_static)
}

fn planning_problem_xml(ego: &[EgoTick], origin: (f64, f64)) -> String {
    let mut out = format!("  <planningProblem id=\"{}\">\n    <initialState>\n", PLANNING_PROBLEM_BASE + 1);
    if let (Some(first), Some(last)) = (ego.first(), ego.last()) {
        let _ = writeln!(out, "      <time><exact>0</exact></time>\n      <position>");
        point(&mut out, "        ", first.centre(), origin);
        let _ = writeln!(
            out,
            "      </position>\n      <orientation><exact>{:.6}</exact></orientation>\n      <velocity><exact>{:.4}</exact></velocity>\n      <yawRate><exact>{:.6}</exact></yawRate>\n      <slipAngle><exact>0</exact></slipAngle>\n    </initialState>",
            first.heading, first.velocity.0, first.yaw_rate
        );
        let steps = ego.len() - 1;
        let (x, y) = last.centre();
        let _ = writeln!(
            out,
            "    <goalState>\n      <time><intervalStart>{}</intervalStart><intervalEnd>{}</intervalEnd></time>\n      <position>\n        <rectangle>\n          <length>{GOAL_LENGTH_M}</length>\n          <width>{GOAL_WIDTH_M}</width>\n          <orientation>{:.6}</orientation>\n          <center><x>{:.3}</x><y>{:.3}</y></center>\n        </rectangle>\n      </position>\n    </goalState>",
            steps.saturating_sub(GOAL_STEPS).max(1),
            steps + GOAL_STEPS,
            last.heading,
            x - origin.0,
            y - origin.1
        );
    }
    out.push_str("  </planningProblem>\n");
    out
}

/// The ego's states as a CommonRoad solution: a kinematic single-track trajectory of its
/// centre (where CommonRoad's collision checks put the vehicle's rectangle), the steering
/// angle from the yaw rate (δ = atan(wheelbase · ω / v)).
fn solution_xml(ego: &[EgoTick], origin: (f64, f64), id: &str, date: &str) -> String {
    let mut out = format!(
        "<?xml version=\"1.0\" ?>\n<CommonRoadSolution benchmark_id=\"KS2:SM1:{id}:2020a\" date=\"{}\">\n  <ksTrajectory planningProblem=\"{}\">\n",
        &date[..19],
        PLANNING_PROBLEM_BASE + 1
    );
    for (k, t) in ego.iter().enumerate() {
        let (x, y) = t.centre();
        let speed = t.velocity.0;
        let steering = if speed.abs() > 0.5 { (WHEELBASE_M * t.yaw_rate / speed).atan() } else { 0.0 };
        let _ = writeln!(
            out,
            "    <ksState><x>{:.3}</x><y>{:.3}</y><steeringAngle>{steering:.5}</steeringAngle><velocity>{speed:.4}</velocity><orientation>{:.6}</orientation><time>{k}</time></ksState>",
            x - origin.0,
            y - origin.1,
            t.heading
        );
    }
    out.push_str("  </ksTrajectory>\n</CommonRoadSolution>\n");
    out
}
