//! `dash2sim export LOG --openscenario DIR --map MAP|OSM [--scenario-seconds S]`: a 4D log as
//! ASAM OpenSCENARIO XML 1.0 scenarios on an OpenDRIVE road (`docs/openscenario.md`), for
//! CARLA's ScenarioRunner, esmini and the ASAM tool chain.
//!
//! * `DIR/road.xodr`: the map tile's roads ([`super::opendrive`]), which every scenario names
//!   as its road network.
//! * `DIR/scenario.xosc` (with windows `scenario-001.xosc`, …): the ego (`Ego`, a car with
//!   nuPlan's Pacifica footprint, its reference point the rear axle as OpenSCENARIO has it)
//!   and every track as an entity of its class and size. Each moving one follows its
//!   recorded trajectory (`FollowTrajectoryAction`: a polyline of timed world positions at
//!   10 Hz, absolute time from the window's start, following the positions exactly); one
//!   seen only part of the window is invisible until it appears and after it is lost. Static
//!   objects (cones, drums, barriers, signs, parked cars) stand where they were seen. The
//!   scenario stops at the window's end.
//!
//! Positions are in the `.xodr`'s frame (UTM less the map origin). The roads are flat, so the
//! entities stand at height 0. Everything is written under temporary names and renamed at
//! the end: a refused input leaves nothing behind.

use std::fmt::Write as _;
use std::path::PathBuf;

use dash2sim_core::class;
use dash2sim_core::obb::PACIFICA;
use dash2sim_core::score::AgentKind;

use super::opendrive::{opendrive, OpenDrive};
use super::partial::Cleanup;
use super::request::ScenarioRequest;
use super::road::road;
use super::ticks::{agents_at_ticks, by_track, on_map, runs, standing, stands_still, windows, AgentTick, OnMap};
use dash2sim_linux::{Error, Result};

/// The trajectories' step: the log's ego poses are at 10 Hz, s.
pub const TIME_STEP_S: f64 = 0.1;
/// A scenario needs at least this many steps.
const MIN_STEPS: usize = 10;
/// The road file's name in the output folder.
pub const ROAD_FILE: &str = "road.xodr";
/// The ego's wheelbase (nuPlan's Pacifica), m.
const WHEELBASE_M: f64 = 3.089;
/// The ego's height (nuPlan's Pacifica, whose footprint `verify` uses; the footprint has
/// no height), m.
const PACIFICA_HEIGHT_M: f64 = 1.777;
/// A tracked vehicle's rear axle behind its box's centre, as a fraction of its length (the
/// Pacifica's: 1.461 m of 5.176 m). A track's box is what the camera measures; OpenSCENARIO
/// places a vehicle by its rear axle.
const REAR_AXLE_BEHIND_CENTRE: f64 = 0.28;
/// A tracked vehicle's wheelbase as a fraction of its length (the Pacifica's: 0.597).
const WHEELBASE_OF_LENGTH: f64 = 0.6;

/// One scenario written.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The `.xosc` file.
    pub path: PathBuf,
    /// Entities (the ego's included).
    pub entities: usize,
    /// Of which follow a trajectory (the ego's included).
    pub moving: usize,
    /// Steps of the ego's trajectory.
    pub steps: usize,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct OpenScenarioExport {
    /// Every scenario, in time order.
    pub scenarios: Vec<Scenario>,
    /// The road file.
    pub road: PathBuf,
    /// What the road file holds.
    pub opendrive: OpenDrive,
}

