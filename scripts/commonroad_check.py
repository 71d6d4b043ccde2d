"""CommonRoad's own tools on `dash2sim export --commonroad`, against `dash2sim verify` (issue #33).

    VENV/bin/python scripts/commonroad_check.py --dash2sim target/release/dash2sim \
        --log LOG --map MAP --out DIR [--scenario-seconds S] [--json]

1. `dash2sim export LOG --commonroad DIR/NAME.xml --map MAP [--scenario-seconds S]` writes the
   scenarios and the ego's solution trajectories;
2. each scenario is checked against CommonRoad's XSD (2020a) — the one deviation allowed is
   the one commonroad-io's own writer makes: an obstacle that appears after the first step
   carries that step as its initial time — and loaded by `CommonRoadFileReader`, its solution
   by `CommonRoadSolutionReader`;
3. the drivability checker (commonroad-drivability-checker) judges the ego, a rectangle of
   `verify`'s footprint (nuPlan's Pacifica) at every state of the solution: **road
   compliance** against the road boundary it builds from the lanelet network (`aligned_triangulation`:
   everything outside the union of the lanelets, in axis-aligned triangles) and **collision** with the obstacles at
   that step (its collision checker built from the scenario);
4. `dash2sim verify LOG --map MAP --poses CSV` judges the same poses: the pose is compliant
   when its footprint lies in the tile's drivable area; a collision is reported at the pose it
   begins (nuPlan counts each agent once).

5. with `--crime`, CriMe's time to collision (commonroad-crime: `TTC`, constant acceleration
   along the ego's lane) against `verify`'s (nuPlan's: the two boxes projected at constant
   velocity along their headings, 0.1 s steps up to 3 s), at every step where CriMe defines
   one for an obstacle on the ego's course — ahead, in the ego's lanelet, its centre closer
   sideways than half the two widths (CriMe's TTC is one-dimensional: it measures along the
   lane whatever the sideways offset). CriMe 0.4.5 projects both speeds with the cosine of the
   lane's absolute orientation (`ttc.py`), as if the lane ran along x (CommonRoad's own
   benchmark roads mostly do); the scenario is turned so that the ego's mean heading runs
   along +x first. Both must agree on whether the TTC falls to nuPlan's bound (0.95 s) — the
   metric's verdict; reported besides: at how many of those steps `verify`'s TTC (the least
   over every agent it counts) is at most CriMe's plus `--ttc-tolerance` (default 0.3 s), and
   the median gap. `verify` counts an agent only within 30° ahead of the rear axle and never
   one it has already collided with, CriMe any obstacle along the lane: a step where a drum
   beside the bonnet drops out of `verify`'s cone is a step CriMe alone counts.

They must agree on every pose whose footprint is farther than `--tolerance` (default 0.3 m)
from the drivable area's edge in `verify` (the lanelets are the tile's lanes cut at junctions,
without the round caps of the tile's capsules: near an edge the two areas differ by design);
every collision `verify` reports must be a step where the checker finds the ego in collision
(±1 step). The other way round is reported, not required: CommonRoad's static obstacles stand
for the whole scenario, while `verify` replays a track only while the log reports it, so a drum
hit after it left the camera's view collides in CommonRoad only. The script prints a table and
exits 1 on a disagreement.
"""
import bisect
import csv
import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

import peer_cli

import commonroad
from commonroad.common.file_reader import CommonRoadFileReader
from commonroad.common.solution import CommonRoadSolutionReader
from commonroad_dc import pycrcc
from commonroad_dc.boundary.boundary import create_road_boundary_obstacle
from commonroad_dc.collision.collision_detection.pycrcc_collision_dispatch import create_collision_checker
from lxml import etree
from shapely.geometry import Polygon
from shapely.ops import unary_union

# nuPlan's Pacifica, as `verify` has it: 2.297 m wide, 4.049 m ahead of and 1.127 m behind the
# rear axle (the solution's positions are the centre).
LENGTH, WIDTH = 4.049 + 1.127, 2.297
XSD = Path(commonroad.__file__).parent / "scenario_definition/xml_definition_files/XML_commonRoad_XSD.xsd"
# What commonroad-io's own writer does for an obstacle that appears after the first step.
ALLOWED_XSD = "Element 'exact': [facet 'maxInclusive'] The value"


