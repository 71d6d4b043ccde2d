#!/usr/bin/env python3
"""Time pynmea2 on the concatenated gpsd corpus (the bytes `cargo bench --bench nmea`
uses): every `$` line through `pynmea2.parse`, best of 5.

Usage: /tmp/venv/bin/python scripts/bench_pynmea2.py ../shared/data/gpsd/daemon
(pynmea2 in a venv; never a runtime dependency.)
"""
import glob
import sys
import timeit

import pynmea2


def main(folder: str) -> None:
    data = b"".join(open(p, "rb").read() for p in sorted(glob.glob(f"{folder}/*.log")))
    lines = [l.rstrip() for l in data.decode("latin-1").splitlines() if l.startswith("$")]

    def run():
        ok = 0
        for line in lines:
            try:
                pynmea2.parse(line)
                ok += 1
            except Exception:
                pass
        return ok

    print(f"corpus {len(data)} bytes, {len(lines)} lines, parsed {run()}")
    best = min(timeit.repeat(run, number=1, repeat=5))
    print(f"pynmea2: {best * 1e3:.1f} ms, {len(data) / best / 2**20:.2f} MiB/s, {len(lines) / best:.0f} sentences/s")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/gpsd/daemon")