/// Export `request` (its `out` a folder, made if missing), the road named `road_name` (the
/// map's file name, as `map export` names it). Errors name what is wrong; nothing is left
/// behind on an error.
pub fn export(request: &ScenarioRequest<'_>, road_name: &str) -> Result<OpenScenarioExport> {
    let OnMap { view, map_projection, log_projection, ticks, .. } =
        on_map(request.log, request.log_name, request.tile, 1.0 / TIME_STEP_S)?;
    let windows = windows(ticks.len(), request.window_s, TIME_STEP_S, MIN_STEPS, "OpenSCENARIO", request.log_name)?;
    let network = road(&view, &map_projection, 0.0)?;
    let drive = opendrive(&network, &map_projection, road_name)?;
    let origin = drive.offset;
    let agents = agents_at_ticks(request.log, &ticks, &log_projection);
    std::fs::create_dir_all(request.out).map_err(|e| Error::file(request.out, e))?;

    let mut cleanup = Cleanup(Vec::new());
    let mut written = Vec::new();
    let mut stage = |path: PathBuf, text: &str| -> Result<()> {
        let partial = path.with_extension("partial");
        cleanup.0.push(partial.clone());
        std::fs::write(&partial, text).map_err(|e| Error::file(&partial, e))?;
        written.push((partial, path));
        Ok(())
    };
    let road_path = request.out.join(ROAD_FILE);
    stage(road_path.clone(), &drive.xodr)?;
    let mut scenarios = Vec::new();
    for (k, &(from, to)) in windows.iter().enumerate() {
        let name = if request.window_s.is_some() { format!("scenario-{:03}", k + 1) } else { "scenario".to_string() };
        let path = request.out.join(format!("{name}.xosc"));
        let date = dash2sim_linux::utc::iso8601(ticks[from].t_us);
        let mut entities = vec![Entity::ego(
            ticks[from..to].iter().enumerate().map(|(i, t)| Vertex::at(i, t.x, t.y, t.heading, origin)).collect(),
        )];
        let window: Vec<&AgentTick> = agents.iter().filter(|a| a.tick >= from && a.tick < to).collect();
        entities.extend(track_entities(&window, from, origin));
        let header = Header {
            description: format!("{} {name}", request.log_name),
            date: date[..19].to_string(),
            start_us: ticks[from].t_us,
        };
        let text = scenario_xml(&entities, &header, to - from);
        stage(path.clone(), &text)?;
        scenarios.push(Scenario {
            path,
            entities: entities.len(),
            moving: entities.iter().filter(|e| e.path.len() >= 2).count(),
            steps: to - from,
        });
    }
    for (from, to) in &written {
        std::fs::rename(from, to).map_err(|e| Error::file(to, e))?;
    }
    cleanup.0.clear();
    Ok(OpenScenarioExport { scenarios, road: road_path, opendrive: drive })
}

/// A timed world position: seconds from the window's start, the reference point in the
/// `.xodr`'s frame, the heading.
#[derive(Clone, Copy, Debug)]
struct Vertex {
    time: f64,
    x: f64,
    y: f64,
    heading: f64,
}

impl Vertex {
    fn at(step: usize, x: f64, y: f64, heading: f64, origin: (f64, f64)) -> Self {
        Vertex { time: step as f64 * TIME_STEP_S, x: x - origin.0, y: y - origin.1, heading }
    }

    fn xml(&self) -> String {
        format!("<WorldPosition x=\"{:.3}\" y=\"{:.3}\" z=\"0\" h=\"{:.6}\"/>", self.x, self.y, self.heading)
    }
}

