"""ScenarioNet's and MetaDrive's own tools on `dash2sim export --scenarionet`, against
`dash2sim verify` (issue #33).

    VENV/bin/python scripts/scenarionet_check.py --dash2sim target/release/dash2sim \
        --log LOG --map MAP --out DIR [--scenario-seconds S] [--expect verified|collision] [--json]

1. `dash2sim export LOG --scenarionet DIR --map MAP [--scenario-seconds S]` writes the dataset;
2. MetaDrive's readers load it (`read_dataset_summary`, `read_scenario_data`, numpy warnings
   as errors), every scenario passes `ScenarioDescription.sanity_check(check_self_type=True,
   valid_check=True)`, and the summaries in the file and in `dataset_summary.pkl` are what
   `ScenarioDescription.update_summaries` computes from the tracks;
3. MetaDrive's `ScenarioEnv` replays every scenario headless (no rendering), the ego following
   the log (`ReplayEgoCarPolicy`), the traffic the log's tracks; per step it reports a crash
   (with a vehicle, an object, a pedestrian) and out-of-road (`relax_out_of_road_done=False`:
   the ego on a road edge or a solid line);
4. `dash2sim verify LOG --map MAP --poses CSV` judges the same poses.

`--expect verified`: the log must verify, and MetaDrive must report no crash and no
out-of-road. `--expect collision`: `verify` must report a collision, and MetaDrive a crash
within a step of it. Either way every collision `verify` reports must be a MetaDrive crash
(±1 step). The script prints a line per scenario and exits 1 on a disagreement.

MetaDrive draws every cone as its own model's cylinder, 0.4 m across, and every barrier as a
2.0 x 0.3 m box, whatever the scenario says (`TrafficCone.RADIUS`, `TrafficBarrier.LENGTH`);
a drum of the log is 0.6 m across. The replay gives each static object the size of its track
instead (a subclass per size), so that MetaDrive's physics judges the objects the log has;
`--metadrive-sizes` keeps MetaDrive's.

MetaDrive fetches its 3D models and textures from GitHub the first time an engine starts
(`metadrive.pull_asset`); a headless replay draws none of them, so where GitHub cannot be
reached the script gives MetaDrive an assets folder holding only its version stamp and the
one file whose absence triggers the download.
"""
import bisect
import csv
import json
import math
import pickle
import subprocess
import sys
import warnings
from pathlib import Path

import peer_cli

import numpy as np


def stand_in_assets():
    """An assets folder MetaDrive accepts without downloading (see the module's docstring)."""
    import metadrive
    from metadrive.version import VERSION
    assets = Path(metadrive.__file__).parent / "assets"
    if (assets / "version.txt").exists():
        return
    grass = assets / "textures" / "grass1" / "GroundGrassGreen002_COL_1K.jpg"
    grass.parent.mkdir(parents=True, exist_ok=True)
    grass.touch()
    (assets / "version.txt").write_text(VERSION)


def sized_static_objects():
    """Spawn each cone and barrier at its track's size (see the module's docstring)."""
    from metadrive.component.static_object.traffic_object import TrafficBarrier, TrafficCone
    from metadrive.manager.scenario_traffic_manager import ScenarioTrafficManager
    original = ScenarioTrafficManager.spawn_static_object
    classes = {}

    def spawn(self, cls, scenario_id, track):
        state = track["state"]
        k = int(np.argmax(state["valid"]))
        length, width = round(float(state["length"][k]), 2), round(float(state["width"][k]), 2)
        if cls is TrafficCone:
            key = (cls, width)
            classes.setdefault(key, type(f"Cone{width}", (TrafficCone,), {"RADIUS": width / 2}))
        else:
            key = (cls, length, width)
            classes.setdefault(key, type(f"Barrier{length}x{width}", (TrafficBarrier,), {
                "LENGTH": property(lambda _: length), "WIDTH": property(lambda _: width)}))
        return original(self, classes[key], scenario_id, track)

    ScenarioTrafficManager.spawn_static_object = spawn


