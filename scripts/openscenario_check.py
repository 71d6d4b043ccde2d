"""The ASAM tool chain on `dash2sim export --openscenario` (issue #59).

    VENV/bin/python scripts/openscenario_check.py --dash2sim target/release/dash2sim \
        --log LOG --map MAP --out DIR [--scenario-seconds S] [--json]

1. `dash2sim export LOG --openscenario DIR --map MAP [--scenario-seconds S]` writes
   `DIR/road.xodr` (OpenDRIVE 1.7) and the scenarios (`DIR/scenario*.xosc`, OpenSCENARIO 1.0);
2. the ASAM Quality Checker's bundles judge them: `asam-qc-opendrive` on the road and
   `asam-qc-openscenarioxml` on every scenario, each with the standard's XSD among its checks.
   An issue of level error fails the check; warnings and information are listed;
3. the road read back by the Quality Checker's own OpenDRIVE evaluation
   (`qc_opendrive.base.utils`: reference line, lane offset, widths): the middle of every lane
   of every road, every 0.5 m, against the tile's lane centres (`dash2sim map lanes`, its ENU
   frame at `dash2sim map info`'s origin carried into the `.xodr`'s by pyproj: ENU → geodetic → the `<geoReference>`'s UTM
   zone, less the `<offset>`). Every such point must lie within `--lane-tolerance` (0.1 m) of
   a tile lane;
4. every scenario read back by scenariogeneration's parser (`xosc.ParseOpenScenario`): its
   entities, the ego's trajectory and the tracks' against the log, in the same frame —
   * the ego: at every pose of the log inside the window (`dash2sim export --tum`), the
     trajectory interpolated at the pose's time (the window's start is the scenario's
     `log_start_s` parameter) lies within `--tolerance` (0.01 m) of it — a millisecond's
     shift at 10 m/s would already be 1 cm;
   * the tracks (`dash2sim export --parquet`, `tracks3d.parquet`): every moving entity's box
     centre at each vertex (its reference point plus the bounding box's centre along its
     heading) within 0.01 m of the track's state in the log's frame of tracks nearest the
     vertex (within 0.1 s) moved on by its velocity over the difference (a state flagged
     static not moved) — the export's own rule; a vertex whose nearest frame lacks the track is bridged between states, not a
     logged one, and is not checked; every static entity inside the box of its track's
     positions in the window (or before it: a static object stands where it was seen after
     the camera has lost it), grown by 0.01 m; and every track the log holds inside the
     window is an entity.

The script prints a table per file and exits 1 on an error-level issue or a disagreement.
With `--picture F.png` (needs matplotlib) it draws a scenario as read back: the road's
lanes by the Quality Checker's evaluation (borders every 0.5 m), every entity's box where it
starts, the moving ones' paths (docs/openscenario.md shows one).
"""
import bisect
import json
import logging
import math
import re
import subprocess
import sys
from pathlib import Path

import peer_cli

from lxml import etree
from pyproj import Transformer
from qc_baselib import Configuration, IssueSeverity, Result

import qc_opendrive.constants
import qc_opendrive.main
import qc_openscenario.constants
import qc_openscenario.main
from qc_opendrive.base import utils as xodr
from scenariogeneration import xosc

# The checkers' bundles log every step at INFO: their issues are what this script reports.
logging.getLogger().setLevel(logging.WARNING)


def quality_check(bundle, main, path: Path) -> dict:
    """One ASAM Quality Checker bundle on `path`: issues by level, and the error texts."""
    config = Configuration()
    config.set_config_param("InputFile", str(path))
    config.register_checker_bundle(bundle.BUNDLE_NAME)
    result = Result()
    result.register_checker_bundle(name=bundle.BUNDLE_NAME, description="", version=bundle.BUNDLE_VERSION,
                                   summary="")
    result.set_result_version(version=bundle.BUNDLE_VERSION)
    main.run_checks(config, result)
    levels, errors, others, checkers = {}, [], {}, 0
    for checker in result.get_checker_results(bundle.BUNDLE_NAME):
        checkers += 1
        for issue in checker.issues:
            name = IssueSeverity(issue.level).name.lower()
            levels[name] = levels.get(name, 0) + 1
            if issue.level == IssueSeverity.ERROR:
                errors.append(f"{checker.checker_id}: {issue.description}")
            else:
                key = f"{name}: {checker.checker_id}: {issue.description}"
                others[key] = others.get(key, 0) + 1
    return {"checkers": checkers, "issues": levels, "errors": errors, "others": others}


