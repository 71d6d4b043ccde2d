#!/usr/bin/env python3
"""How far a causal average of a phone receiver's fixes can bring the device's position.

Issue #54 asks the device's APE with a phone-grade receiver to be at most 5 m. The simulated
phone receiver's errors are a Gauss-Markov process (horizontal RMS σ wandering between 3 and
10 m over 50 s, correlated over 15 s, a fix a second: `GnssModel::default` in
adapters/sim/src/scenario/sensors.rs). This model keeps that process alone — no relative
motion error, no latency, no multipath — and averages the fixes causally, each weighted
1/σ², with an exponential window of τ seconds, as the anchorer's translation does. It prints
the median over drives of the horizontal RMS error (from 1.3 s, the device's median first
anchor, to the 40 s drive's end). It is an analysis of the generator's receiver, not an
estimator: nothing in the pipeline reads these numbers.

    python3 scripts/phone_window_floor.py [drives]
"""
import math
import random
import statistics
import sys

SIGMA_RANGE = (3.0, 10.0)
CORRELATION_S = 15.0
FIX_INTERVAL_S = 1.0
DRIVE_S = 40.0
FIRST_ANCHOR_S = 1.3


def drive(rng):
    phase = rng.uniform(0.0, 2.0 * math.pi)
    lo, hi = SIGMA_RANGE
    phi = math.exp(-FIX_INTERVAL_S / CORRELATION_S)
    fresh = math.sqrt(1.0 - phi * phi)
    fixes, error = [], None
    t = 0.0
    while t < DRIVE_S:
        sigma = lo + (hi - lo) * 0.5 * (1.0 + math.sin(2.0 * math.pi * t / 50.0 + phase))
        axis = sigma / math.sqrt(2.0)
        if error is None:
            error = [rng.gauss(0.0, axis), rng.gauss(0.0, axis)]
        else:
            error = [phi * e + fresh * rng.gauss(0.0, axis) for e in error]
        fixes.append((t, sigma, error))
        t += FIX_INTERVAL_S
    return fixes


def rms_of_average(fixes, tau):
    mean, weight, squares, n = None, 0.0, 0.0, 0
    previous_t = None
    for t, sigma, error in fixes:
        w = 1.0 / (sigma * sigma)
        if mean is None:
            mean, weight = list(error), w
        else:
            keep = math.exp(-(t - previous_t) / tau) if tau else 1.0
            weight = keep * weight + w
            mean = [m + (w / weight) * (e - m) for m, e in zip(mean, error)]
        previous_t = t
        # Held until the next fix; the 1 s steps from FIRST_ANCHOR_S on sample it evenly.
        if t + FIX_INTERVAL_S > FIRST_ANCHOR_S:
            squares += mean[0] ** 2 + mean[1] ** 2
            n += 1
    return math.sqrt(squares / n)


def main():
    drives = int(sys.argv[1]) if len(sys.argv) > 1 else 1000
    rng = random.Random(54)
    runs = [drive(rng) for _ in range(drives)]
    print(f"{drives} drives of {DRIVE_S:.0f} s; median horizontal RMS of a causal average:")
    print(f"  each fix alone           {statistics.median(rms_of_average(r, 1e-9) for r in runs):5.2f} m")
    for tau in (2.0, 6.0, 12.0, 24.0):
        print(f"  window τ = {tau:4.0f} s        {statistics.median(rms_of_average(r, tau) for r in runs):5.2f} m")
    print(f"  every past fix           {statistics.median(rms_of_average(r, None) for r in runs):5.2f} m")


if __name__ == "__main__":
    main()