def verify_poses(dash2sim: str, log: str, map_path: str, out: Path) -> tuple:
    poses = out / "verify-poses.csv"
    report = subprocess.run([dash2sim, "verify", log, "--map", map_path, "--poses", str(poses), "--json"],
                            check=True, capture_output=True, text=True)
    with open(poses) as f:
        return list(csv.DictReader(f)), json.loads(report.stdout)


def check_files(out: Path) -> tuple:
    """Load the dataset as ScenarioNet does and check each scenario; (scenarios, errors)."""
    from metadrive.scenario.scenario_description import ScenarioDescription as SD
    from metadrive.scenario.utils import read_dataset_summary, read_scenario_data
    errors = []
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        summaries, ids, mapping = read_dataset_summary(str(out))
        scenarios = [read_scenario_data(str(out / mapping[i] / i)) for i in ids]
    for name, scenario in zip(ids, scenarios):
        try:
            SD.sanity_check(dict(scenario), check_self_type=False, valid_check=True)
            with open(out / name, "rb") as f:
                SD.sanity_check(pickle.load(f), check_self_type=True, valid_check=True)
        except AssertionError as e:
            errors.append(f"{name}: sanity_check: {e}")
            continue
        stored = scenario["metadata"]
        recomputed = SD.update_summaries(SD(pickle.loads(pickle.dumps(dict(scenario)))))["metadata"]
        for key in ("object_summary", "number_summary"):
            a, b = stored[key], recomputed[key]
            if key == "object_summary":
                same = a.keys() == b.keys() and all(
                    all(math.isclose(a[k][f], b[k][f], abs_tol=1e-3) if isinstance(a[k][f], float) else a[k][f] == b[k][f]
                        for f in b[k]) for k in b)
            else:
                same = {k: (dict(v) if isinstance(v, dict) else v) for k, v in a.items()} == \
                       {k: (dict(v) if isinstance(v, dict) else v) for k, v in b.items()}
            if not same:
                errors.append(f"{name}: the stored {key} is not ScenarioNet's")
        if summaries[name]["object_summary"].keys() != stored["object_summary"].keys():
            errors.append(f"{name}: dataset_summary.pkl does not match the scenario's metadata")
    return ids, scenarios, errors


def replay(out: Path, scenarios: list) -> tuple:
    """Each scenario replayed in MetaDrive: per step (crash kind or '', out of road); and the
    farthest the replayed ego strayed from the log, m."""
    from metadrive.envs.scenario_env import ScenarioEnv
    from metadrive.policy.replay_policy import ReplayEgoCarPolicy
    # Every vehicle a box of its track's size, the ego one of the SDC's (`verify`'s footprint).
    sdc = scenarios[0]["tracks"][scenarios[0]["metadata"]["sdc_id"]]["state"]
    size = {k: float(sdc[k][0]) for k in ("length", "width", "height")}
    env = ScenarioEnv({
        "use_render": False, "agent_policy": ReplayEgoCarPolicy, "data_directory": str(out),
        "num_scenarios": len(scenarios), "relax_out_of_road_done": False, "log_level": 50,
        "crash_vehicle_done": False, "crash_object_done": False, "crash_human_done": False,
        "sequential_seed": True, "horizon": None, "use_bounding_box": True,
        "vehicle_config": size,
    })
    results, stray = [], 0.0
    try:
        for seed, scenario in enumerate(scenarios):
            env.reset(seed=seed)
            length = env.engine.data_manager.current_scenario_length
            # MetaDrive moves the scenario's origin to the ego's first position.
            current = env.engine.data_manager.current_scenario
            logged = current["tracks"][current["metadata"]["sdc_id"]]["state"]["position"]
            steps = []
            for k in range(length - 1):
                _, _, terminated, truncated, info = env.step([0.0, 0.0])
                stray = max(stray, float(np.hypot(*(np.asarray(env.agent.position) - logged[k + 1][:2]))))
                kind = ("vehicle" if info.get("crash_vehicle") else "object" if info.get("crash_object") else
                        "human" if info.get("crash_human") else "building" if info.get("crash_building") else "")
                steps.append((kind, bool(info.get("out_of_road"))))
                if terminated and not (kind or info.get("out_of_road")) and not info.get("arrive_dest"):
                    break
            results.append(steps)
    finally:
        env.close()
    return results, stray


