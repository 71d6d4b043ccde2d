"""nuPlan's own simulator and metrics against `dash2sim verify`, on a `dash2sim export --nuplan`
(issue #15).

    VENV/bin/python scripts/nuplan_crosscheck.py --dash2sim target/release/dash2sim \
        --log LOG --map MAP --out DIR [--every S] [--planner log|pdm] [--controller lqr|perfect]
        [--expect-fail METRIC] [--score-within POINTS] [--json]

1. `dash2sim export LOG --nuplan DIR --map MAP` writes the log database and the map;
2. the devkit's `NuPlanScenarioBuilder` loads every scenario (the map's name added to its
   hard-coded `MAP_LOCATIONS`), one starting every S seconds (default 5);
3. each is simulated as nuPlan's `closed_loop_nonreactive_agents` does — non-reactive agents
   (`TracksObservation`), the LQR two-stage controller on a kinematic bicycle (or, with
   `--controller perfect`, nuPlan's `PerfectTrackingController`: the ego is the plan) — with the
   log-replay planner (`LogFuturePlanner`, the expert) or PDM-Closed, and scored with nuPlan's
   metrics composed from its own Hydra configs; the aggregate as its weighted average computes it;
4. `dash2sim verify LOG --map MAP --from START --to END` scores the same window.

With the log-replay planner the two must give the same verdict, the same value for every
multiplier metric and every weighted metric within 0.05; the script prints the table and
exits 1 otherwise, and when every scenario was skipped (nothing compared). A bad drive's log
(`demo --driver KIND`) names the metric it must fail with `--expect-fail`: some scenario must
then fail it in both. With PDM-Closed it reports nuPlan's scores only. `../shared/nuplan/setup.sh
VENV` installs the devkit and PDM-Closed; they are test tools, never product dependencies.
"""
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import peer_cli
import nuplan.database.maps_db.gpkg_mapsdb as gpkg_mapsdb
from hydra import compose, initialize_config_dir
from nuplan.common.actor_state.vehicle_parameters import get_pacifica_parameters
from nuplan.planning.scenario_builder.nuplan_db.nuplan_scenario_builder import NuPlanScenarioBuilder
from nuplan.planning.scenario_builder.scenario_filter import ScenarioFilter
from nuplan.planning.script.builders.metric_builder import build_metrics_engines
from nuplan.planning.simulation.controller.motion_model.kinematic_bicycle import KinematicBicycleModel
from nuplan.planning.simulation.controller.perfect_tracking import PerfectTrackingController
from nuplan.planning.simulation.controller.tracker.lqr import LQRTracker
from nuplan.planning.simulation.controller.two_stage_controller import TwoStageController
from nuplan.planning.simulation.observation.tracks_observation import TracksObservation
from nuplan.planning.simulation.planner.log_future_planner import LogFuturePlanner
from nuplan.planning.simulation.simulation import Simulation
from nuplan.planning.simulation.simulation_setup import SimulationSetup
from nuplan.planning.simulation.simulation_time_controller.step_simulation_time_controller import (
    StepSimulationTimeController,
)
from nuplan.planning.utils.multithreading.worker_sequential import Sequential

MULTIPLIERS = ["no_ego_at_fault_collisions", "drivable_area_compliance", "ego_is_making_progress", "driving_direction_compliance"]
WEIGHTS = {"ego_progress_along_expert_route": 5.0, "time_to_collision_within_bound": 5.0, "speed_limit_compliance": 4.0,
           "ego_is_comfortable": 2.0}


def metric_config(output: str):
    """nuPlan's closed-loop non-reactive metric set, composed from its own configs."""
    folder = tempfile.mkdtemp()
    Path(folder, "main.yaml").write_text(
        "defaults:\n  - simulation_metric: simulation_closed_loop_nonreactive_agents\n  - _self_\n"
        "hydra:\n  searchpath:\n    - pkg://nuplan.planning.script.config.common\n"
        f"output_dir: {output}\nmetric_dir: metrics\nselected_simulation_metrics: null\n"
    )
    with initialize_config_dir(config_dir=folder, version_base=None):
        return compose(config_name="main")


