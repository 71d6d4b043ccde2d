#!/usr/bin/env python3
"""Issue #18's judged run: the corpus job on a local Dask cluster against a plain loop of
command-line calls, on a generated corpus with logs damaged on purpose.

1. `dash2sim scenario corpus` writes N logs (several seeds, lengths, regions, drivers; one
   in ten damaged: garbage, cut header, cut tail, flipped bits, no GNSS, no map).
2. The baseline: for each log `dash2sim finish LOG --map MAP --json` and
   `dash2sim export FINISHED --parquet DIR`, one process after the other.
3. The job (`dash2sim.corpus.run`) on 1 worker and on 2 workers, each into a fresh folder.
4. Checks (exit 1 on any failure): every log in both manifests; every intact log's status,
   score and eight metrics identical to the command line's; every failure's reason the
   command line's message; the damaged-but-readable logs finished with their damage
   counted; a re-run processes nothing and changes no file; DuckDB reads the dataset, its
   verified share equals the manifest's, and DuckDB and pyarrow agree on every table's rows.
5. Throughput (reported, not asserted): logs per second per worker, the 1 → 2 worker
   speed-up, and the engine's cost per log against the command-line loop.

    python scripts/fleet_check.py --dash2sim target/release/dash2sim --logs 200 --out target/fleet
"""

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import duckdb
import pyarrow.dataset as ds
import pyarrow.parquet as pq

import dash2sim
from dash2sim import corpus as job

FAILING = ("garbage", "header-cut", "no-gnss", "no-map")
problems = []


def check(condition, message):
    if not condition:
        problems.append(message)
        print(f"FAIL: {message}", file=sys.stderr)


def cli_loop(binary, logs, out):
    """finish + export per log with the command line: {log_id: (report or None, error)} and seconds."""
    out.mkdir(parents=True)
    results = {}
    started = time.perf_counter()
    for log in logs:
        finished = out / f"{log.stem}.d2slog"
        run = subprocess.run(
            [binary, "finish", log, "-o", finished, "--map", log.with_suffix(".map"), "--json"],
            capture_output=True, text=True)
        if run.returncode != 0:
            results[log.stem] = (None, run.stderr.strip().removeprefix("dash2sim: error: "))
            continue
        export = subprocess.run([binary, "export", finished, "--parquet", out / log.stem], capture_output=True, text=True)
        check(export.returncode == 0, f"{log.stem}: CLI export failed: {export.stderr}")
        results[log.stem] = (json.loads(run.stdout), None)
    return results, time.perf_counter() - started


def compare(name, rows, cli, plan):
    check(set(rows) == set(cli), f"{name}: manifest has {len(rows)} logs, the folder {len(cli)}")
    for log_id, (report, error) in cli.items():
        row = rows.get(log_id, {})
        damage = plan[log_id]["damage"]
        if report is None:
            check(row.get("status") == "failed" and row.get("reason") == error,
                  f"{name} {log_id}: {row.get('status')} {row.get('reason')!r}, CLI said {error!r}")
            check(damage in FAILING, f"{log_id}: damage {damage} should not fail ({error})")
            continue
        drive = report["verification"]["drive"]["channel_insensitive"]
        status = "verified" if drive["verified"] else "rejected"
        check(row.get("status") == status, f"{name} {log_id}: {row.get('status')}, CLI {status}")
        check(row.get("score") == drive["score"], f"{name} {log_id}: score {row.get('score')} vs {drive['score']}")
        for metric in job.METRICS:
            check(row.get(metric) == drive["metrics"][metric], f"{name} {log_id}: {metric} differs from the CLI")
        check(damage not in FAILING, f"{log_id}: damage {damage} finished")
        if damage == "bit-flips":
            check(row.get("damaged_bytes", 0) > 0, f"{log_id}: flipped bits not counted as damage")