def to_xodr_frame(root, origin: dict):
    """A function from ENU points at `origin` (a dict with lat, lon, height) to the `.xodr`'s
    frame: its geoReference's projection less its offset."""
    proj = root.find("header/geoReference").text.strip()
    offset = root.find("header/offset")
    dx, dy = float(offset.get("x")), float(offset.get("y"))
    t = Transformer.from_pipeline(
        f"+proj=pipeline +step +inv +proj=topocentric +ellps=WGS84 +lat_0={origin['lat']} "
        f"+lon_0={origin['lon']} +h_0={origin['height']} +step +inv +proj=cart +ellps=WGS84 "
        f"+step {proj.replace('+no_defs', '').replace('+datum=WGS84', '+ellps=WGS84')}")

    def convert(points):
        out = []
        for e, n, u in points:
            x, y, _ = t.transform(e, n, u)
            out.append((x - dx, y - dy))
        return out
    return convert


def distance_to_lines(p, lines) -> float:
    best = math.inf
    for line in lines:
        for (ax, ay), (bx, by) in zip(line, line[1:]):
            dx, dy = bx - ax, by - ay
            l2 = dx * dx + dy * dy
            f = 0.0 if l2 == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / l2))
            best = min(best, math.hypot(p[0] - ax - dx * f, p[1] - ay - dy * f))
    return best


def lane_centres(root) -> list:
    """The middle of every lane of every road outside junctions, every 0.5 m, by the
    Quality Checker's own OpenDRIVE evaluation."""
    points = []
    for road in xodr.get_roads(root):
        if xodr.road_belongs_to_junction(road):
            continue
        length = xodr.get_road_length(road)
        for section in xodr.get_lane_sections(road):
            for lane in xodr.get_right_lanes_from_lane_section(section):
                steps = max(1, int(length / 0.5))
                for k in range(steps + 1):
                    p = xodr.get_middle_point_xyz_at_height_zero_from_lane_by_s(road, section, lane,
                                                                                min(length, k * 0.5))
                    if p is not None:
                        points.append((p.x, p.y))
    return points


def world(position):
    w = position.get_element().find("WorldPosition")
    return float(w.get("x")), float(w.get("y")), float(w.get("h", 0))


def trajectories(path: Path) -> dict:
    """Entity name → list of (time, x, y, h) from the scenario's FollowTrajectoryActions, read
    by scenariogeneration; and name → (x, y, h) of the Init's teleports."""
    scenario = xosc.ParseOpenScenario(str(path))
    entities = [e.name for e in scenario.entities.scenario_objects]
    boxes, widths = {}, {}
    for e in scenario.entities.scenario_objects:
        bb = e.entityobject.boundingbox
        boxes[e.name] = (bb.center.x, bb.boundingbox.length)
        widths[e.name] = bb.boundingbox.width
    paths = {}
    for story in scenario.storyboard.stories:
        for act in story.acts:
            for group in act.maneuvergroup:
                for maneuver in group.maneuvers:
                    for event in maneuver.events:
                        for action in event.action:
                            element = action.action.get_element()
                            if element.find(".//FollowTrajectoryAction") is None:
                                continue
                            name = group.actors.actors[0].entity
                            shape = action.action.trajectory.shapes
                            paths[name] = [(float(t), *world(p)) for t, p in zip(shape.time, shape.positions)]
    placed = {}
    init = scenario.storyboard.init.get_element()
    for private in init.findall(".//Private"):
        w = private.find(".//TeleportAction/Position/WorldPosition")
        placed[private.get("entityRef")] = (float(w.get("x")), float(w.get("y")), float(w.get("h")))
    start = None
    for p in scenario.parameters.parameters:
        if p.name == "log_start_s":
            start = float(p.value)
    return {"entities": entities, "boxes": boxes, "widths": widths, "paths": paths, "placed": placed,
            "start": start}


