#!/usr/bin/env python3
"""Record filterpy's KalmanFilter with AB3DMOT's settings on a synthetic object track,
for `tests/tests/ekf_filterpy.rs` (the core `ekf` must reproduce it within 1e-9).

AB3DMOT (Weng et al. 2020): state [x y z θ l w h vx vy vz], constant velocity,
P = diag(10×7, 1e4×3), Q = I with the velocity block 0.01, R = I (7 × 7), H = [I7 0].
The measurements are a car at 8 m/s with noise (seeded); every 5th frame is a miss
(predict only). Output: one line per step —
`kind,z0..z6,x0..x9,P00..P99` (kind 0 = initial, 1 = predict, 2 = update), then one line
per frame (0..40) with filterpy's `rts_smoother` over the frames' posteriors (kind 3).

Usage: /tmp/venv/bin/python scripts/make_ekf_fixture.py > tests/fixtures/ekf_ab3dmot_filterpy.csv
(filterpy 2.0.0 and numpy in a venv; never a runtime dependency.)
"""
import numpy as np
from filterpy.kalman import KalmanFilter


def row(kind, z, kf):
    values = [kind] + list(z) + list(kf.x.ravel()) + list(kf.P.ravel())
    return ",".join(repr(float(v)) if i else str(v) for i, v in enumerate(values))


def main():
    rng = np.random.default_rng(20261122)
    kf = KalmanFilter(dim_x=10, dim_z=7)
    kf.F = np.eye(10)
    kf.F[0, 7] = kf.F[1, 8] = kf.F[2, 9] = 1.0
    kf.H = np.zeros((7, 10))
    kf.H[:7, :7] = np.eye(7)
    kf.P[7:, 7:] *= 1000.0
    kf.P *= 10.0
    kf.Q[7:, 7:] *= 0.01
    kf.R = np.eye(7)
    truth = np.array([10.0, -2.0, 0.5, 0.3, 4.5, 1.9, 1.6])
    kf.x[:7, 0] = truth + rng.normal(0, 0.3, 7)
    lines = [row(0, [0.0] * 7, kf)]
    xs, ps = [kf.x.copy()], [kf.P.copy()]
    for frame in range(1, 41):
        truth[0] += 0.8 * np.cos(truth[3])
        truth[1] += 0.8 * np.sin(truth[3])
        truth[3] += 0.01
        kf.predict()
        lines.append(row(1, [0.0] * 7, kf))
        if frame % 5 != 0:
            z = truth + rng.normal(0, [0.3, 0.3, 0.1, 0.05, 0.2, 0.1, 0.1])
            kf.update(z)
            lines.append(row(2, z, kf))
        xs.append(kf.x.copy())
        ps.append(kf.P.copy())
    smoothed_x, smoothed_p, _, _ = kf.rts_smoother(np.array(xs), np.array(ps))
    for x, p in zip(smoothed_x, smoothed_p):
        kf.x, kf.P = x, p
        lines.append(row(3, [0.0] * 7, kf))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
