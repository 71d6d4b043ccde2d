"""Load a `dash2sim export --nuplan` folder with the real nuPlan devkit (issue #15).

    /tmp/nuplan-venv/bin/python scripts/nuplan_crosscheck.py OUT_DIR MAP_NAME [--json]

Builds every scenario of every log in OUT_DIR/db through `NuPlanScenarioBuilder` (with the map
name added to the devkit's hard-coded `MAP_LOCATIONS`), and for each reads what the simulator
reads: the ego's initial state, the route roadblocks, the mission goal, the tracked objects,
and the map objects under the ego (lane, roadblock, drivable area). Prints one line per
scenario, or JSON; exits non-zero when a scenario fails to load. The nuPlan tools are test
tools: `../shared/nuplan/setup.sh VENV` installs them, the product never imports them.
"""
import json
import sys
from pathlib import Path

import nuplan.database.maps_db.gpkg_mapsdb as gpkg_mapsdb
from nuplan.common.actor_state.state_representation import Point2D
from nuplan.common.maps.maps_datatypes import SemanticMapLayer
from nuplan.planning.scenario_builder.nuplan_db.nuplan_scenario_builder import NuPlanScenarioBuilder
from nuplan.planning.scenario_builder.scenario_filter import ScenarioFilter
from nuplan.planning.utils.multithreading.worker_sequential import Sequential


def main() -> int:
    out, map_name = Path(sys.argv[1]), sys.argv[2]
    as_json = "--json" in sys.argv
    # The devkit loads every location it knows (four cities) when a map is first read: only
    # this one exists here.
    gpkg_mapsdb.MAP_LOCATIONS = {map_name}
    builder = NuPlanScenarioBuilder(
        data_root=str(out / "db"),
        map_root=str(out / "maps"),
        sensor_root=None,
        db_files=None,
        map_version="nuplan-maps-v1.0",
        include_cameras=False,
        verbose=False,
    )
    scenario_filter = ScenarioFilter(
        scenario_types=None,
        scenario_tokens=None,
        log_names=None,
        map_names=None,
        num_scenarios_per_type=None,
        limit_total_scenarios=None,
        timestamp_threshold_s=None,
        ego_displacement_minimum_m=None,
        expand_scenarios=False,
        remove_invalid_goals=False,
        shuffle=False,
    )
    scenarios = builder.get_scenarios(scenario_filter, Sequential())
    rows = []
    for scenario in scenarios:
        ego = scenario.initial_ego_state
        centre = Point2D(ego.rear_axle.x, ego.rear_axle.y)
        map_api = scenario.map_api
        objects = scenario.initial_tracked_objects.tracked_objects
        rows.append(
            {
                "token": scenario.token,
                "log": scenario.log_name,
                "start_us": scenario.start_time.time_us,
                "duration_s": scenario.duration_s.time_s,
                "iterations": scenario.get_number_of_iterations(),
                "ego": [ego.rear_axle.x, ego.rear_axle.y, ego.rear_axle.heading],
                "speed_mps": ego.dynamic_car_state.speed,
                "route_roadblocks": scenario.get_route_roadblock_ids(),
                "goal": None if scenario.get_mission_goal() is None else [scenario.get_mission_goal().x, scenario.get_mission_goal().y],
                "objects": len(objects),
                "object_types": sorted({o.tracked_object_type.fullname for o in objects}),
                "on_drivable_area": map_api.is_in_layer(centre, SemanticMapLayer.DRIVABLE_AREA),
                "lanes_here": [l.id for l in map_api.get_all_map_objects(centre, SemanticMapLayer.LANE)],
            }
        )
    if as_json:
        print(json.dumps({"scenarios": rows}))
    else:
        for r in rows:
            print(f"{r['log']} {r['token']}: {r['duration_s']:.1f} s, speed {r['speed_mps']:.1f} m/s, "
                  f"{r['objects']} objects, route {len(r['route_roadblocks'])} roadblocks, on drivable area {r['on_drivable_area']}")
    return 0 if rows else 1


if __name__ == "__main__":
    sys.exit(main())
