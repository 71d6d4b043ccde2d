//! `dash2sim export LOG --scenarionet DIR --map MAP|OSM [--scenario-seconds S]`: a 4D log and
//! its roads as a ScenarioNet dataset (`docs/scenarionet.md`) — the pickled
//! `ScenarioDescription` MetaDrive replays and ScenarioMax converts onwards — one scenario per
//! window, with the `dataset_summary.pkl` and `dataset_mapping.pkl` ScenarioNet's tools read.
//!
//! * **tracks**: the ego (`"ego"`, the SDC: nuPlan's Pacifica, as `verify` has it) and every
//!   tracked object of the window, by its track id: position (its box's centre), heading,
//!   velocity, length, width, height and a `valid` mask per step of 0.1 s; what is not valid is
//!   zero. A static object stands at the median of where it was seen.
//! * **map_features**: the pieces and connectors of [`super::road`] — the lanes nuPlan's map,
//!   CommonRoad's lanelets and `verify` see — as lanes (centreline, polygon, entry and exit
//!   lanes, neighbours, boundaries, speed limit), the lines between same-direction neighbours
//!   (broken white), the centre line of a two-way road (broken yellow: crossing it is not
//!   leaving the road) and the road's outer edges (`ROAD_EDGE_BOUNDARY`).
//! * **dynamic_map_states**: empty (the tile has no traffic lights).
//! * **metadata**: ids, the time stamps, the frame (UTM less the map origin, with the EPSG
//!   code and the translation), the source, and the object and number summaries ScenarioNet
//!   computes.
//!
//! Everything is written under temporary names and renamed at the end.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dash2sim_core::obb::PACIFICA;

use super::partial::Cleanup;
use super::pickle::{dict, dumps, Array, Py};
use super::request::ScenarioRequest;
use super::road::{road, Road};
use super::ticks::{agents_at_ticks, on_map, windows, AgentTick, EgoTick, OnMap};
use dash2sim_core::class::name_of as class_name;
use dash2sim_linux::geometry::Line;
use dash2sim_linux::{Error, Result};

/// ScenarioNet's time step (Waymo's and its nuPlan converter's), s.
pub const TIME_STEP_S: f64 = 0.1;
/// A scenario needs at least this many steps.
const MIN_STEPS: usize = 10;
/// The SDC's track id.
pub const EGO_ID: &str = "ego";
/// nuPlan's Pacifica is 1.777 m tall.
const EGO_HEIGHT_M: f64 = 1.777;
/// The dataset's name in file names and metadata.
const DATASET: &str = "dash2sim";
/// An object moving less than this (m) in a scenario is not moving (ScenarioNet's summary).
const MOVING_M: f64 = 1.0;

/// One scenario written.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Its file.
    pub path: PathBuf,
    /// Its id.
    pub id: String,
    /// Time steps.
    pub steps: usize,
    /// Tracks, the ego's included.
    pub tracks: usize,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct ScenarioNetExport {
    /// Every scenario, in time order.
    pub scenarios: Vec<Scenario>,
    /// `dataset_summary.pkl`.
    pub summary: PathBuf,
    /// `dataset_mapping.pkl`.
    pub mapping: PathBuf,
    /// Map features in each (the same map).
    pub map_features: usize,
    /// EPSG code of the projected frame.
    pub epsg: i32,
}

