#!/usr/bin/env python3
"""Check `dash2sim export --parquet` folders against docs/parquet.md with two independent
readers: every file's schema (names, types, nullability) and metadata as the page documents
them, pyarrow's and DuckDB's row counts equal, and both equal to the records `dash2sim
inspect` counts in the log.

    validate_parquet.py --doc docs/parquet.md --dash2sim target/release/dash2sim \
        --export LOG DIR [--export LOG DIR ...]
"""
import argparse
import json
import re
import subprocess
import sys

import duckdb
import pyarrow as pa
import pyarrow.parquet as pq

TYPES = {"double": pa.float64(), "int64": pa.int64(), "string": pa.string(), "boolean": pa.bool_()}
# The log's record kind behind each table (`inspect --json` counts; tracks3d has a row per
# track state, checked against the records otherwise).
KINDS = {"ego": "EgoPose", "gnss": "GnssFix", "speed": "VehicleSpeed", "anchors": "AnchorEstimate",
         "verification": "Verification", "events": "Event", "imu": "ImuDelta", "imu_estimates": "ImuEstimate"}


DUCKDB = duckdb.connect()


def scalar(query):
    return DUCKDB.execute(query).fetchone()[0]


def documented(path):
    """{table: [(column, arrow type, nullable)]} from the page's tables."""
    tables, current = {}, None
    for line in open(path, encoding="utf-8"):
        m = re.match(r"### (\w+)\.parquet", line)
        if m:
            current = m.group(1)
            tables[current] = [("log_id", pa.string(), False), ("t", pa.timestamp("us", tz="UTC"), False)]
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if current and len(cells) == 3 and cells[0] not in ("column", "---") and not cells[0].startswith("-"):
            kind, *null = cells[1].split()
            tables[current].append((cells[0], TYPES[kind], null == ["null"]))
    return tables


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--doc", required=True)
    ap.add_argument("--dash2sim", required=True)
    ap.add_argument("--export", nargs=2, action="append", metavar=("LOG", "DIR"), required=True)
    args = ap.parse_args()
    schema = documented(args.doc)
    assert len(schema) == 9, f"{args.doc}: {len(schema)} tables documented"
    failures = 0
    for log, folder in args.export:
        inspect = json.loads(subprocess.run([args.dash2sim, "inspect", log, "--json"], check=True,
                                            capture_output=True, text=True).stdout)
        by_type = inspect["by_type"]
        for table, columns in schema.items():
            path = f"{folder}/{table}.parquet"
            t = pq.read_table(path)
            got = [(f.name, f.type, f.nullable) for f in t.schema]
            meta = pq.read_metadata(path).metadata or {}
            keys = {k.decode() for k in meta}
            rows_duckdb = scalar(f"SELECT count(*) FROM '{path}'")
            problems = []
            if table == "tracks3d":
                # A Tracks3d record holds up to 8 states of one time: times ≤ records ≤ states.
                times = scalar(f"SELECT count(DISTINCT t) FROM '{path}'")
                records = by_type.get("Tracks3d", 0)
                if not times <= records <= rows_duckdb or (records == 0) != (rows_duckdb == 0):
                    problems.append(f"{rows_duckdb} states at {times} times from {records} Tracks3d records")
                expected = rows_duckdb
            else:
                expected = by_type.get(KINDS[table], 0)
            if got != columns:
                problems.append(f"schema {got} != documented {columns}")
            missing = {"dash2sim.schema_version", "dash2sim.log_id", "dash2sim.device_id", "dash2sim.origin"} - keys
            if missing:
                problems.append(f"metadata lacks {sorted(missing)}")
            if not (t.num_rows == rows_duckdb == expected):
                problems.append(f"rows: pyarrow {t.num_rows}, DuckDB {rows_duckdb}, the log {expected}")
            ids = scalar(f"SELECT count(DISTINCT log_id) FROM '{path}'")
            if t.num_rows and ids != 1:
                problems.append(f"{ids} log ids")
            status = "ok" if not problems else "FAILED: " + "; ".join(problems)
            print(f"{path}: {t.num_rows} rows, {len(columns)} columns — {status}")
            failures += bool(problems)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