def snapshot(out):
    return {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--dash2sim", type=Path, required=True, help="the dash2sim binary (release)")
    parser.add_argument("--logs", type=int, default=200)
    parser.add_argument("--out", type=Path, required=True, help="work folder (emptied first)")
    args = parser.parse_args()
    binary = args.dash2sim.resolve()
    shutil.rmtree(args.out, ignore_errors=True)
    corpus = args.out / "corpus"
    # The ideal sensor profile: this checks the job (damage handled as its kind says, the
    # dataset against the CLI), not the logs' quality, which docs/fidelity.md measures; under
    # the typical profile a log with flipped bits may rightly fail to finish.
    subprocess.run([binary, "scenario", "corpus", "-o", corpus, "--logs", str(args.logs), "--profile", "ideal", "-q"],
                   check=True, stdout=subprocess.DEVNULL)
    plan = {e["log"].removesuffix(".d2slog"): e for e in json.loads((corpus / "corpus.json").read_text())["logs"]}
    logs = sorted(corpus.glob("*.d2slog"))
    print(f"{len(logs)} logs, {sum(e['damage'] is not None for e in plan.values())} damaged on purpose", file=sys.stderr)

    cli, cli_seconds = cli_loop(binary, logs, args.out / "cli")
    print(f"command-line loop: {cli_seconds:.1f} s", file=sys.stderr)
    runs = {}
    for workers in (1, 2):
        out = args.out / f"job{workers}"
        result = job.run(corpus, out, workers=workers)
        rows = {r["log_id"]: r for r in pq.read_table(out / "manifest.parquet").to_pylist()}
        compare(f"{workers} worker(s)", rows, cli, plan)
        check(result.processed == len(logs) and result.workers == workers, f"{workers} workers: {result.summary()}")
        runs[workers] = (result, rows)
        print(result.summary(), file=sys.stderr)

    out = args.out / "job2"
    before = snapshot(out)
    again = job.run(corpus, out, workers=2)
    check(again.processed == 0 and again.workers == 0, f"re-run: {again.summary()}")
    check(snapshot(out) == before, "re-run changed files")

    result, rows = runs[2]
    con = duckdb.connect()
    glob = lambda table: f"read_parquet('{out}/dataset/{table}/*/*/*/*.parquet', hive_partitioning = true)"
    verified, total = con.execute(
        f"SELECT count(DISTINCT log_id) FILTER (verdict = 'verified'), count(DISTINCT log_id) FROM {glob('ego')}").fetchone()
    manifest_verified = sum(r["status"] == "verified" for r in rows.values())
    manifest_finished = sum(r["status"] != "failed" for r in rows.values())
    check((verified, total) == (manifest_verified, manifest_finished),
          f"DuckDB verified {verified}/{total}, manifest {manifest_verified}/{manifest_finished}")
    counts = {}
    for table in dash2sim.TABLES:
        duck = con.execute(f"SELECT count(*) FROM {glob(table)}").fetchone()[0]
        arrow = ds.dataset(out / "dataset" / table, format="parquet", partitioning="hive").count_rows()
        check(duck == arrow, f"{table}: DuckDB {duck} rows, pyarrow {arrow}")
        counts[table] = duck

    # Every query of docs/fleet.md runs on the dataset (the docs stay true to it).
    doc = Path(__file__).resolve().parent.parent / "docs" / "fleet.md"
    queries = re.findall(r"```sql\n(.*?)```", doc.read_text(), re.S)
    check(len(queries) >= 4, f"{doc}: {len(queries)} SQL examples")
    cwd = os.getcwd()
    os.chdir(out)
    try:
        for query in queries:
            try:
                check(len(con.execute(query).fetchall()) > 0, f"docs/fleet.md query gave no rows: {query}")
            except duckdb.Error as e:
                check(False, f"docs/fleet.md query failed: {e}\n{query}")
    finally:
        os.chdir(cwd)

    r1, r2 = runs[1][0], runs[2][0]
    n = len(logs)
    native = sum(r["seconds"] for r in runs[1][1].values()) / n
    figures = {
        "logs": n,
        "verified": manifest_verified,
        "rejected": manifest_finished - manifest_verified,
        "failed": n - manifest_finished,
        "cli_loop_s": cli_seconds,
        "cli_per_log_ms": 1e3 * cli_seconds / n,
        "job1_s": r1.seconds,
        "job1_cluster_s": r1.cluster_seconds,
        "job2_s": r2.seconds,
        "job2_cluster_s": r2.cluster_seconds,
        "logs_per_s_per_worker_1": n / r1.seconds,
        "logs_per_s_per_worker_2": n / r2.seconds / 2,
        "speedup": r1.seconds / r2.seconds,
        "speedup_without_cluster_start": (r1.seconds - r1.cluster_seconds) / (r2.seconds - r2.cluster_seconds),
        "task_per_log_ms": 1e3 * native,
        "engine_per_log_ms": 1e3 * ((r1.seconds - r1.cluster_seconds) / n - native),
        "rerun_s": again.seconds,
        "duckdb_verified_share": verified / total,
        "rows": counts,
    }
    (args.out / "fleet.json").write_text(json.dumps(figures, indent=2))
    print(json.dumps(figures, indent=2))
    if problems:
        print(f"{len(problems)} problems", file=sys.stderr)
        return 1
    print(f"fleet check passed: {n} logs, both worker counts agree with the command line", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