/// Export `request` (its `out` the dataset folder, made if missing). Errors name what is
/// wrong; nothing is left behind on an error.
pub fn export(request: &ScenarioRequest<'_>) -> Result<ScenarioNetExport> {
    let OnMap { view, map_projection, log_projection, ticks, .. } =
        on_map(request.log, request.log_name, request.tile, 1.0 / TIME_STEP_S)?;
    let windows = windows(ticks.len(), request.window_s, TIME_STEP_S, MIN_STEPS, "ScenarioNet", request.log_name)?;
    let road = road(&view, &map_projection, 0.0)?;
    // The local frame: the map origin at (0, 0).
    let origin = map_projection.project(&[(0.0, 0.0, 0.0)]).first().copied().unwrap_or_default();
    let agents = agents_at_ticks(request.log, &ticks, &log_projection);
    let map = map_features(&road, origin);
    let map_count = map.len();
    let map = Py::Dict(map);

    std::fs::create_dir_all(request.out).map_err(|e| Error::file(request.out, e))?;
    let stem = Path::new(request.log_name).file_stem().and_then(|s| s.to_str()).unwrap_or("log");
    let mut cleanup = Cleanup(Vec::new());
    let mut renames = Vec::new();
    let mut write = |path: PathBuf, value: &Py| -> Result<()> {
        let partial = path.with_extension("partial");
        cleanup.0.push(partial.clone());
        std::fs::write(&partial, dumps(value)).map_err(|e| Error::file(&partial, e))?;
        renames.push((partial, path));
        Ok(())
    };
    let (mut scenarios, mut summary, mut mapping) = (Vec::new(), Vec::new(), Vec::new());
    for (k, &(from, to)) in windows.iter().enumerate() {
        let id = format!("{stem}-{:03}", k + 1);
        let file = format!("sd_{DATASET}_{}_{id}.pkl", env!("CARGO_PKG_VERSION"));
        let window_agents: Vec<&AgentTick> = agents.iter().filter(|a| a.tick >= from && a.tick < to).collect();
        let mut tracks = vec![ego_track(&ticks[from..to], origin)];
        tracks.extend(agent_tracks(&window_agents, from, to - from, origin));
        let metadata = metadata(&Metadata {
            id: &id,
            log_name: request.log_name,
            start_us: ticks[from].t_us,
            steps: to - from,
            tracks: &tracks,
            map_features: map_count,
            epsg: map_projection.epsg(),
            origin,
        });
        let scenario = Py::Dict(vec![
            ("id".into(), id.clone().into()),
            ("version".into(), format!("{DATASET} {}", env!("CARGO_PKG_VERSION")).into()),
            ("length".into(), (to - from).into()),
            ("metadata".into(), metadata.clone()),
            ("tracks".into(), Py::Dict(tracks.iter().map(|t| (t.id.clone(), t.value.clone())).collect())),
            ("dynamic_map_states".into(), Py::Dict(Vec::new())),
            ("map_features".into(), map.clone()),
        ]);
        let path = request.out.join(&file);
        write(path.clone(), &scenario)?;
        summary.push((file.clone(), metadata));
        mapping.push((file, Py::from("")));
        scenarios.push(Scenario { path, id, steps: to - from, tracks: tracks.len() });
    }
    let summary_path = request.out.join("dataset_summary.pkl");
    let mapping_path = request.out.join("dataset_mapping.pkl");
    write(summary_path.clone(), &Py::Dict(summary))?;
    write(mapping_path.clone(), &Py::Dict(mapping))?;
    for (from, to) in &renames {
        std::fs::rename(from, to).map_err(|e| Error::file(to, e))?;
    }
    cleanup.0.clear();
    Ok(ScenarioNetExport {
        scenarios,
        summary: summary_path,
        mapping: mapping_path,
        map_features: map_count,
        epsg: map_projection.epsg(),
    })
}

/// A track's arrays, before they become a dict: what the summaries are computed from.
struct Track {
    id: String,
    kind: &'static str,
    /// Centre per step (x, y) in the local frame; zero where not valid.
    positions: Vec<(f64, f64)>,
    valid: Vec<bool>,
    value: Py,
}

/// The ScenarioNet (MetaDrive) type of a dash2sim class.
fn object_type(class: &str) -> &'static str {
    match class {
        "car" | "truck" | "bus" => "VEHICLE",
        "motorcycle" | "bicycle" => "CYCLIST",
        "pedestrian" => "PEDESTRIAN",
        "cone" | "drum" => "TRAFFIC_CONE",
        "barricade" | "barrier" => "TRAFFIC_BARRIER",
        // An arrow board is a trailer: MetaDrive places a static vehicle as a box of its size,
        // and spawns no TRAFFIC_OBJECT at all.
        "arrow_board" => "VEHICLE",
        "sign" => "TRAFFIC_OBJECT",
        _ => "OTHER",
    }
}

/// One step of a track: centre, height above the frame, heading, velocity, size.
#[derive(Clone, Copy, Default)]
struct Step {
    x: f64,
    y: f64,
    z: f64,
    heading: f64,
    velocity: (f64, f64),
    size: (f64, f64, f64),
}

