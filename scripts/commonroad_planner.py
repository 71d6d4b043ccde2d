"""CommonRoad's reactive planner on `dash2sim export --commonroad` scenarios (issue #33), as
PDM-Closed runs on the nuPlan export (docs/verify.md).

    VENV/bin/python scripts/commonroad_planner.py SCENARIO.xml [SCENARIO.xml ...] [--json] [--require-goal]

For each scenario (its planning problem: the logged ego's state at the first step, a goal
region around where the ego is at the last), the reactive planner (commonroad-reactive-planner,
its default configuration, its kinematic checks in one process: sampling in a Frenet frame along the route planner's reference path
to the goal, replanning every step) drives closed-loop from the initial state until the goal is
reached, no feasible trajectory is left, or twice the scenario's steps have passed. Its driven
states are then judged by the drivability checker as `scripts/commonroad_check.py` judges the
log's ego — road compliance against the lanelets' boundary, collisions with the obstacles at
each step — with the planner's own vehicle (its default, a BMW 320i, 4.508 x 1.61 m), and the
least distance to a static obstacle (a drum, cone, barrier) is reported. `--require-goal`: exit 1
unless the planner reaches every goal without a colliding or off-road step (CI runs it so on
the demo's two 15 s windows: a regression in the export that leaves the planner stuck fails).

The route planner's reference path is smoothed with splines (`CLCSParams`: SPLINE_SMOOTHING):
with the default (resampling only) the curvilinear initial state of these maps' polylines
carries a lateral acceleration of 15 m/s² and every sampled trajectory is infeasible.
"""
import argparse
import json
import logging
import math
import sys
import time
import warnings
from pathlib import Path


def plan(path: Path) -> dict:
    import numpy as np
    from commonroad.common.file_reader import CommonRoadFileReader
    from commonroad.geometry.shape import Rectangle
    from commonroad_clcs.config import CLCSParams, ProcessingOption
    from commonroad_dc import pycrcc
    from commonroad_dc.boundary.boundary import create_road_boundary_obstacle
    from commonroad_dc.collision.collision_detection.pycrcc_collision_dispatch import create_collision_checker
    from commonroad_route_planner.fast_api.fast_api import generate_reference_path_from_scenario_and_planning_problem
    from commonroad_rp.reactive_planner import ReactivePlanner
    from commonroad_rp.utility.config import ReactivePlannerConfiguration
    from commonroad_rp.utility.utils_coordinate_system import CoordinateSystem

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scenario, problems = CommonRoadFileReader(str(path)).open()
    problem = next(iter(problems.planning_problem_dict.values()))
    config = ReactivePlannerConfiguration()
    config.update(scenario=scenario, planning_problem=problem)
    # The kinematic checks in this process: by default the planner forks six worker processes
    # (copies of this one, a GB each) at every step and merges their lists before sorting them
    # by cost, which on CI's two cores cost more than the checks themselves. Same trajectories,
    # same order after the sort.
    config.debug.multiproc = False
    route = generate_reference_path_from_scenario_and_planning_problem(scenario, problem)
    planner = ReactivePlanner(config)
    cosys = CoordinateSystem(route.reference_path, clcs_params=CLCSParams(processing_option=ProcessingOption.SPLINE_SMOOTHING))
    planner.set_reference_path(coordinate_system=cosys)
    planner.reset(initial_state_cart=planner.x_0, collision_checker=planner.collision_checker, coordinate_system=cosys)
    planner.record_state_and_input(planner.x_0)
    steps = max(s.time_step.end for s in problem.goal.state_list)
    started, outcome = time.perf_counter(), "goal reached"
    while not planner.goal_reached():
        if len(planner.record_state_list) > 2 * steps:
            outcome = "goal not reached in time"
            break
        planner.set_desired_velocity(current_speed=planner.x_0.velocity)
        optimal = planner.plan()
        if not optimal:
            outcome = f"no feasible trajectory at step {len(planner.record_state_list) - 1}"
            break
        planner.record_state_and_input(optimal[0].state_list[1])
        planner.reset(initial_state_cart=planner.record_state_list[-1], initial_state_curv=(optimal[1][1], optimal[2][1]),
                      collision_checker=planner.collision_checker, coordinate_system=cosys)
    seconds = time.perf_counter() - started
    # The driven states (the planner's are at its rear axle: its vehicle's centre is wb_rear_axle ahead).
    length, width, rear = config.vehicle.length, config.vehicle.width, config.vehicle.wb_rear_axle
    _, boundary = create_road_boundary_obstacle(scenario, method="aligned_triangulation", axis="auto")
    obstacles = create_collision_checker(scenario)
    off_road = collisions = 0
    nearest_static = math.inf
    for state in planner.record_state_list:
        (x, y), h = state.position, state.orientation
        cx, cy = x + rear * math.cos(h), y + rear * math.sin(h)
        box = pycrcc.RectOBB(length / 2, width / 2, h, cx, cy)
        off_road += boundary.collide(box)
        collisions += obstacles.time_slice(state.time_step).collide(box)
        footprint = Rectangle(length, width, np.array([cx, cy]), h).shapely_object
        for o in scenario.static_obstacles:
            nearest_static = min(nearest_static, footprint.distance(o.occupancy_at_time(0).shape.shapely_object))
    speeds = [s.velocity for s in planner.record_state_list]
    return {"scenario": path.name, "outcome": outcome, "steps": len(planner.record_state_list) - 1,
            "goal_end_step": steps, "off_road_steps": off_road, "colliding_steps": collisions,
            "nearest_static_m": round(nearest_static, 2) if nearest_static < math.inf else None,
            "speed_mps": [round(min(speeds), 1), round(max(speeds), 1)],
            "planning_ms_per_step": round(1000 * seconds / max(1, len(planner.record_state_list) - 1), 1)}


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("scenarios", nargs="+")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--require-goal", action="store_true")
    args = parser.parse_args()
    logging.disable(logging.WARNING)
    results = [plan(Path(p)) for p in args.scenarios]
    if args.json:
        print(json.dumps(results))
    else:
        for r in results:
            print(f"{r['scenario']}: {r['outcome']} after {r['steps']} steps (the goal window ends at step {r['goal_end_step']}); "
                  f"off road {r['off_road_steps']} steps, colliding {r['colliding_steps']} steps, nearest static "
                  f"obstacle {r['nearest_static_m']} m, speed {r['speed_mps'][0]}–{r['speed_mps'][1]} m/s, "
                  f"{r['planning_ms_per_step']} ms per step")
    failed = [r for r in results if r["outcome"] != "goal reached" or r["off_road_steps"] or r["colliding_steps"]]
    return 1 if args.require_goal and failed else 0


if __name__ == "__main__":
    sys.exit(main())
