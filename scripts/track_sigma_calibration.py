#!/usr/bin/env python3
"""How well a finished log's stated track covariance (`TrackCovariance`) covers the truth.

For every static drum and cone track of every finished log a sweep kept (`scenario sweep
--keep`), its place relative to the finished ego where the true ego passes the true object
nearest it, across the ego's path, against the σ across the path of the covariance the log
states for it: the share within 1, 2 and 3 σ (docs/verify.md, "The objects' σ").

    track_sigma_calibration.py --dash2sim target/release/dash2sim --sweep DIR [--drivers careful,knife-edge]

Needs pyarrow, pandas and numpy (a cross-check's venv, never the product's).
"""
import argparse
import glob
import os
import subprocess
import sys

import numpy as np
import pandas as pd

# The generated drives start at this UTC second (`dash2sim_sim::scenario::write::START_UNIX_S`).
START_UNIX_S = 1780300800.0
# A track further than this from every true static object is not one of them, m.
MATCH_M = 1.5


def passes(drive, parquet):
    """(across-path error, σ across the path) of each drum and cone track of one drive."""
    tracks = pd.read_parquet(f"{parquet}/tracks3d.parquet")
    ego = pd.read_parquet(f"{parquet}/ego.parquet")
    ego_t = np.array([t.timestamp() for t in ego["t"]]) - START_UNIX_S
    objects = pd.read_csv(f"{drive}/drive/objects.csv")
    objects = objects[objects.static == 1].groupby("id").first()
    truth = np.loadtxt(f"{drive}/drive/ego.tum")
    truth_yaw = 2 * np.arctan2(truth[:, 6], truth[:, 7])
    out = []
    for _, track in tracks[tracks.is_static].groupby("track_id").first().iterrows():
        if track["class"] not in ("drum", "cone") or pd.isna(track.cov_xx_m2):
            continue
        distance = np.hypot(objects.x - track.x_m, objects.y - track.y_m)
        nearest = distance.idxmin()
        if distance[nearest] > MATCH_M:
            continue
        obj = objects.loc[nearest]
        k = np.argmin(np.hypot(truth[:, 1] - obj.x, truth[:, 2] - obj.y))
        # The finished ego's error where the true ego passes: the object's place relative to it.
        ego_dx = np.interp(truth[k, 0], ego_t, ego.x_m) - truth[k, 1]
        ego_dy = np.interp(truth[k, 0], ego_t, ego.y_m) - truth[k, 2]
        dx, dy = track.x_m - obj.x - ego_dx, track.y_m - obj.y - ego_dy
        nx, ny = -np.sin(truth_yaw[k]), np.cos(truth_yaw[k])
        across = dx * nx + dy * ny
        sigma = np.sqrt(track.cov_xx_m2 * nx * nx + 2 * track.cov_xy_m2 * nx * ny + track.cov_yy_m2 * ny * ny)
        out.append((across, sigma))
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dash2sim", required=True)
    ap.add_argument("--sweep", required=True, help="a sweep's output folder, run with --keep")
    ap.add_argument("--drivers", default="careful,knife-edge")
    args = ap.parse_args()
    rows, drives = [], 0
    for driver in args.drivers.split(","):
        for drive in sorted(glob.glob(f"{args.sweep}/drives/*-{driver}")):
            log = f"{drive}/finished.d2slog"
            if not os.path.exists(log):
                continue
            parquet = f"{drive}/finished.parquet"
            subprocess.run([args.dash2sim, "export", log, "--parquet", parquet], check=True, capture_output=True)
            rows += passes(drive, parquet)
            drives += 1
    if not rows:
        sys.exit(f"{args.sweep}: no finished drum or cone track to compare")
    a = np.array(rows)
    z = np.abs(a[:, 0]) / a[:, 1]
    print(f"{drives} drives, {len(a)} drum and cone tracks")
    print(f"across the path: error SD {a[:, 0].std():.3f} m, stated σ median {np.median(a[:, 1]):.3f} m")
    print(f"within 1σ {100 * (z < 1).mean():.1f} %, 2σ {100 * (z < 2).mean():.1f} %, 3σ {100 * (z < 3).mean():.1f} %")


if __name__ == "__main__":
    main()