/// A track's state dict and metadata from its steps (`None`: not seen at that step).
fn track(id: &str, kind: &'static str, class: &str, steps: &[Option<Step>], original_id: Option<i64>) -> Track {
    let n = steps.len();
    let step = |k: usize| steps[k].unwrap_or_default();
    let state = dict([
        ("position", Array::f32(&[n, 3], (0..n).flat_map(|k| [step(k).x, step(k).y, step(k).z])).into()),
        ("heading", Array::f32(&[n], (0..n).map(|k| step(k).heading)).into()),
        ("velocity", Array::f32(&[n, 2], (0..n).flat_map(|k| [step(k).velocity.0, step(k).velocity.1])).into()),
        ("length", Array::f32(&[n], (0..n).map(|k| step(k).size.0)).into()),
        ("width", Array::f32(&[n], (0..n).map(|k| step(k).size.1)).into()),
        ("height", Array::f32(&[n], (0..n).map(|k| step(k).size.2)).into()),
        ("valid", Array::bool(&[n], steps.iter().map(Option::is_some)).into()),
    ]);
    let mut metadata = vec![
        ("type".to_string(), Py::from(kind)),
        ("object_id".to_string(), id.into()),
        ("track_length".to_string(), n.into()),
        ("dataset".to_string(), DATASET.into()),
        ("class".to_string(), class.into()),
    ];
    if let Some(original) = original_id {
        metadata.push(("original_id".to_string(), original.into()));
    }
    Track {
        id: id.to_string(),
        kind,
        positions: (0..n).map(|k| (step(k).x, step(k).y)).collect(),
        valid: steps.iter().map(Option::is_some).collect(),
        value: dict([("type", kind.into()), ("state", state), ("metadata", Py::Dict(metadata))]),
    }
}

/// The ego over a window: its footprint's centre, valid throughout.
fn ego_track(ego: &[EgoTick], origin: (f64, f64)) -> Track {
    let steps: Vec<Option<Step>> = ego
        .iter()
        .map(|t| {
            let (x, y) = t.centre();
            let (s, c) = t.heading.sin_cos();
            let (forward, left) = t.velocity;
            Some(Step {
                x: x - origin.0,
                y: y - origin.1,
                z: t.z,
                heading: t.heading,
                velocity: (c * forward - s * left, s * forward + c * left),
                size: (PACIFICA.front + PACIFICA.rear, PACIFICA.width, EGO_HEIGHT_M),
            })
        })
        .collect();
    track(EGO_ID, "VEHICLE", "ego", &steps, None)
}

/// The window's tracks (`agents`, ticks `from`…`from + steps`), one per track id, in id order.
fn agent_tracks(agents: &[&AgentTick], from: usize, steps: usize, origin: (f64, f64)) -> Vec<Track> {
    let mut by_track: BTreeMap<i64, Vec<&AgentTick>> = BTreeMap::new();
    for a in agents {
        by_track.entry(a.track.id).or_default().push(a);
    }
    let mut tracks = Vec::new();
    for (id, seen) in by_track {
        let Some(first) = seen.first() else { continue };
        let class = class_name(first.track.class);
        let is_static = 2 * seen.iter().filter(|a| a.track.is_static == 1).count() > seen.len();
        let size = |a: &AgentTick| {
            let mm = |v: i64| (v as f64 * 1e-3).max(0.01);
            (mm(a.track.l_mm), mm(a.track.w_mm), mm(a.track.h_mm))
        };
        // Where a static object stands: the median of where it was seen.
        let median = |f: fn(&AgentTick) -> f64| {
            let mut v: Vec<f64> = seen.iter().map(|a| f(a)).collect();
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let standing = (median(|a| a.x), median(|a| a.y));
        let mut states: Vec<Option<Step>> = vec![None; steps];
        for a in &seen {
            let (x, y, velocity) =
                if is_static { (standing.0, standing.1, (0.0, 0.0)) } else { (a.x, a.y, a.velocity) };
            if let Some(slot) = states.get_mut(a.tick - from) {
                *slot = Some(Step {
                    x: x - origin.0,
                    y: y - origin.1,
                    z: a.z,
                    heading: if is_static { first.heading } else { a.heading },
                    velocity,
                    size: size(if is_static { first } else { a }),
                });
            }
        }
        tracks.push(track(&id.to_string(), object_type(class), class, &states, Some(id)));
    }
    tracks
}

/// What the metadata is made from.
struct Metadata<'a> {
    id: &'a str,
    log_name: &'a str,
    start_us: i64,
    steps: usize,
    tracks: &'a [Track],
    map_features: usize,
    epsg: i32,
    origin: (f64, f64),
}

