"""Publishes N frame-metadata messages with dash2sim.camera, one a millisecond, each stamped
with the device clock just before it is sent: the Python side of
``cargo bench -p dash2sim-examples --bench publisher_latency`` (docs/benchmarks.md).

    python latency.py PREFIX N
"""

import sys
import time

from dash2sim.camera import Publisher, device_now_us

prefix, n = sys.argv[1], int(sys.argv[2])
with Publisher(prefix) as camera:
    for k in range(1, n + 1):
        time.sleep(0.001)
        camera.frame(k, device_now_us())
    time.sleep(0.5)