def main() -> int:
    parser = peer_cli.parser(__doc__.split("\n", 1)[0])
    parser.add_argument("--scenario-seconds")
    parser.add_argument("--expect", choices=["verified", "collision"])
    parser.add_argument("--metadrive-sizes", action="store_true")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    stand_in_assets()
    if not args.metadrive_sizes:
        sized_static_objects()
    command = [args.dash2sim, "export", args.log, "--scenarionet", str(out), "--map", args.map]
    if args.scenario_seconds:
        command += ["--scenario-seconds", args.scenario_seconds]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    rows, report = verify_poses(args.dash2sim, args.log, args.map, out)
    ids, scenarios, errors = check_files(out)
    if not ids:
        print("no scenario written", file=sys.stderr)
        return 1
    replays, stray = replay(out, scenarios)
    if stray > 0.05:
        errors.append(f"MetaDrive's ego strays {stray:.2f} m from the log")
    times = [float(r["t_s"]) for r in rows]
    results = []
    for name, scenario, steps in zip(ids, scenarios, replays):
        own = []
        # The verify row of each step: a window's steps are 0.1 s apart from its start.
        suffix = scenario["id"].rsplit("-", 1)[-1]
        first = (int(suffix) - 1) * scenario["length"] if args.scenario_seconds else 0
        mine = []
        for k in range(1, len(steps) + 1):
            t = times[0] + (first + k) * 0.1
            j = bisect.bisect_left(times, t - 0.05)
            mine.append(rows[j] if j < len(rows) and abs(times[j] - t) < 0.05 else None)
        crashes = [k for k, (kind, _) in enumerate(steps) if kind]
        off_road = [k for k, (_, off) in enumerate(steps) if off]
        verify_hits = [k for k, row in enumerate(mine) if row and row["collision_agent"]]
        for k in verify_hits:
            if not any(abs(k - c) <= 1 for c in crashes):
                own.append(f"verify collides with {mine[k]['collision_agent']} at step {k + 1}, MetaDrive does not")
        kinds = sorted({kind for kind, _ in steps if kind})
        results.append({"scenario": name, "steps": len(steps) + 1, "tracks": len(scenario["tracks"]),
                        "map_features": len(scenario["map_features"]), "metadrive_crash_steps": len(crashes),
                        "metadrive_crash_kinds": kinds, "metadrive_first_crash": crashes[0] + 1 if crashes else None,
                        "metadrive_off_road_steps": len(off_road), "verify_collisions": len(verify_hits),
                        "errors": own})
    verified = bool(report.get("verified"))
    if args.expect == "verified":
        if not verified:
            errors.append("the log does not verify")
        errors += [f"{r['scenario']}: MetaDrive reports {r['metadrive_crash_steps']} crash and "
                   f"{r['metadrive_off_road_steps']} out-of-road steps on a verified log"
                   for r in results if r["metadrive_crash_steps"] or r["metadrive_off_road_steps"]]
    if args.expect == "collision":
        if not any(r["verify_collisions"] for r in results):
            errors.append("verify reports no collision")
        if not any(r["metadrive_crash_steps"] for r in results):
            errors.append("MetaDrive reports no crash")
    errors += [e for r in results for e in r["errors"]]
    if args.json:
        print(json.dumps({"verified": verified, "scenarios": results, "errors": errors}))
    else:
        for r in results:
            print(f"{r['scenario']}: {r['steps']} steps, {r['tracks']} tracks, {r['map_features']} map features; "
                  f"MetaDrive: {r['metadrive_crash_steps']} crash steps {r['metadrive_crash_kinds'] or ''}"
                  f"{' from step ' + str(r['metadrive_first_crash']) if r['metadrive_first_crash'] else ''}, "
                  f"{r['metadrive_off_road_steps']} out-of-road steps; verify: {r['verify_collisions']} collisions")
        print(f"verify: {'verified' if verified else 'NOT verified'}; " +
              ("agree" if not errors else "DISAGREE: " + "; ".join(errors)))
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