/// A scenario's metadata, with the summaries ScenarioNet's converters add
/// (`ScenarioDescription.update_summaries`).
fn metadata(m: &Metadata<'_>) -> Py {
    let mut objects = Vec::new();
    let (mut each_type, mut moving_each_type): (BTreeMap<&str, usize>, BTreeMap<&str, usize>) = Default::default();
    let mut moving = 0usize;
    for t in m.tracks {
        let valid: Vec<(f64, f64)> = t.positions.iter().zip(&t.valid).filter(|(_, v)| **v).map(|(p, _)| *p).collect();
        // In float32, as ScenarioNet sums the stored array.
        let distance: f64 = valid
            .windows(2)
            .map(|w| {
                let d = |a: f64, b: f64| f64::from(b as f32) - f64::from(a as f32);
                d(w[0].0, w[1].0).hypot(d(w[0].1, w[1].1))
            })
            .sum();
        let continuous = t.valid.iter().skip_while(|v| !**v).take_while(|v| **v).count();
        objects.push((
            t.id.clone(),
            dict([
                ("type", t.kind.into()),
                ("object_id", t.id.clone().into()),
                ("track_length", t.valid.len().into()),
                ("moving_distance", distance.into()),
                ("valid_length", valid.len().into()),
                ("continuous_valid_length", continuous.into()),
            ]),
        ));
        *each_type.entry(t.kind).or_default() += 1;
        if distance > MOVING_M {
            moving += 1;
            *moving_each_type.entry(t.kind).or_default() += 1;
        }
    }
    let counts = |c: &BTreeMap<&str, usize>| Py::Dict(c.iter().map(|(k, n)| (k.to_string(), (*n).into())).collect());
    let number_summary = dict([
        ("num_objects", m.tracks.len().into()),
        ("object_types", Py::Set(each_type.keys().map(|k| (*k).into()).collect())),
        ("num_objects_each_type", counts(&each_type)),
        ("num_moving_objects", moving.into()),
        ("num_moving_objects_each_type", counts(&moving_each_type)),
        ("num_traffic_lights", 0usize.into()),
        ("num_traffic_light_types", Py::Set(Vec::new())),
        ("num_traffic_light_each_step", Py::Dict(Vec::new())),
        ("num_map_features", m.map_features.into()),
        ("map_height_diff", 0.0.into()),
    ]);
    dict([
        ("ts", Array::f32(&[m.steps], (0..m.steps).map(|k| k as f64 * TIME_STEP_S)).into()),
        ("metadrive_processed", false.into()),
        // What ScenarioNet's converters write for a right-handed frame in metres.
        ("coordinate", "waymo".into()),
        ("dataset", DATASET.into()),
        ("scenario_id", m.id.into()),
        ("id", m.id.into()),
        ("source_file", m.log_name.into()),
        ("sdc_id", EGO_ID.into()),
        ("timestep", TIME_STEP_S.into()),
        ("start_time_utc", dash2sim_linux::utc::iso8601(m.start_us).into()),
        ("start_time_us", m.start_us.into()),
        ("frame", format!("EPSG:{} less the map origin's UTM coordinates", m.epsg).into()),
        ("utm_epsg", i64::from(m.epsg).into()),
        ("utm_origin", Py::List(vec![m.origin.0.into(), m.origin.1.into()])),
        ("object_summary", Py::Dict(objects)),
        ("number_summary", number_summary),
    ])
}

/// A polyline in the local frame as ScenarioNet stores one: (N, 3), z zero (the tile is flat).
fn polyline(line: &[(f64, f64)], origin: (f64, f64)) -> Py {
    Array::f64(&[line.len(), 3], line.iter().flat_map(|p| [p.0 - origin.0, p.1 - origin.1, 0.0])).into()
}

/// A polygon's ring in the local frame, (N, 2): MetaDrive builds its lane surfaces from the
/// points as they are and wants them flat.
fn polygon(ring: &[(f64, f64)], origin: (f64, f64)) -> Py {
    Array::f64(&[ring.len(), 2], ring.iter().flat_map(|p| [p.0 - origin.0, p.1 - origin.1])).into()
}