def footprint(state):
    """The ego's rectangle at a solution state, as a shapely polygon."""
    (x, y), (s, c) = state.position, (math.sin(state.orientation), math.cos(state.orientation))
    corners = [(LENGTH / 2, WIDTH / 2), (-LENGTH / 2, WIDTH / 2), (-LENGTH / 2, -WIDTH / 2), (LENGTH / 2, -WIDTH / 2)]
    return Polygon([(x + c * a - s * b, y + s * a + c * b) for a, b in corners])


def xsd_errors(path: Path) -> list:
    schema = etree.XMLSchema(etree.parse(str(XSD)))
    schema.validate(etree.parse(str(path)))
    return [f"{e.line}: {e.message}" for e in schema.error_log if ALLOWED_XSD not in e.message]


def verify_poses(dash2sim: str, log: str, map_path: str, out: Path) -> list:
    poses = out / "verify-poses.csv"
    subprocess.run([dash2sim, "verify", log, "--map", map_path, "--poses", str(poses)], check=True,
                   stdout=subprocess.DEVNULL)
    with open(poses) as f:
        return list(csv.DictReader(f))


TTC_BOUND_S = 0.95  # nuPlan's time_to_collision_within_bound
TTC_HORIZON_S = 3.0  # verify's projection horizon


def crime_ttc(path: Path, rows: list, first_step: int, tolerance: float) -> dict:
    """CriMe's TTC on the scenario at `path` against `verify`'s rows (see the docstring)."""
    import numpy as np
    from commonroad.geometry.shape import Rectangle
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.lanelet import LaneletNetwork
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.state import CustomState, InitialState
    from commonroad.scenario.trajectory import Trajectory
    from commonroad_crime.data_structure.configuration import CriMeConfiguration
    from commonroad_crime.measure.time.ttc import TTC

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario, _ = CommonRoadFileReader(str(path)).open()
    states = CommonRoadSolutionReader.open(str(path.with_suffix(".solution.xml"))) \
        .planning_problem_solutions[0].trajectory.state_list
    theta = math.atan2(sum(math.sin(s.orientation) for s in states), sum(math.cos(s.orientation) for s in states))
    scenario.translate_rotate(np.zeros(2), -theta)
    # translate_rotate leaves the lanelet network's spatial index where it was: rebuild it.
    scenario.replace_lanelet_network(LaneletNetwork.create_from_lanelet_network(scenario.lanelet_network))
    c, s_ = math.cos(-theta), math.sin(-theta)
    dt, ego_states = scenario.dt, []
    for k, st in enumerate(states):
        x, y = st.position
        a, b = max(k - 1, 0), min(k + 1, len(states) - 1)
        kind = InitialState if k == 0 else CustomState
        ego_states.append(kind(time_step=k, position=np.array([c * x - s_ * y, s_ * x + c * y]),
                               orientation=st.orientation - theta, velocity=st.velocity,
                               acceleration=(states[b].velocity - states[a].velocity) / (dt * max(b - a, 1)),
                               yaw_rate=0.0, slip_angle=0.0))
    ego_id = scenario.generate_object_id()
    shape = Rectangle(LENGTH, WIDTH)
    scenario.add_objects(DynamicObstacle(ego_id, ObstacleType.CAR, shape, ego_states[0],
                                         TrajectoryPrediction(Trajectory(1, ego_states[1:]), shape)))
    scenario.assign_obstacles_to_lanelets(obstacle_ids={ego_id}, use_center_only=True)
    config = CriMeConfiguration()
    config.update(ego_id=ego_id, sce=scenario)
    import logging
    logging.disable(logging.WARNING)
    ttc = TTC(config)
    net, times = scenario.lanelet_network, [float(r["t_s"]) for r in rows]
    compared, errors = [], []
    for k, ego in enumerate(ego_states):
        lanes = net.find_lanelet_by_position([ego.position])[0]
        polygons = [net.find_lanelet_by_id(lane).polygon for lane in lanes]
        least = math.inf
        for o in scenario.obstacles:
            if o.obstacle_id == ego_id:
                continue
            other = o.state_at_time(k) if isinstance(o, DynamicObstacle) else o.initial_state
            if other is None:
                continue
            dx, dy = other.position - ego.position
            ahead = dx * math.cos(ego.orientation) + dy * math.sin(ego.orientation)
            side = -dx * math.sin(ego.orientation) + dy * math.cos(ego.orientation)
            if ahead <= 0 or abs(side) > (WIDTH + o.obstacle_shape.width) / 2 or \
                    not any(p.contains_point(other.position) for p in polygons):
                continue
            value = ttc.compute(o.obstacle_id, k, verbose=False)
            if value is not None and not math.isnan(value):
                least = min(least, value)
        if least >= TTC_HORIZON_S:
            continue
        t = times[0] + (first_step + k) * dt
        j = bisect.bisect_left(times, t - 0.05)
        mine = float(rows[j]["ttc_s"]) if j < len(rows) and rows[j]["ttc_s"] not in ("", "inf") else math.inf
        compared.append((k, least, mine))
    crime_below = any(least <= TTC_BOUND_S for _, least, _ in compared)
    verify_below = any(float(r["ttc_s"]) <= TTC_BOUND_S for r in rows[first_step:first_step + len(states)]
                       if r["ttc_s"] not in ("", "inf"))
    if crime_below != verify_below:
        errors.append(f"TTC under {TTC_BOUND_S} s: CriMe {crime_below}, verify {verify_below}")
    gaps = sorted(abs(least - mine) for _, least, mine in compared if mine < math.inf)
    within = sum(mine <= least + tolerance for _, least, mine in compared)
    return {"ttc_steps": len(compared), "ttc_within_tolerance": within,
            "ttc_median_gap_s": round(gaps[len(gaps) // 2], 2) if gaps else None,
            "crime_under_bound": crime_below, "verify_under_bound": verify_below, "ttc_errors": errors}


def check(path: Path, rows: list, tolerance: float) -> dict:
    errors = xsd_errors(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario, problems = CommonRoadFileReader(str(path)).open()
    solution = CommonRoadSolutionReader.open(str(path.with_suffix(".solution.xml")))
    states = solution.planning_problem_solutions[0].trajectory.state_list
    problem = next(iter(problems.planning_problem_dict.values()))
    start = problem.initial_state.position
    if math.dist(start, states[0].position) > 1e-3:
        errors.append(f"the planning problem starts at {start}, the solution at {states[0].position}")
    # Lanes across a centre line name each other, facing the other way, along a shared bound.
    network = scenario.lanelet_network
    for lanelet in network.lanelets:
        if lanelet.adj_left is not None and not lanelet.adj_left_same_direction:
            other = network.find_lanelet_by_id(lanelet.adj_left)
            if other.adj_left != lanelet.lanelet_id or other.adj_left_same_direction:
                errors.append(f"lanelet {lanelet.lanelet_id}: opposite neighbour {other.lanelet_id} does not name it back")
            elif Polygon(lanelet.polygon.vertices).buffer(0).intersection(
                    Polygon(other.polygon.vertices).buffer(0)).area > 0.05 * lanelet.polygon.shapely_object.area:
                errors.append(f"lanelets {lanelet.lanelet_id} and {other.lanelet_id} overlap across the centre line")
    _, boundary = create_road_boundary_obstacle(scenario, method="aligned_triangulation", axis="auto")
    obstacles = create_collision_checker(scenario)
    # The verify row of each step: the export's steps are 0.1 s apart from the log's first
    # ego pose, a window's from its start (`NAME-001.xml` is the first window).
    suffix = path.stem.rsplit("-", 1)[-1]
    first_step = (int(suffix) - 1) * len(states) if suffix.isdigit() else 0
    t0, times = float(rows[0]["t_s"]), [float(r["t_s"]) for r in rows]
    compliant, colliding, mine = [], [], []
    for state in states:
        x, y = state.position
        ego = pycrcc.RectOBB(LENGTH / 2, WIDTH / 2, state.orientation, x, y)
        compliant.append(not boundary.collide(ego))
        colliding.append(obstacles.time_slice(state.time_step).collide(ego))
        t = t0 + (first_step + state.time_step) * scenario.dt
        k = bisect.bisect_left(times, t - 0.05)
        if k < len(rows) and abs(times[k] - t) < 0.05:
            mine.append(rows[k])
        else:
            errors.append(f"no verify pose at {t:.2f} s")
            break
    # The lanelets' union, for how far a footprint is from its edge.
    edge = unary_union([lanelet.polygon.shapely_object.buffer(0) for lanelet in scenario.lanelet_network.lanelets]).boundary
    judged = agree = 0
    disagree = []
    for k, row in enumerate(mine):
        corners = [float(row[c]) for c in ("front_left_m", "front_right_m", "rear_right_m", "rear_left_m")]
        if min(abs(c) for c in corners) <= tolerance or footprint(states[k]).distance(edge) <= tolerance:
            continue
        judged += 1
        if compliant[k] == (row["compliant"] == "1"):
            agree += 1
        else:
            disagree.append((k, row["t_s"], compliant[k], row["compliant"]))
    verify_hits = [k for k, row in enumerate(mine) if row["collision_agent"]]
    starts = [k for k in range(len(colliding)) if colliding[k] and (k == 0 or not colliding[k - 1])]
    collision_problems = [f"verify collides at step {k}, CommonRoad does not" for k in verify_hits
                          if not any(colliding[j] for j in range(max(0, k - 1), min(len(colliding), k + 2)))]
    # CommonRoad's static obstacles stand for the whole scenario; `verify` replays a track only
    # while the log reports it, so a static object hit after it left the camera's view is a
    # collision in CommonRoad only (reported, not a disagreement).
    commonroad_only = [k for k in starts if not any(abs(k - j) <= 1 for j in verify_hits)]
    if disagree:
        errors.append(f"road compliance differs at {len(disagree)} poses, first {disagree[:3]}")
    errors += collision_problems
    return {"scenario": path.name, "id": str(scenario.scenario_id), "lanelets": len(scenario.lanelet_network.lanelets),
            "dynamic": len(scenario.dynamic_obstacles), "static": len(scenario.static_obstacles),
            "steps": len(states), "road_judged": judged, "road_agree": agree,
            "commonroad_off_road": compliant.count(False), "verify_off_road": sum(r["compliant"] == "0" for r in mine),
            "commonroad_collision_steps": sum(colliding), "verify_collisions": len(verify_hits),
            "commonroad_only_collisions": commonroad_only, "errors": errors}


def main() -> int:
    parser = peer_cli.parser(__doc__.split("\n", 1)[0])
    parser.add_argument("--scenario-seconds")
    parser.add_argument("--tolerance", type=float, default=0.3)
    parser.add_argument("--crime", action="store_true", help="compare CriMe's TTC with verify's")
    parser.add_argument("--ttc-tolerance", type=float, default=0.3)
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = [args.dash2sim, "export", args.log, "--commonroad", str(out / "scenario.xml"), "--map", args.map]
    if args.scenario_seconds:
        command += ["--scenario-seconds", args.scenario_seconds]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    rows = verify_poses(args.dash2sim, args.log, args.map, out)
    scenarios = sorted(p for p in out.glob("scenario*.xml") if not p.name.endswith(".solution.xml"))
    if not scenarios:
        print("no scenario written", file=sys.stderr)
        return 1
    results = [check(p, rows, args.tolerance) for p in scenarios]
    if args.crime:
        for p, r in zip(scenarios, results):
            suffix = p.stem.rsplit("-", 1)[-1]
            first_step = (int(suffix) - 1) * r["steps"] if suffix.isdigit() else 0
            r.update(crime_ttc(p, rows, first_step, args.ttc_tolerance))
            r["errors"] += r["ttc_errors"]
    if args.json:
        print(json.dumps(results))
    else:
        for r in results:
            print(f"{r['scenario']} ({r['id']}): {r['lanelets']} lanelets, {r['dynamic']} dynamic and {r['static']} "
                  f"static obstacles, {r['steps']} steps; road compliance agrees on {r['road_agree']} of "
                  f"{r['road_judged']} poses away from the edge (off road: CommonRoad {r['commonroad_off_road']}, "
                  f"verify {r['verify_off_road']}); collisions: CommonRoad {r['commonroad_collision_steps']} steps, "
                  f"verify {r['verify_collisions']}" +
                  (f" (CommonRoad only, from steps {r['commonroad_only_collisions']})" if r["commonroad_only_collisions"] else "") +
                  (f"; CriMe's TTC on {r['ttc_steps']} steps, verify's within it on {r['ttc_within_tolerance']}, median gap "
                   f"{r['ttc_median_gap_s'] if r['ttc_median_gap_s'] is not None else '-'} s, under "
                   f"{TTC_BOUND_S} s: CriMe {r['crime_under_bound']}, verify {r['verify_under_bound']}" if "ttc_steps" in r else "") +
                  ("" if not r["errors"] else "  DISAGREE: " + "; ".join(r["errors"])))
    return 1 if any(r["errors"] for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