def interpolate(path, t):
    times = [p[0] for p in path]
    i = bisect.bisect_left(times, t)
    if i <= 0:
        return path[0][1:3]
    if i >= len(path):
        return path[-1][1:3]
    a, b = path[i - 1], path[i]
    f = (t - a[0]) / (b[0] - a[0]) if b[0] > a[0] else 0.0
    return a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f


def check_scenario(path: Path, read: dict, ego_log, tracks, convert, step: float, tolerance: float) -> dict:
    out = {"file": path.name, "entities": len(read["entities"]), "problems": []}
    ego = read["paths"].get("Ego")
    start = read["start"]
    if ego is None or start is None:
        out["problems"].append("no ego trajectory or no log_start_s")
        return out
    end = start + ego[-1][0]
    inside = [p for p in ego_log if start - 1e-6 <= p[0] <= end + 1e-6]
    xy = convert([p[1:4] for p in inside])
    worst_ego = 0.0
    for (t, *_), q in zip(inside, xy):
        x, y = interpolate(ego, t - start)
        worst_ego = max(worst_ego, math.hypot(x - q[0], y - q[1]))
    out["ego_poses"], out["ego_worst_m"] = len(inside), worst_ego
    if not inside or worst_ego > tolerance:
        out["problems"].append(f"ego: {len(inside)} log poses, worst {worst_ego:.4f} m from the trajectory")
    # Tracks: the log's inside the window, each an entity.
    by_id, before = {}, {}
    for row in tracks:
        if start - step / 2 <= row["t"] <= end + step / 2:
            by_id.setdefault(row["track_id"], []).append(row)
        elif row["t"] < start and row["is_static"]:
            before.setdefault(row["track_id"], []).append(row)
    names = {}
    for name in read["entities"]:
        m = re.fullmatch(r"[a-z_]+-(\d+)(?:-\d+)?", name)
        if m:
            names.setdefault(int(m.group(1)), []).append(name)
    missing = sorted(set(by_id) - set(names))
    out["tracks"], out["missing"] = len(by_id), missing
    if missing:
        out["problems"].append(f"{len(missing)} tracks of the log are no entity: {missing[:10]}")
    # The times of the log's frames of 3D tracks (each a batch of every track it saw), µs.
    frames = sorted({row["t_us"] for row in tracks})
    start_us, step_us = round(start * 1e6), round(step * 1e6)
    worst_moving, worst_static, vertices = 0.0, 0.0, 0
    for track_id, entity_names in names.items():
        # A static object seen before the window stands where it was seen (`verify` and the
        # other exports keep it there after the camera has lost it).
        rows = sorted(by_id.get(track_id) or before.get(track_id, []), key=lambda r: r["t"])
        moving = [n for n in entity_names if n in read["paths"]]
        if not rows or (moving and track_id not in by_id):
            out["problems"].append(f"entities {entity_names} have no track in the log's window")
            continue
        positions = convert([(r["x_m"], r["y_m"], r["z_m"]) for r in rows])
        for name in entity_names:
            ahead, _ = read["boxes"][name]
            if name not in read["paths"]:
                x, y, h = read["placed"][name]
                cx, cy = x + ahead * math.cos(h), y + ahead * math.sin(h)
                xs, ys = [p[0] for p in positions], [p[1] for p in positions]
                d = max(min(xs) - cx, cx - max(xs), min(ys) - cy, cy - max(ys), 0.0)
                worst_static = max(worst_static, d)
                continue
            by_time = {r["t_us"]: r for r in rows}
            for t, x, y, h in read["paths"][name]:
                at, at_us = start + t, start_us + round(t * 1e6)
                # The log's frame nearest the vertex's time, as the export takes it (in whole
                # microseconds, the earlier of two as near): the track's state there, or — the
                # track missing from that frame — a vertex bridged linearly between the states
                # around it (not a logged state: not checked).
                k = bisect.bisect_left(frames, at_us)
                near = [f for f in frames[max(0, k - 1):k + 1] if abs(f - at_us) <= step_us]
                if not near:
                    continue
                r = by_time.get(min(near, key=lambda f: (abs(f - at_us), f)))
                if r is None:
                    continue
                vertices += 1
                # A state flagged static does not move (the log's views give it no velocity).
                dt = 0.0 if r["is_static"] else at - r["t"]
                moved = convert([(r["x_m"] + r["vx_mps"] * dt, r["y_m"] + r["vy_mps"] * dt, r["z_m"])])[0]
                cx, cy = x + ahead * math.cos(h), y + ahead * math.sin(h)
                worst_moving = max(worst_moving, math.hypot(cx - moved[0], cy - moved[1]))
    out["track_vertices"], out["moving_worst_m"], out["static_outside_m"] = vertices, worst_moving, worst_static
    if worst_moving > tolerance:
        out["problems"].append(f"a moving entity {worst_moving:.4f} m from its track")
    if worst_static > tolerance:
        out["problems"].append(f"a static entity {worst_static:.4f} m outside its track's positions")
    return out


