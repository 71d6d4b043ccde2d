#!/usr/bin/env python3
"""Time cantools (the DBC decoder CSS Electronics' and comma's expected files were made
with) on the capture `cargo bench --bench can` uses for DBC decoding: every frame of
comma2k19's `raw_can.candump.log` whose id the Toyota DBC defines, through
`Database.decode_message`, best of 3. Text parsing is included, as on our side.

Usage: /tmp/venv/bin/python scripts/bench_cantools.py ../shared/data/comma2k19
(cantools in a venv; never a runtime dependency.)
"""
import sys
import timeit

import cantools


def main(folder: str) -> None:
    db = cantools.database.load_file(f"{folder}/opendbc-toyota/_toyota_2017.dbc", strict=False)
    known = {m.frame_id for m in db.messages}
    text = open(f"{folder}/raw_can.candump.log").read().splitlines()

    def run():
        decoded = 0
        for line in text:
            _, _, body = line.split(" ")
            ident, data = body.split("#")
            frame_id = int(ident, 16)
            if frame_id in known:
                try:
                    db.decode_message(frame_id, bytes.fromhex(data))
                    decoded += 1
                except Exception:
                    pass
        return decoded

    print(f"{len(text)} frames, {run()} decoded")
    best = min(timeit.repeat(run, number=1, repeat=3))
    print(f"cantools {cantools.__version__}: best {best * 1e3:.1f} ms, {len(text) / best / 1e6:.3f} M frames/s")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/comma2k19")
