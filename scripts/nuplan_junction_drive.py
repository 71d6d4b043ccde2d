"""A drive through junctions along a nuPlan map's own lanes and lane connectors, as a TUM
trajectory in the ENU frame of a dash2sim tile (issue #15: junction maps cross-checked with
the devkit).

    VENV/bin/python scripts/nuplan_junction_drive.py --gpkg DIR/maps/NAME/9.17.1964/map.gpkg \
        --origin LAT,LON --out drive.tum [--turns left,right,straight] [--start-lane FID] \
        [--junctions N] [--seconds 45] [--speed 5]

Starts on the longest lane from which the route is long enough (and passes `--junctions`),
follows its baseline path and at every junction takes the lane
connector the next entry of `--turns` asks for (the sharpest left, the sharpest right, or the
straightest, which must be within 30°), until `--seconds` of driving at `--speed`. The path is smoothed over 0.75 s of driving (a
driver does not follow a polyline's corners) and written as rear-axle poses at 10 Hz, for
`dash2sim import --traj drive.tum --origin LAT,LON`.
"""
import argparse
import math
import sys

import geopandas as gpd
import numpy as np
import pyproj

START_S = 1780300800.0  # 2026-06-01T08:00:00Z, the scenario clock's zero
RATE_HZ = 10.0
SMOOTHING_S = 0.75  # the path is smoothed over the distance driven in this time
STRAIGHT_DEG = 30.0  # "straight" at a junction: the straightest connector, if within this


def turn_of(line):
    """Signed heading change along a line, rad (left positive)."""
    xy = np.asarray(line.coords)
    a = math.atan2(xy[1, 1] - xy[0, 1], xy[1, 0] - xy[0, 0])
    b = math.atan2(xy[-1, 1] - xy[-2, 1], xy[-1, 0] - xy[-2, 0])
    return (b - a + math.pi) % (2 * math.pi) - math.pi


def route(gpkg, turns, metres, start_lane=None, junctions=0):
    lanes = gpd.read_file(gpkg, layer="lanes_polygons")
    baselines = gpd.read_file(gpkg, layer="baseline_paths")
    connectors = gpd.read_file(gpkg, layer="lane_connectors", fid_as_index=True)
    lane_line = {int(r.lane_fid): r.geometry for r in baselines.itertuples() if r.lane_fid == r.lane_fid}
    connector_line = {
        int(r.lane_connector_fid): r.geometry for r in baselines.itertuples() if r.lane_connector_fid == r.lane_connector_fid
    }
    best = ([], [])
    starts = [start_lane] if start_lane is not None else sorted(lane_line, key=lambda f: -lane_line[f].length)
    for start in starts:
        lane, points, taken, k = start, list(lane_line[start].coords), [f"lane {start}"], 0
        while sum(math.dist(a, b) for a, b in zip(points, points[1:])) < metres:
            out = connectors[connectors.exit_lane_fid == lane]
            if out.empty:
                break
            want = turns[k % len(turns)]
            k += 1
            scored = [
                (turn_of(connector_line[int(c.Index)]), int(c.Index), int(c.entry_lane_fid)) for c in out.itertuples()
            ]
            if want == "left":
                turn, connector, lane = max(scored)
            elif want == "right":
                turn, connector, lane = min(scored)
            else:
                turn, connector, lane = min(scored, key=lambda t: abs(t[0]))
                if abs(turn) > math.radians(STRAIGHT_DEG):
                    break
            taken.append(f"{want} ({math.degrees(turn):.0f}°) via connector {connector} to lane {lane}")
            points += list(connector_line[connector].coords)[1:] + list(lane_line[lane].coords)[1:]
        long_enough = sum(math.dist(a, b) for a, b in zip(points, points[1:])) >= metres
        if len(taken) > len(best[1]) or long_enough:
            best = (points, taken)
            if long_enough and len(taken) > junctions:
                break
    points, taken = best
    return np.asarray(points), taken, lanes.crs


def resample(points, step):
    seg = np.hypot(*np.diff(points, axis=0).T)
    keep = np.concatenate([[True], seg > 1e-6])
    points = points[keep]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))])
    at = np.arange(0.0, s[-1], step)
    return np.column_stack([np.interp(at, s, points[:, 0]), np.interp(at, s, points[:, 1])])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--gpkg", required=True)
    ap.add_argument("--origin", required=True, help="LAT,LON of the tile")
    ap.add_argument("--out", required=True)
    ap.add_argument("--turns", default="left,right,straight")
    ap.add_argument("--start-lane", type=int, help="lane_fid to start on (default: the longest that works)")
    ap.add_argument("--junctions", type=int, default=0, help="pass at least this many junctions")
    ap.add_argument("--seconds", type=float, default=45.0)
    ap.add_argument("--speed", type=float, default=5.0)
    args = ap.parse_args()
    turns = args.turns.split(",")
    if any(t not in ("left", "right", "straight") for t in turns):
        sys.exit(f"--turns: each entry is left, right or straight, not {args.turns!r}")
    metres = args.seconds * args.speed
    points, taken, crs = route(args.gpkg, turns, metres + 10.0, args.start_lane, args.junctions)
    fine = resample(points, 0.1)
    if len(fine) * 0.1 < metres:
        sys.exit(f"the route ends after {len(fine) * 0.1:.0f} m (a dead end); {metres:.0f} m asked: {taken}")
    window = max(int(SMOOTHING_S * args.speed / 0.1), 1)
    kernel = np.ones(window) / window
    padded = np.pad(fine, ((window // 2, window - window // 2 - 1), (0, 0)), mode="edge")
    smooth = np.column_stack([np.convolve(padded[:, i], kernel, mode="valid") for i in range(2)])
    poses = resample(smooth, args.speed / RATE_HZ)[: int(args.seconds * RATE_HZ) + 1]
    # Projected → ECEF → ENU around the tile's origin.
    lat0, lon0 = (float(v) for v in args.origin.split(","))
    to_ecef = pyproj.Transformer.from_crs(crs, "EPSG:4978", always_xy=True)
    x, y, z = to_ecef.transform(poses[:, 0], poses[:, 1], np.zeros(len(poses)))
    x0, y0, z0 = pyproj.Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True).transform(lon0, lat0, 0.0)
    phi, lam = math.radians(lat0), math.radians(lon0)
    d = np.vstack([x - x0, y - y0, z - z0])
    east = -math.sin(lam) * d[0] + math.cos(lam) * d[1]
    north = -math.sin(phi) * math.cos(lam) * d[0] - math.sin(phi) * math.sin(lam) * d[1] + math.cos(phi) * d[2]
    yaw = np.arctan2(np.gradient(north), np.gradient(east))
    with open(args.out, "w") as f:
        for k in range(len(poses)):
            f.write(
                f"{START_S + k / RATE_HZ:.3f} {east[k]:.3f} {north[k]:.3f} 0 0 0 "
                f"{math.sin(yaw[k] / 2):.6f} {math.cos(yaw[k] / 2):.6f}\n"
            )
    print(f"{args.out}: {len(poses)} poses, {(len(poses) - 1) / RATE_HZ:.1f} s; " + "; ".join(taken))


if __name__ == "__main__":
    main()