def lane_borders(root) -> list:
    """Every lane's two borders, every 0.5 m, as polylines (junctions' included)."""
    lines = []
    for road in xodr.get_roads(root):
        length = xodr.get_road_length(road)
        steps = max(1, int(length / 0.5))
        stations = [min(length, k * 0.5) for k in range(steps + 1)]
        for section in xodr.get_lane_sections(road):
            lanes = xodr.get_right_lanes_from_lane_section(section)
            s0 = xodr.get_s_from_lane_section(section)
            borders = {}
            for s in stations:
                offset = xodr.get_lane_offset_value_from_road_by_s(road, s)
                outer = xodr.get_outer_border_points_from_lane_group_by_s(lanes, offset, s0, s)
                outer[0] = offset
                for lane_id, t in outer.items():
                    p = xodr.get_point_xyz_from_road(road, s, t, 0.0)
                    borders.setdefault(lane_id, []).append((p.x, p.y))
            lines.extend(borders.values())
    return lines


def picture(root, read: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon as Patch
    fig, ax = plt.subplots(figsize=(12, 5), dpi=120)
    for line in lane_borders(root):
        ax.plot([p[0] for p in line], [p[1] for p in line], color="0.6", lw=0.6)
    for name in read["entities"]:
        path_ = read["paths"].get(name)
        x, y, h = (path_[0][1:] if path_ else read["placed"][name])
        ahead, length = read["boxes"][name]
        width = read["widths"][name]
        c, s = math.cos(h), math.sin(h)
        cx, cy = x + ahead * c, y + ahead * s
        corners = [(cx + c * a - s * b, cy + s * a + c * b)
                   for a, b in ((length / 2, width / 2), (-length / 2, width / 2), (-length / 2, -width / 2),
                                (length / 2, -width / 2))]
        colour = "tab:red" if name == "Ego" else ("tab:blue" if path_ else "tab:orange")
        ax.add_patch(Patch(corners, closed=True, facecolor=colour, alpha=0.7, lw=0))
        if path_:
            ax.plot([p[1] for p in path_], [p[2] for p in path_], color=colour, lw=0.8)
    ax.set_aspect("equal")
    xs = [p[1] for p in read["paths"]["Ego"]]
    ys = [p[2] for p in read["paths"]["Ego"]]
    ax.set_xlim(min(xs) - 20, max(xs) + 20)
    ax.set_ylim(min(ys) - 25, max(ys) + 25)
    ax.set_xlabel("x, m (the .xodr's frame: UTM less the map origin)")
    ax.set_ylabel("y, m")
    ax.set_title("road.xodr read by the ASAM Quality Checker's evaluation; the scenario's entities where they "
                 "start (ego red, moving blue, static orange) and the paths they follow", fontsize=9)
    fig.tight_layout()
    fig.savefig(path)


def read_tracks(dash2sim: str, log: str, out: Path) -> list:
    import pyarrow.parquet as pq
    folder = out / "log.parquet"
    subprocess.run([dash2sim, "export", log, "--parquet", str(folder)], check=True, stdout=subprocess.DEVNULL)
    import pyarrow as pa
    table = pq.read_table(folder / "tracks3d.parquet")
    # `t` is a UTC timestamp; as seconds since the epoch, as TUM's and `log_start_s` are.
    unit = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}[table.schema.field("t").type.unit]
    raw = table.column("t").cast(pa.int64()).to_pylist()
    rows = table.drop(["t"]).to_pylist()
    for row, v in zip(rows, raw):
        row["t"] = v * unit
        # The log counts in whole microseconds; frames are matched to ticks in them.
        row["t_us"] = round(v * unit * 1e6)
    return rows


