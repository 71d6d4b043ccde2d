#!/usr/bin/env python3
"""Time pynmea2 on the concatenated gpsd corpus (the bytes `cargo bench --bench nmea`
uses), best of 5, two ways:

* parse only: every `$` line, pre-split, through `pynmea2.parse` — pynmea2 keeps the
  fields as strings and converts them only when read, so this does less than dash2sim;
* equal work: the raw text through `NMEAStreamReader` (framing, as dash2sim does from
  bytes), then every declared field of every sentence read (the conversion dash2sim does
  for every field), plus latitude/longitude of position sentences.

Usage: /tmp/venv/bin/python scripts/bench_pynmea2.py ../shared/data/gpsd/daemon
(pynmea2 in a venv; never a runtime dependency.)
"""
import glob
import sys
import timeit

import pynmea2


def main(folder: str) -> None:
    data = b"".join(open(p, "rb").read() for p in sorted(glob.glob(f"{folder}/*.log")))
    text = data.decode("latin-1")
    lines = [l.rstrip() for l in text.splitlines() if l.startswith("$")]

    def parse_only():
        ok = 0
        for line in lines:
            try:
                pynmea2.parse(line)
                ok += 1
            except Exception:
                pass
        return ok

    def equal_work():
        reader = pynmea2.NMEAStreamReader(errors="ignore")
        n = 0
        for msg in reader.next(text):
            for field in getattr(msg, "fields", ()):
                try:
                    getattr(msg, field[1])
                except (ValueError, TypeError):
                    pass
            if isinstance(msg, pynmea2.LatLonFix):
                try:
                    msg.latitude, msg.longitude
                except (ValueError, TypeError):
                    pass
            n += 1
        return n

    print(f"corpus {len(data)} bytes, {len(lines)} lines")
    for name, run in [("parse only", parse_only), ("equal work", equal_work)]:
        count = run()
        best = min(timeit.repeat(run, number=1, repeat=5))
        print(f"pynmea2 {pynmea2.version}, {name}: {count} sentences, {best * 1e3:.1f} ms, "
              f"{len(data) / best / 2**20:.2f} MiB/s, {count / best:.0f} sentences/s")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/gpsd/daemon")