/// The lanes (ids 1…, as CommonRoad's lanelets), then the lines between and around them.
fn map_features(road: &Road, origin: (f64, f64)) -> Vec<(String, Py)> {
    let pieces = road.pieces.len();
    let lane_id = |k: usize| (k + 1).to_string();
    let connector_id = |k: usize| (pieces + k + 1).to_string();
    let mut next_line = pieces + road.connectors.len();
    let mut lines: Vec<(String, Py)> = Vec::new();
    let mut line = |kind: &str, points: &Line| {
        next_line += 1;
        let id = next_line.to_string();
        lines.push((id.clone(), dict([("type", kind.into()), ("polyline", polyline(points, origin))])));
        (id, kind.to_string())
    };
    let opposite = road.opposite_neighbours();
    let boundary = |(id, kind): (String, String), n: usize| {
        dict([
            ("boundary_feature_id", id.into()),
            ("boundary_type", kind.into()),
            ("lane_start_index", 0usize.into()),
            ("lane_end_index", n.saturating_sub(1).into()),
        ])
    };
    let neighbour = |other: usize, n: usize| {
        let m = road.pieces[other].centre.len();
        dict([
            ("feature_id", lane_id(other).into()),
            ("self_start_index", 0usize.into()),
            ("self_end_index", n.saturating_sub(1).into()),
            ("neighbor_start_index", 0usize.into()),
            ("neighbor_end_index", m.saturating_sub(1).into()),
        ])
    };
    // A line between two neighbours is the left bound of the one on the right.
    let left_lines: Vec<(String, String)> = (0..pieces)
        .map(|i| {
            let kind = match road.pieces[i].left_neighbour {
                Some(_) => "ROAD_LINE_BROKEN_SINGLE_WHITE",
                None if opposite[i].is_some() => "ROAD_LINE_BROKEN_SINGLE_YELLOW",
                None => "ROAD_EDGE_BOUNDARY",
            };
            line(kind, &road.pieces[i].left)
        })
        .collect();
    let mut lanes = Vec::new();
    for (i, piece) in road.pieces.iter().enumerate() {
        let n = piece.centre.len();
        let left = boundary(left_lines[i].clone(), n);
        let right = match piece.right_neighbour {
            Some(j) => boundary(left_lines[j].clone(), n),
            None => boundary(line("ROAD_EDGE_BOUNDARY", &piece.right), n),
        };
        let mut lane = vec![
            ("type".to_string(), Py::from("LANE_SURFACE_STREET")),
            ("polyline".to_string(), polyline(&piece.centre, origin)),
            ("polygon".to_string(), polygon(&piece.ring, origin)),
            (
                "entry_lanes".to_string(),
                Py::List(
                    road.connectors
                        .iter()
                        .enumerate()
                        .filter(|(_, c)| c.to == i)
                        .map(|(k, _)| connector_id(k).into())
                        .collect(),
                ),
            ),
            (
                "exit_lanes".to_string(),
                Py::List(
                    road.connectors
                        .iter()
                        .enumerate()
                        .filter(|(_, c)| c.from == i)
                        .map(|(k, _)| connector_id(k).into())
                        .collect(),
                ),
            ),
            (
                "left_neighbor".to_string(),
                Py::List(piece.left_neighbour.map(|j| neighbour(j, n)).into_iter().collect()),
            ),
            (
                "right_neighbor".to_string(),
                Py::List(piece.right_neighbour.map(|j| neighbour(j, n)).into_iter().collect()),
            ),
            ("left_boundaries".to_string(), Py::List(vec![left])),
            ("right_boundaries".to_string(), Py::List(vec![right])),
        ];
        if let Some(limit) = piece.speed_limit {
            lane.push(("speed_limit_kmh".to_string(), (limit * 3.6).into()));
        }
        lanes.push((lane_id(i), Py::Dict(lane)));
    }
    for (k, c) in road.connectors.iter().enumerate() {
        let mut lane = vec![
            ("type".to_string(), Py::from("LANE_SURFACE_STREET")),
            ("polyline".to_string(), polyline(&c.centre, origin)),
            ("polygon".to_string(), polygon(&c.ring, origin)),
            ("entry_lanes".to_string(), Py::List(vec![lane_id(c.from).into()])),
            ("exit_lanes".to_string(), Py::List(vec![lane_id(c.to).into()])),
            ("left_neighbor".to_string(), Py::List(Vec::new())),
            ("right_neighbor".to_string(), Py::List(Vec::new())),
            ("left_boundaries".to_string(), Py::List(Vec::new())),
            ("right_boundaries".to_string(), Py::List(Vec::new())),
        ];
        if let Some(limit) = c.speed_limit {
            lane.push(("speed_limit_kmh".to_string(), (limit * 3.6).into()));
        }
        lanes.push((connector_id(k), Py::Dict(lane)));
    }
    lanes.extend(lines);
    lanes
}
