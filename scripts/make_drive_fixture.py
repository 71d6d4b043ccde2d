#!/usr/bin/env python3
"""Generate tests/fixtures/drive: a small synthetic drive with known truth.

Deterministic (seeded), standard library only. It writes
  truth.tum  ground-truth poses in a local ENU frame (20 Hz, identity orientation)
  vo.tum     the same motion as a monocular VO would report it: unknown scale (0.5 m per
             unit), arbitrary orientation, 1 %/min scale drift, 1 deg/min yaw drift
  gnss.tum   10 Hz fixes stamped at receive time, 80 ms after the instant they describe,
             with a slowly wandering error (~0.25 m per axis, 20 s correlation — about
             what the real u-blox fixes of comma2k19 show after alignment) plus 0.1 m
             white noise
  speed.csv  50 Hz wheel speed reading 1 % low
Usage: python3 scripts/make_drive_fixture.py tests/fixtures/drive
"""
import math
import os
import random
import sys

SECONDS = 40.0
LATENCY = 0.080


def truth(t):
    """Speed 8 -> 20 m/s, a 90 degree bend, a gentle hill."""
    s = 8.0 * t + 0.15 * t * t
    radius = 250.0
    heading = max(0.0, s - 150.0) / radius if s < 150.0 + radius * math.pi / 2 else math.pi / 2
    if s < 150.0:
        x, y = s, 0.0
    elif s < 150.0 + radius * math.pi / 2:
        x, y = 150.0 + radius * math.sin(heading), radius * (1 - math.cos(heading))
    else:
        x, y = 150.0 + radius, radius + (s - 150.0 - radius * math.pi / 2)
    return (x, y, 3.0 * math.sin(t / 9.0))


def speed(t):
    return 8.0 + 0.3 * t


def rot(axis, angle):
    n = math.sqrt(sum(a * a for a in axis))
    x, y, z = (a / n for a in axis)
    c, s, C = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return [[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C]]


def main(out):
    os.makedirs(out, exist_ok=True)
    rng = random.Random(2)
    r0 = rot((0.3, -0.8, 0.5), 1.7)
    with open(os.path.join(out, "truth.tum"), "w") as ft, open(os.path.join(out, "vo.tum"), "w") as fv:
        ft.write("# t x y z qx qy qz qw  (ENU, m)\n")
        fv.write("# t x y z qx qy qz qw  (VO frame, unknown scale)\n")
        vo = [0.0, 0.0, 0.0]
        prev = truth(0.0)
        for k in range(int(SECONDS * 20) + 1):
            t = k / 20.0
            p = truth(t)
            if k > 0:
                scale = 0.5 * (1 + 0.01 * t / 60)
                yaw = math.radians(1.0 * t / 60)
                r = [[sum(rot((0, 0, 1), yaw)[i][m] * r0[m][j] for m in range(3)) for j in range(3)] for i in range(3)]
                d = [p[i] - prev[i] for i in range(3)]
                for j in range(3):  # x += R^T d / s
                    vo[j] += sum(r[i][j] * d[i] for i in range(3)) / scale
            prev = p
            ft.write(f"{t:.3f} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f} 0 0 0 1\n")
            fv.write(f"{t:.3f} {vo[0]:.6f} {vo[1]:.6f} {vo[2]:.6f} 0 0 0 1\n")
    with open(os.path.join(out, "gnss.tum"), "w") as fg:
        fg.write("# t_receive x y z qx qy qz qw  (ENU, m; orientation unused)\n")
        bias = [0.0, 0.0, 0.0]
        for k in range(1, int(SECONDS * 10) + 1):
            t = k / 10.0
            p = truth(t - LATENCY)
            bias = [0.995 * b + rng.gauss(0.0, 0.025) for b in bias]
            q = [p[i] + bias[i] + rng.gauss(0.0, 0.1) for i in range(3)]
            fg.write(f"{t:.3f} {q[0]:.4f} {q[1]:.4f} {q[2]:.4f} 0 0 0 1\n")
    with open(os.path.join(out, "speed.csv"), "w") as fs:
        fs.write("t_s,speed_mps\n")
        for k in range(int(SECONDS * 50) + 1):
            t = k / 50.0
            fs.write(f"{t:.3f},{0.99 * speed(t):.4f}\n")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    main(sys.argv[1])