def planner_for(name: str, scenario):
    if name == "pdm":
        from tuplan_garage.planning.simulation.planner.pdm_planner.pdm_closed_planner import PDMClosedPlanner
        from hydra.utils import instantiate
        from omegaconf import OmegaConf
        cfg = OmegaConf.load(Path(__import__("tuplan_garage").__file__).parent / "planning/script/config/simulation/planner/pdm_closed_planner.yaml")
        return instantiate(cfg["pdm_closed_planner"])
    return LogFuturePlanner(scenario, num_poses=16, future_time_horizon=8.0)


NAMES = {"no_ego_at_fault_collisions": "no_at_fault_collisions"}
TOLERANCE = 0.05


def main() -> int:
    parser = peer_cli.parser(__doc__.split("\n", 1)[0])
    parser.add_argument("--map-name", default="dash2sim-crosscheck")
    parser.add_argument("--every", type=float, default=5.0)
    parser.add_argument("--scenario-seconds", default="5")
    parser.add_argument("--planner", choices=["log", "pdm"], default="log")
    parser.add_argument("--score-within", type=float, metavar="POINTS",
                        help="also require the aggregate scores to agree within POINTS (issue #55: 0.01 with "
                             "`--controller perfect`)")
    parser.add_argument("--controller", choices=["lqr", "perfect"], default="lqr",
                        help="how nuPlan's ego follows the plan: `lqr`, the two-stage LQR tracker on a kinematic "
                             "bicycle (closed_loop_nonreactive_agents), or `perfect` (PerfectTrackingController: "
                             "the ego is the planned trajectory, so that with the log-replay planner nuPlan scores "
                             "the log itself, as `dash2sim verify` does)")
    parser.add_argument("--expect-fail", metavar="METRIC",
                        help="a bad drive: some scenario must fail this metric (nuPlan's name) in nuPlan and in dash2sim")
    args = parser.parse_args()
    out = Path(args.out)
    subprocess.run([args.dash2sim, "export", args.log, "--nuplan", str(out), "--map", args.map,
                    "--map-name", args.map_name, "--scenario-seconds", args.scenario_seconds], check=True, stdout=subprocess.DEVNULL)
    gpkg_mapsdb.MAP_LOCATIONS = {args.map_name}
    builder = NuPlanScenarioBuilder(data_root=str(out / "db"), map_root=str(out / "maps"), sensor_root=None,
                                    db_files=None, map_version="nuplan-maps-v1.0", include_cameras=False, verbose=False)
    scenario_filter = ScenarioFilter(scenario_types=None, scenario_tokens=None, log_names=None, map_names=None,
                                     num_scenarios_per_type=None, limit_total_scenarios=None,
                                     timestamp_threshold_s=args.every, ego_displacement_minimum_m=None,
                                     expand_scenarios=False, remove_invalid_goals=False, shuffle=False)
    scenarios = builder.get_scenarios(scenario_filter, Sequential())
    if not scenarios:
        print("no scenario loaded", file=sys.stderr)
        return 1
    engines = build_metrics_engines(metric_config(tempfile.mkdtemp()), scenarios)
    vehicle = get_pacifica_parameters()
    rows, failures = [], 0
    for scenario in scenarios:
        tracker = LQRTracker(q_longitudinal=[10.0], r_longitudinal=[1.0], q_lateral=[1.0, 10.0, 0.0], r_lateral=[1.0],
                             discretization_time=0.1, tracking_horizon=10, jerk_penalty=1e-4, curvature_rate_penalty=1e-2,
                             stopping_proportional_gain=0.5, stopping_velocity=0.2, vehicle=vehicle)
        controller = (PerfectTrackingController(scenario) if args.controller == "perfect"
                      else TwoStageController(scenario, tracker, KinematicBicycleModel(vehicle)))
        setup = SimulationSetup(time_controller=StepSimulationTimeController(scenario),
                                observations=TracksObservation(scenario),
                                ego_controller=controller,
                                scenario=scenario)
        simulation = Simulation(setup, callback=None, simulation_history_buffer_duration=2.0)
        planner = planner_for(args.planner, scenario)
        planner.initialize(simulation.initialize())
        try:
            while simulation.is_simulation_running():
                simulation.propagate(planner.compute_trajectory(simulation.get_planner_input()))
        except ValueError as e:
            # The log-replay planner needs the log to go on for its horizon (8 s) past the
            # scenario: the last scenarios of a short log cannot be replayed.
            rows.append({"token": scenario.token, "skipped": str(e)})
            if not args.json:
                print(f"{scenario.token}: skipped ({e})", flush=True)
            continue
        files = engines[scenario.scenario_type].compute(simulation.history, scenario=scenario, planner_name=args.planner)
        nuplan, lane_changes = {}, {}
        for metric_files in files.values():
            for f in metric_files:
                # A metric may add results without a score (the drivable-area corners' time
                # series): its score is the one that has one.
                for result in f.metric_statistics:
                    if result.metric_computator == "ego_lane_change":
                        lane_changes = {st.name: st.value for st in result.statistics}
                    if result.metric_score is not None or result.metric_computator not in nuplan:
                        nuplan[NAMES.get(result.metric_computator, result.metric_computator)] = result.metric_score
        # nuPlan's weighted average: a metric without a score (None) counts as 1.
        value = lambda m: 1.0 if nuplan.get(m) is None else float(nuplan[m])
        multiplier = 1.0
        for m in MULTIPLIERS:
            multiplier *= value(NAMES.get(m, m))
        score = 100.0 * multiplier * sum(WEIGHTS[m] * value(m) for m in WEIGHTS) / sum(WEIGHTS.values())
        start, end = scenario.start_time.time_us / 1e6, scenario.end_time.time_us / 1e6
        row = {"token": scenario.token, "start_s": start, "end_s": end, "planner": args.planner,
               "nuplan": {"score": score, "verified": score > 90.0, "metrics": nuplan, "lane_changes": lane_changes}}
        if args.planner == "log":
            verify = json.loads(subprocess.run([args.dash2sim, "verify", args.log, "--map", args.map, "--json",
                                                "--from", str(start), "--to", str(end)],
                                               check=True, capture_output=True, text=True).stdout)
            row["dash2sim"] = {"score": verify["score"], "verified": verify["verified"], "metrics": verify["metrics"]}
            problems = []
            if verify["verified"] != row["nuplan"]["verified"]:
                problems.append("verdict")
            for m in MULTIPLIERS:
                name = NAMES.get(m, m)
                if value(name) != verify["metrics"][name]:
                    problems.append(name)
            for m in WEIGHTS:
                if abs(value(m) - verify["metrics"][m]) > TOLERANCE:
                    problems.append(m)
            if args.score_within is not None and abs(score - verify["score"]) > args.score_within:
                problems.append(f"score by {abs(score - verify['score']):.3f}")
            row["disagreements"] = problems
            failures += bool(problems)
        rows.append(row)
        if not args.json:
            d = row.get("dash2sim")
            print(f"{scenario.token} {start:.2f}-{end:.2f} s: nuPlan {score:.2f}" +
                  ("" if d is None else f", dash2sim {d['score']:.2f}" +
                   (f"  DISAGREE: {', '.join(row['disagreements'])}" if row["disagreements"] else "  agree")), flush=True)
    compared = [r for r in rows if "nuplan" in r]
    both_fail = [r for r in compared if args.expect_fail and "dash2sim" in r
                 and value_of(r["nuplan"]["metrics"], NAMES.get(args.expect_fail, args.expect_fail)) < 1.0
                 and r["dash2sim"]["metrics"][NAMES.get(args.expect_fail, args.expect_fail)] < 1.0]
    if args.json:
        print(json.dumps({"scenarios": rows, "disagreeing": failures, "both_fail": len(both_fail)}))
    if not compared:
        print("compared nothing: every scenario was skipped", file=sys.stderr)
        return 1
    if args.expect_fail and not both_fail:
        print(f"no scenario fails {args.expect_fail} in both nuPlan and dash2sim", file=sys.stderr)
        return 1
    return 1 if failures else 0


def value_of(metrics: dict, name: str) -> float:
    """nuPlan's metric value, a metric without a score counting as 1 (its weighted average's rule)."""
    return 1.0 if metrics.get(name) is None else float(metrics[name])


if __name__ == "__main__":
    sys.exit(main())