def main() -> int:
    p = peer_cli.parser(__doc__.split("\n")[0])
    p.add_argument("--scenario-seconds", type=float)
    p.add_argument("--tolerance", type=float, default=0.01, help="trajectories against the log, m")
    p.add_argument("--lane-tolerance", type=float, default=0.1, help="lane centres against the tile's, m")
    p.add_argument("--picture", help="draw a scenario as read back into this PNG (needs matplotlib)")
    p.add_argument("--picture-scenario", type=int, default=1, help="which scenario --picture draws (1: the first)")
    args = p.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    folder = out / "openscenario"
    cmd = [args.dash2sim, "export", args.log, "--map", args.map, "--openscenario", str(folder)]
    if args.scenario_seconds:
        cmd += ["--scenario-seconds", str(args.scenario_seconds)]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    failed = False
    report = {"road": {}, "scenarios": []}

    road = folder / "road.xodr"
    qc = quality_check(qc_opendrive.constants, qc_opendrive.main, road)
    root = xodr.get_root_without_default_namespace(str(road))
    tile = json.loads(subprocess.run([args.dash2sim, "map", "lanes", args.map], check=True,
                                     capture_output=True, text=True).stdout)
    # The tile's origin with its height (`map lanes` gives latitude and longitude only).
    origin = json.loads(subprocess.run([args.dash2sim, "map", "info", args.map, "--json"], check=True,
                                       capture_output=True, text=True).stdout)["origin"]
    to_road = to_xodr_frame(root, {"lat": origin["lat"], "lon": origin["lon"], "height": origin["height_m"]})
    tile_lanes = [to_road([(x, y, 0.0) for x, y in lane["points"]]) for lane in tile["lanes"]]
    centres = lane_centres(root)
    worst_lane = max((distance_to_lines(c, tile_lanes) for c in centres), default=math.inf)
    report["road"] = {"quality_checker": qc, "lane_points": len(centres), "lane_worst_m": worst_lane}
    print(f"{road}: {len(xodr.get_roads(root))} roads, {len(xodr.get_junctions(root))} junctions; "
          f"{qc['checkers']} ASAM checkers, issues {qc['issues'] or 'none'}; {len(centres)} lane-centre "
          f"points within {worst_lane:.3f} m of the tile's lanes")
    for e in qc["errors"]:
        print(f"  error: {e}")
    for what, n in qc["others"].items():
        print(f"  {n} × {what}")
    if qc["errors"] or worst_lane > args.lane_tolerance:
        failed = True

    info = json.loads(subprocess.run([args.dash2sim, "inspect", args.log, "--json"], check=True,
                                     capture_output=True, text=True).stdout)
    to_log = to_xodr_frame(root, info["header"]["origin"])
    tum = out / "log.tum"
    subprocess.run([args.dash2sim, "export", args.log, "--tum", str(tum)], check=True, stdout=subprocess.DEVNULL)
    ego_log = [tuple(map(float, line.split()[:4])) for line in tum.read_text().splitlines()
               if line and not line.startswith("#")]
    tracks = read_tracks(args.dash2sim, args.log, out)
    for k, scenario in enumerate(sorted(folder.glob("*.xosc"))):
        qc = quality_check(qc_openscenario.constants, qc_openscenario.main, scenario)
        read = trajectories(scenario)
        if args.picture and k + 1 == args.picture_scenario:
            picture(root, read, Path(args.picture))
        result = check_scenario(scenario, read, ego_log, tracks, to_log, 0.1, args.tolerance)
        result["quality_checker"] = qc
        report["scenarios"].append(result)
        print(f"{scenario}: {result['entities']} entities ({result.get('tracks', 0)} tracks of the log), "
              f"{qc['checkers']} ASAM checkers, issues {qc['issues'] or 'none'}; ego {result.get('ego_poses', 0)} "
              f"poses within {result.get('ego_worst_m', math.inf):.4f} m; {result.get('track_vertices', 0)} track "
              f"vertices within {result.get('moving_worst_m', 0):.4f} m, static entities "
              f"{result.get('static_outside_m', 0):.4f} m outside their tracks")
        for e in qc["errors"] + result["problems"]:
            print(f"  error: {e}")
        failed |= bool(qc["errors"] or result["problems"])
    if args.json:
        print(json.dumps(report, indent=1, default=str))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
