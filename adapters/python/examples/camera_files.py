"""A camera process in Python: publishes recorded camera outputs from a folder (vo.csv,
detections3d.csv, det2d.txt, imu.csv — the files ``dash2sim record`` reads, docs/cli.md) over
dash2sim's shared-memory bridge at their frame rate with ``dash2sim.camera.Publisher``,
then prints "N frames published".

The same program as examples/src/bin/camera_files.rs (Rust) and
examples/camera-c/camera_files.c: ``dash2sim record --camera`` logs the same bytes from
each (adapters/cli/tests/camera_publishers.rs).

    python camera_files.py DRIVE_DIR [--prefix P] [--speedup X] [--file-times]
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

from dash2sim.camera import DEFAULT_PREFIX, Publisher, class_id, device_now_us, micros, rotation_from_quaternion

VO_HEADER = "frame,t_s,x,y,z,qx,qy,qz,qw,session"
IMU_HEADER = "t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z"


def read_rows(path: Path, header: str | None = None) -> list[list[str]]:
    """The file's comma-separated rows (none when it does not exist), without its header."""
    if not path.exists():
        return []
    rows = []
    with path.open(newline="") as f:
        for n, row in enumerate(csv.reader(f), start=1):
            if not row or row[0].startswith("#") or (n == 1 and header is not None and row[0] == header.split(",")[0]):
                continue
            rows.append(row)
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description="Publish a folder of VO poses and detections as a camera process would.")
    parser.add_argument("dir", type=Path, help="the folder with vo.csv, detections3d.csv, det2d.txt and imu.csv")
    parser.add_argument("--prefix", default=DEFAULT_PREFIX, help="service prefix")
    parser.add_argument("--speedup", type=float, default=1.0, help="publish this many times faster")
    parser.add_argument("--file-times", action="store_true", help="stamp frames with the files' times")
    args = parser.parse_args()
    if not args.speedup > 0:
        parser.error("--speedup must be positive")

    times: dict[int, float] = {}
    poses = {}
    for row in read_rows(args.dir / "vo.csv", VO_HEADER):
        frame, t, x, y, z, qx, qy, qz, qw = int(row[0]), *map(float, row[1:9])
        times[frame] = t
        poses[frame] = ([x, y, z], rotation_from_quaternion(qw, qx, qy, qz), int(row[9]))
    boxes3d = defaultdict(list)
    for row in read_rows(args.dir / "detections3d.csv", "frame"):
        frame = int(row[0])
        times.setdefault(frame, float(row[1]))
        covariance = [float(v) if v else 0.0 for v in row[11:14]] if len(row) == 14 else [0.0] * 3
        boxes3d[frame].append((class_id(row[2]), [float(v) for v in row[3:10]], float(row[10]), covariance))
    boxes2d = defaultdict(list)
    for row in read_rows(args.dir / "det2d.txt"):
        boxes2d[int(float(row[0]))].append([float(v) for v in row[2:7]])
    imu = [[float(v) for v in row] for row in read_rows(args.dir / "imu.csv", IMU_HEADER)]

    frames = sorted(times)
    first = times[frames[0]] if frames else 0.0
    with Publisher(args.prefix) as camera:
        start, device_start = time.monotonic(), device_now_us()

        def moved(t_s: float) -> int:
            return micros(t_s) if args.file_times else device_start + micros(t_s) - micros(first)

        next_imu = 0
        for frame in frames:
            t_s = times[frame]
            wait = start + (t_s - first) / args.speedup - time.monotonic()
            if wait > 0:
                time.sleep(wait)
            # The IMU samples stamped up to this frame (a camera reads its IMU's FIFO once a frame).
            while next_imu < len(imu) and imu[next_imu][0] <= t_s:
                sample = imu[next_imu]
                camera.imu(moved(sample[0]), sample[1:4], sample[4:7])
                next_imu += 1
            t = moved(t_s)
            camera.frame(frame, t)
            if frame in poses:
                position, rotation, session = poses[frame]
                camera.vo(frame, t, position, rotation, session)
            d3 = boxes3d.get(frame, [])
            camera.detections3d(
                frame,
                t,
                [d[0] for d in d3],
                np.array([d[1] for d in d3]).reshape(-1, 7),
                [d[2] for d in d3],
                np.array([d[3] for d in d3]).reshape(-1, 3),
            )
            d2 = np.array(boxes2d.get(frame, [])).reshape(-1, 5)
            camera.detections2d(frame, t, [0] * len(d2), d2[:, :4], d2[:, 4])
        # Samples live in the publisher's shared memory: closing it at once could take the
        # last frame's away before the logger has read them.
        time.sleep(0.5)
    print(f"{len(frames)} frames published")
    return 0


if __name__ == "__main__":
    sys.exit(main())
