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

They must agree on every pose whose footprint is farther than `--tolerance` (default 0.3 m)
from the drivable area's edge in `verify` (the lanelets are the tile's lanes cut at junctions,
without the round caps of the tile's capsules: near an edge the two areas differ by design);
every collision `verify` reports must be a step where the checker finds the ego in collision
(±1 step). The other way round is reported, not required: CommonRoad's static obstacles stand
for the whole scenario, while `verify` replays a track only while the log reports it, so a drum
hit after it left the camera's view collides in CommonRoad only. The script prints a table and
exits 1 on a disagreement.
"""
import argparse
import bisect
import csv
import json
import math
import subprocess
import sys
import warnings
from pathlib import Path

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
    parser = argparse.ArgumentParser()
    parser.add_argument("--dash2sim", required=True)
    parser.add_argument("--log", required=True)
    parser.add_argument("--map", required=True)
    parser.add_argument("--out", required=True)
    parser.add_argument("--scenario-seconds")
    parser.add_argument("--tolerance", type=float, default=0.3)
    parser.add_argument("--json", action="store_true")
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
                  ("" if not r["errors"] else "  DISAGREE: " + "; ".join(r["errors"])))
    return 1 if any(r["errors"] for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