/// What OpenSCENARIO calls an entity: its kind and category, its box relative to its
/// reference point, where it is.
#[derive(Clone, Debug)]
struct Entity {
    name: String,
    kind: Kind,
    /// Length, width, height, m.
    size: (f64, f64, f64),
    /// The box's centre ahead of the reference point, m.
    centre_ahead: f64,
    /// Its path: one vertex stands, two or more move.
    path: Vec<Vertex>,
    /// It is there from the window's start to its end; otherwise it is shown only between
    /// its first and last vertex.
    always: bool,
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Ego,
    Vehicle(&'static str),
    Pedestrian,
    Misc(&'static str),
}

impl Entity {
    fn ego(path: Vec<Vertex>) -> Self {
        let length = PACIFICA.front + PACIFICA.rear;
        Entity {
            name: "Ego".to_string(),
            kind: Kind::Ego,
            size: (length, PACIFICA.width, PACIFICA_HEIGHT_M),
            centre_ahead: 0.5 * (PACIFICA.front - PACIFICA.rear),
            path,
            always: true,
        }
    }
}

/// OpenSCENARIO's kind and category of a class code.
fn kind_of(code: i64) -> Kind {
    match class::by_code(code) {
        Some(c) if c.kind == AgentKind::Vehicle => Kind::Vehicle(match c.name {
            "truck" => "truck",
            "bus" => "bus",
            "motorcycle" => "motorbike",
            _ => "car",
        }),
        Some(c) if c.name == "bicycle" => Kind::Vehicle("bicycle"),
        Some(c) if c.name == "pedestrian" => Kind::Pedestrian,
        Some(c) if c.name == "barrier" || c.name == "barricade" => Kind::Misc("barrier"),
        Some(c) if c.name == "sign" => Kind::Misc("pole"),
        Some(_) => Kind::Misc("obstacle"),
        None => Kind::Misc("none"),
    }
}

/// The window's tracks (`agents`, ticks from `from` on) as entities: one per static track,
/// one per gapless run of a moving one ([`runs`]).
fn track_entities(agents: &[&AgentTick], from: usize, origin: (f64, f64)) -> Vec<Entity> {
    let mut out = Vec::new();
    for (id, states) in by_track(agents) {
        let Some(first) = states.first() else { continue };
        let class_name = class::name_of(first.track.class);
        let kind = kind_of(first.track.class);
        let size = (first.track.l_mm as f64 * 1e-3, first.track.w_mm as f64 * 1e-3, first.track.h_mm as f64 * 1e-3);
        let size = (size.0.max(0.01), size.1.max(0.01), size.2.max(0.01));
        // A vehicle's reference point is its rear axle; anything else's, its box's centre.
        let centre_ahead = if matches!(kind, Kind::Vehicle(_)) { REAR_AXLE_BEHIND_CENTRE * size.0 } else { 0.0 };
        let vertex = |a: &AgentTick| {
            let (s, c) = a.heading.sin_cos();
            Vertex::at(a.tick - from, a.x - centre_ahead * c, a.y - centre_ahead * s, a.heading, origin)
        };
        if stands_still(&states) {
            let at = standing(&states);
            out.push(Entity {
                name: format!("{class_name}-{id}"),
                kind,
                size,
                centre_ahead,
                path: vec![vertex(&at)],
                always: true,
            });
            continue;
        }
        for (k, run) in runs(&states).iter().filter(|r| r.len() >= 2).enumerate() {
            let name = if k == 0 { format!("{class_name}-{id}") } else { format!("{class_name}-{id}-{}", k + 1) };
            out.push(Entity { name, kind, size, centre_ahead, path: run.iter().map(vertex).collect(), always: false });
        }
    }
    out
}

/// The `<ScenarioObject>` of `e`.
fn entity_xml(x: &mut String, e: &Entity) {
    let (l, w, h) = e.size;
    let bounding_box = format!(
        "<BoundingBox><Center x=\"{:.3}\" y=\"0\" z=\"{:.3}\"/><Dimensions width=\"{w:.3}\" length=\"{l:.3}\" height=\"{h:.3}\"/></BoundingBox>",
        e.centre_ahead,
        0.5 * h
    );
    let _ = writeln!(x, "    <ScenarioObject name=\"{}\">", e.name);
    match e.kind {
        Kind::Ego | Kind::Vehicle(_) => {
            let (category, wheelbase, role) = match e.kind {
                Kind::Vehicle(c) => (c, WHEELBASE_OF_LENGTH * l, "simulation"),
                _ => ("car", WHEELBASE_M, "ego_vehicle"),
            };
            let _ = writeln!(
                x,
                "      <Vehicle name=\"{}\" vehicleCategory=\"{category}\">\n        {bounding_box}\n        <Performance maxSpeed=\"70\" maxAcceleration=\"10\" maxDeceleration=\"10\"/>\n        <Axles>\n          <FrontAxle maxSteering=\"0.5\" wheelDiameter=\"0.7\" trackWidth=\"{:.3}\" positionX=\"{wheelbase:.3}\" positionZ=\"0.35\"/>\n          <RearAxle maxSteering=\"0\" wheelDiameter=\"0.7\" trackWidth=\"{:.3}\" positionX=\"0\" positionZ=\"0.35\"/>\n        </Axles>\n        <Properties>\n          <Property name=\"type\" value=\"{role}\"/>\n        </Properties>\n      </Vehicle>",
                e.name,
                (w - 0.3).max(0.1),
                (w - 0.3).max(0.1)
            );
        }
        Kind::Pedestrian => {
            let _ = writeln!(
                x,
                "      <Pedestrian name=\"{}\" model=\"pedestrian\" mass=\"80\" pedestrianCategory=\"pedestrian\">\n        {bounding_box}\n        <Properties/>\n      </Pedestrian>",
                e.name
            );
        }
        Kind::Misc(category) => {
            let _ = writeln!(
                x,
                "      <MiscObject name=\"{}\" mass=\"10\" miscObjectCategory=\"{category}\">\n        {bounding_box}\n        <Properties/>\n      </MiscObject>",
                e.name
            );
        }
    }
    x.push_str("    </ScenarioObject>\n");
}

/// A trigger that fires once the simulation time passes `seconds`.
fn time_trigger(kind: &str, name: &str, seconds: f64) -> String {
    format!(
        "<{kind}><ConditionGroup><Condition name=\"{name}\" delay=\"0\" conditionEdge=\"rising\"><ByValueCondition><SimulationTimeCondition value=\"{seconds:.3}\" rule=\"greaterThan\"/></ByValueCondition></Condition></ConditionGroup></{kind}>"
    )
}

fn visibility(visible: bool) -> String {
    format!("<VisibilityAction graphics=\"{visible}\" traffic=\"{visible}\" sensors=\"{visible}\"/>")
}

/// What a scenario says of itself: a description, its date, and where in the log it starts.
struct Header {
    description: String,
    /// ISO 8601, to the second.
    date: String,
    /// The log's time at the scenario's time 0, µs.
    start_us: i64,
}

/// The whole `.xosc`: `entities` over `steps` of the window. The log's time at the
/// scenario's start is its parameter `log_start_s` (seconds, as the log counts them), so that
/// a reader can lay the scenario over the log.
fn scenario_xml(entities: &[Entity], header: &Header, steps: usize) -> String {
    let mut x = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<OpenSCENARIO>\n  <FileHeader revMajor=\"1\" revMinor=\"0\" date=\"{}\" description=\"{}\" author=\"dash2sim\"/>\n  <ParameterDeclarations>\n    <ParameterDeclaration name=\"log_start_s\" parameterType=\"double\" value=\"{}{}.{:06}\"/>\n  </ParameterDeclarations>\n  <CatalogLocations/>\n  <RoadNetwork>\n    <LogicFile filepath=\"{ROAD_FILE}\"/>\n  </RoadNetwork>\n  <Entities>\n",
        header.date,
        super::xml_escape(&header.description),
        if header.start_us < 0 { "-" } else { "" },
        header.start_us.unsigned_abs() / 1_000_000,
        header.start_us.unsigned_abs() % 1_000_000
    );
    for e in entities {
        entity_xml(&mut x, e);
    }
    x.push_str("  </Entities>\n  <Storyboard>\n    <Init>\n      <Actions>\n");
    for e in entities {
        let Some(first) = e.path.first() else { continue };
        let _ = writeln!(
            x,
            "        <Private entityRef=\"{}\">\n          <PrivateAction><TeleportAction><Position>{}</Position></TeleportAction></PrivateAction>",
            e.name,
            first.xml()
        );
        if !e.always && first.time > 0.0 {
            let _ = writeln!(x, "          <PrivateAction>{}</PrivateAction>", visibility(false));
        }
        x.push_str("        </Private>\n");
    }
    x.push_str("      </Actions>\n    </Init>\n    <Story name=\"log\">\n      <Act name=\"replay\">\n");
    let end = steps.saturating_sub(1) as f64 * TIME_STEP_S;
    for e in entities.iter().filter(|e| e.path.len() >= 2) {
        let _ = writeln!(
            x,
            "        <ManeuverGroup name=\"{0}\" maximumExecutionCount=\"1\">\n          <Actors selectTriggeringEntities=\"false\"><EntityRef entityRef=\"{0}\"/></Actors>\n          <Maneuver name=\"{0} as logged\">",
            e.name
        );
        let _ = writeln!(
            x,
            "            <Event name=\"{0} follows its trajectory\" priority=\"parallel\">\n              <Action name=\"{0} trajectory\">\n                <PrivateAction><RoutingAction><FollowTrajectoryAction>\n                  <Trajectory name=\"{0}\" closed=\"false\"><Shape><Polyline>",
            e.name
        );
        for v in &e.path {
            let _ = writeln!(
                x,
                "                    <Vertex time=\"{:.3}\"><Position>{}</Position></Vertex>",
                v.time,
                v.xml()
            );
        }
        let _ = writeln!(
            x,
            "                  </Polyline></Shape></Trajectory>\n                  <TimeReference><Timing domainAbsoluteRelative=\"absolute\" scale=\"1\" offset=\"0\"/></TimeReference>\n                  <TrajectoryFollowingMode followingMode=\"position\"/>\n                </FollowTrajectoryAction></RoutingAction></PrivateAction>\n              </Action>\n              {}\n            </Event>",
            time_trigger("StartTrigger", "start", -1.0)
        );
        if !e.always {
            let (first, last) = (e.path[0].time, e.path[e.path.len() - 1].time);
            let mut shown = vec![("appears", true, first)];
            if last < end {
                shown.push(("is lost", false, last));
            }
            for (what, visible, at) in shown.into_iter().filter(|s| s.2 > 0.0) {
                let _ = writeln!(
                    x,
                    "            <Event name=\"{0} {what}\" priority=\"parallel\">\n              <Action name=\"{0} {what}\"><PrivateAction>{1}</PrivateAction></Action>\n              {2}\n            </Event>",
                    e.name,
                    visibility(visible),
                    time_trigger("StartTrigger", what, at - 0.5 * TIME_STEP_S)
                );
            }
        }
        x.push_str("          </Maneuver>\n        </ManeuverGroup>\n");
    }
    let _ = writeln!(
        x,
        "        {}\n      </Act>\n    </Story>\n    {}\n  </Storyboard>\n</OpenSCENARIO>",
        time_trigger("StartTrigger", "start", -1.0),
        time_trigger("StopTrigger", "the log ends", end)
    );
    x
}
