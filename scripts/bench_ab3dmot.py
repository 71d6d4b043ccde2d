#!/usr/bin/env python3
"""The peer for `cargo bench -p dash2sim-linux --bench track3d`: an AB3DMOT-style frame
loop (Weng et al. 2020) on filterpy + scipy, on the same input — 64 cars, 64 detections
per frame (the formula below is the bench's), 10 warm-up frames, then 50 timed frames.

Per frame, as AB3DMOT does it: predict every track (filterpy `KalmanFilter`, AB3DMOT's
F/H/P/Q/R), a 64 × 64 affinity matrix of 3D GIoU (bird's-eye polygons clipped by
Sutherland–Hodgman, their area and the enclosing area from `scipy.spatial.ConvexHull`,
times the height overlap / union), `scipy.optimize.linear_sum_assignment` on it, the
GIoU > −0.2 gate, the orientation correction and the update of matched tracks, new tracks
for unmatched detections, retirement after 2 misses. Best of 3 runs.

Usage: /tmp/venv/bin/python scripts/bench_ab3dmot.py
(filterpy, numpy and scipy in a venv; never a runtime dependency.)
"""
import copy
import math
import time

import numpy as np
from filterpy.kalman import KalmanFilter
from scipy.optimize import linear_sum_assignment
from scipy.spatial import ConvexHull

OBJECTS, WARM_UP, TIMED = 64, 10, 50


def detections(k):
    out = []
    for j in range(OBJECTS):
        i = (j * 37 + k) % OBJECTS
        x = 10.0 * (i % 8) + (0.3 + 0.01 * i) * k + 0.1 * math.sin(1.7 * i + 0.9 * k)
        y = 10.0 * (i // 8) + (0.2 - 0.005 * i) * k + 0.1 * math.cos(2.3 * i + 1.1 * k)
        yaw = 0.1 * i + 0.02 * math.sin(i + k)
        out.append(np.array([x, y, 0.8, yaw, 4.5, 1.9, 1.6]))
    return out


def footprint(b):
    c, s = math.cos(b[3]), math.sin(b[3])
    hl, hw = b[4] / 2, b[5] / 2
    return [(b[0] + dl * c - dw * s, b[1] + dl * s + dw * c) for dl, dw in ((hl, hw), (-hl, hw), (-hl, -hw), (hl, -hw))]


def clip(subject, clipper):
    """Sutherland–Hodgman: `subject` clipped by the convex, counter-clockwise `clipper`."""
    output = subject
    for a, b in zip(clipper, clipper[1:] + clipper[:1]):
        inside = lambda p: (b[0] - a[0]) * (p[1] - a[1]) > (b[1] - a[1]) * (p[0] - a[0])
        def cut(p, q):
            d1, d2 = (a[0] - b[0], a[1] - b[1]), (p[0] - q[0], p[1] - q[1])
            n1, n2 = a[0] * b[1] - a[1] * b[0], p[0] * q[1] - p[1] * q[0]
            den = d1[0] * d2[1] - d1[1] * d2[0]
            return ((n1 * d2[0] - n2 * d1[0]) / den, (n1 * d2[1] - n2 * d1[1]) / den)
        points, output = output, []
        if not points:
            return []
        previous = points[-1]
        for p in points:
            if inside(p):
                if not inside(previous):
                    output.append(cut(previous, p))
                output.append(p)
            elif inside(previous):
                output.append(cut(previous, p))
            previous = p
    return output


def giou_3d(a, b):
    pa, pb = footprint(a), footprint(b)
    inter = clip(pa, pb)
    inter_area = ConvexHull(np.array(inter)).volume if len(inter) >= 3 else 0.0
    enclosing = ConvexHull(np.array(pa + pb)).volume
    za, zb = (a[2] - a[6] / 2, a[2] + a[6] / 2), (b[2] - b[6] / 2, b[2] + b[6] / 2)
    overlap = max(0.0, min(za[1], zb[1]) - max(za[0], zb[0]))
    joint = max(za[1], zb[1]) - min(za[0], zb[0])
    i3 = inter_area * overlap
    u3 = a[4] * a[5] * a[6] + b[4] * b[5] * b[6] - i3
    c3 = enclosing * joint
    return i3 / u3 - (c3 - u3) / c3


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


class Track:
    def __init__(self, box, ident):
        kf = KalmanFilter(dim_x=10, dim_z=7)
        kf.F = np.eye(10)
        kf.F[0, 7] = kf.F[1, 8] = kf.F[2, 9] = 1.0
        kf.H = np.zeros((7, 10))
        kf.H[:7, :7] = np.eye(7)
        kf.P[7:, 7:] *= 1000.0
        kf.P *= 10.0
        kf.Q[7:, 7:] *= 0.01
        kf.R = np.eye(7)
        kf.x[:7, 0] = box
        self.kf, self.id, self.hits, self.since_update = kf, ident, 1, 0


def frame(tracks, dets, next_id):
    for t in tracks:
        t.kf.predict()
        t.kf.x[3, 0] = wrap(t.kf.x[3, 0])
        t.since_update += 1
    predicted = [t.kf.x[:7, 0] for t in tracks]
    affinity = np.zeros((len(dets), len(tracks)))
    for d, det in enumerate(dets):
        for t, trk in enumerate(predicted):
            affinity[d, t] = giou_3d(det, trk)
    rows, cols = linear_sum_assignment(-affinity)
    matched = set()
    for d, t in zip(rows, cols):
        if affinity[d, t] < -0.2:
            continue
        matched.add(d)
        kf, z = tracks[t].kf, dets[d].copy()
        if abs(wrap(z[3] - kf.x[3, 0])) > math.pi / 2:
            kf.x[3, 0] = wrap(kf.x[3, 0] + math.pi)
        z[3] = kf.x[3, 0] + wrap(z[3] - kf.x[3, 0])
        kf.update(z)
        kf.x[3, 0] = wrap(kf.x[3, 0])
        tracks[t].hits += 1
        tracks[t].since_update = 0
    tracks[:] = [t for t in tracks if t.since_update <= 2]
    for d, det in enumerate(dets):
        if d not in matched:
            tracks.append(Track(det, next_id))
            next_id += 1
    return next_id


def main():
    frames = [detections(k) for k in range(WARM_UP + TIMED)]
    tracks, next_id = [], 1
    for dets in frames[:WARM_UP]:
        next_id = frame(tracks, dets, next_id)
    assert len(tracks) == OBJECTS and next_id == OBJECTS + 1, (len(tracks), next_id)
    best = math.inf
    for _ in range(3):
        run = copy.deepcopy(tracks)
        start = time.perf_counter()
        ids = next_id
        for dets in frames[WARM_UP:]:
            ids = frame(run, dets, ids)
        best = min(best, time.perf_counter() - start)
        assert ids == next_id and len(run) == OBJECTS, "every detection matched its track"
    print(f"AB3DMOT-style filterpy + scipy loop: {TIMED} frames of 64 x 64 in {best * 1e3:.1f} ms, "
          f"{best / TIMED * 1e3:.2f} ms per frame")


if __name__ == "__main__":
    main()
