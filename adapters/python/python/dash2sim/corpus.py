"""The corpus job: finish and verify a folder of 4D logs on Dask distributed.

Given a folder of device logs (``*.d2slog``, searched recursively) the job finishes and
verifies each log on a Dask cluster — a local one it starts, or an existing one by its
scheduler address — and writes:

``OUT/dataset/<table>/date=YYYY-MM-DD/region=<geohash>/verdict=<verified|rejected>/<log_id>.parquet``
    each finished log's tables (docs/parquet.md), Hive-partitioned by the UTC date of the
    log's start, the geohash (4 characters, about 40 × 20 km) of its origin and its verdict
    (``verdict``, not ``verified``: the verification table has a ``verified`` column per window);
``OUT/finished/<log_id>.d2slog``
    the finished logs;
``OUT/_manifest/<log_id>.json``
    one entry per log, written last and atomically: the log's content hash, its status
    (``verified``, ``rejected`` or ``failed``), the reason of a failure, the verdict and every
    metric, the files written;
``OUT/manifest.parquet``
    all entries as one table.

A log's map tile is ``NAME.map`` beside ``NAME.d2slog``, else the job's ``map``.

Idempotent and resumable: a log whose entry records the same content hash (log, map,
package version) is skipped, so a re-run after a crash does only what is left and a re-run
of a complete job does no work (it does not even start the cluster). A log that cannot be
read, anchored or verified is recorded as ``failed`` with the command line's message and
never stops the job; re-run those with ``retry_failed=True``.

Run it with ``python -m dash2sim.corpus LOGS OUT`` (``--help``) or :func:`run`.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Optional

import pyarrow as pa
import pyarrow.parquet as pq

import dash2sim

#: The metrics of a verification, in the order of docs/verify.md.
METRICS = (
    "no_at_fault_collisions",
    "drivable_area_compliance",
    "driving_direction_compliance",
    "ego_is_making_progress",
    "ego_progress_along_expert_route",
    "time_to_collision_within_bound",
    "speed_limit_compliance",
    "ego_is_comfortable",
)

_GEOHASH = "0123456789bcdefghjkmnpqrstuvwxyz"


def geohash(lat: float, lon: float, length: int = 4) -> str:
    """The geohash of a position: the job's region (4 characters: a cell of about 40 × 20 km)."""
    lat_range, lon_range = [-90.0, 90.0], [-180.0, 180.0]
    code, bits, value, even = [], 0, 0, True
    while len(code) < length:
        rng, x = (lon_range, lon) if even else (lat_range, lat)
        mid = (rng[0] + rng[1]) / 2
        value = value * 2 + (x >= mid)
        rng[0 if x >= mid else 1] = mid
        even, bits = not even, bits + 1
        if bits == 5:
            code.append(_GEOHASH[value])
            bits, value = 0, 0
    return "".join(code)


def file_sha256(path: Path) -> Optional[str]:
    """The SHA-256 of a file's content, or None if it does not exist."""
    digest = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                digest.update(block)
    except FileNotFoundError:
        return None
    return digest.hexdigest()


@dataclass(frozen=True)
class Task:
    """One log to process: what a worker needs, with the content hash it is known by."""

    log_id: str
    log: str
    map: str
    out: str
    fingerprint: str
    previous_files: List[str]
    #: Refuse the log unless every segment is signed by this public key (64 hex digits).
    require_signed: Optional[str] = None


@dataclass
class CorpusResult:
    """What a run of the job did."""

    logs: int
    processed: int
    skipped: int
    verified: int
    rejected: int
    failed: int
    seconds: float
    #: Of ``seconds``, starting the cluster (or connecting to it) and stopping it.
    cluster_seconds: float
    workers: int
    manifest: Path

    def summary(self) -> str:
        if self.processed == 0:
            return (
                f"{self.logs} logs, all done before: nothing to do; {self.verified} verified, "
                f"{self.rejected} rejected, {self.failed} failed in the manifest"
            )
        rate = self.processed / self.seconds / max(self.workers, 1) if self.seconds > 0 else 0.0
        return (
            f"{self.logs} logs: {self.processed} processed, {self.skipped} skipped (already done); "
            f"{self.verified} verified, {self.rejected} rejected, {self.failed} failed in the manifest; "
            f"{self.seconds:.1f} s on {self.workers} workers ({rate:.2f} logs/s per worker)"
        )


def _write_atomically(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
    with os.fdopen(fd, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


def _utc_date(seconds: float) -> str:
    return datetime.fromtimestamp(seconds, tz=timezone.utc).strftime("%Y-%m-%d")


def process_log(task: Task) -> Dict[str, Any]:
    """Finish, verify and export one log (runs on a worker); its manifest entry.

    The entry is written last (atomically), so a log either has a complete entry with all
    its files or is done again on the next run.
    """
    started = time.perf_counter()
    out = Path(task.out)
    for stale in task.previous_files:
        Path(stale).unlink(missing_ok=True)
    entry: Dict[str, Any] = {
        "log_id": task.log_id,
        "log": task.log,
        "map": task.map,
        "fingerprint": task.fingerprint,
        "dash2sim_version": dash2sim.__version__,
        "status": "failed",
        "reason": None,
        "files": [],
    }
    try:
        entry.update(_finish_and_export(task, out))
    except dash2sim.Dash2SimError as e:
        entry["reason"] = str(e)
    except OSError as e:
        entry["reason"] = f"{type(e).__name__}: {e}"
    entry["seconds"] = time.perf_counter() - started
    _write_atomically(out / "_manifest" / f"{task.log_id}.json", json.dumps(entry, sort_keys=True).encode())
    return entry


def _finish_and_export(task: Task, out: Path) -> Dict[str, Any]:
    finished = out / "finished" / f"{task.log_id}.d2slog"
    finished.parent.mkdir(parents=True, exist_ok=True)
    partial = finished.with_name(f".{finished.name}.partial")
    report = dash2sim.finish(task.log, partial, map=task.map, require_signed=task.require_signed)
    os.replace(partial, finished)
    info = dash2sim.inspect(finished)
    origin = info["header"]["origin"]
    drive = report["verification"]["drive"]
    insensitive, sensitive = drive["channel_insensitive"], drive["channel_sensitive"]
    verified = bool(insensitive["verified"])
    partition = {
        "date": _utc_date(info["t_start"]),
        "region": geohash(origin["lat"], origin["lon"]),
        "verdict": "verified" if verified else "rejected",
    }
    files = [str(finished)]
    with tempfile.TemporaryDirectory(dir=out, prefix=".export-") as tmp:
        dash2sim.export(finished, parquet=tmp, log_id=task.log_id)
        for table in dash2sim.TABLES:
            target = out / "dataset" / table
            for key, value in partition.items():
                target = target / f"{key}={value}"
            target.mkdir(parents=True, exist_ok=True)
            path = target / f"{task.log_id}.parquet"
            shutil.move(os.path.join(tmp, f"{table}.parquet"), path)
            files.append(str(path))
    entry: Dict[str, Any] = {
        "status": "verified" if verified else "rejected",
        "files": files,
        "date": partition["date"],
        "region": partition["region"],
        "lat": origin["lat"],
        "lon": origin["lon"],
        "start_utc": info["t_start"],
        "duration_s": info["t_end"] - info["t_start"],
        "verified": verified,
        "score": insensitive["score"],
        # With the σ the finished log states for its poses and tracks: verified, rejected
        # or undecided (docs/verify.md); `in_doubt` in `verify` says which evidence would
        # decide it (street anchors for the ego, nearer looks for the objects).
        "decision": insensitive["decision"],
        "score_low": insensitive["score_interval"][0],
        "score_high": insensitive["score_interval"][1],
        "verified_channel_sensitive": bool(sensitive["verified"]),
        "score_channel_sensitive": sensitive["score"],
        "windows": len(report["verification"]["windows"]),
        "windows_verified": sum(bool(w["channel_insensitive"]["verified"]) for w in report["verification"]["windows"]),
        "ego_poses": report["ego_poses"],
        "gnss_fixes_used": report["gnss"]["used"],
        "scale": report["anchoring"]["scale"],
        "scale_sigma_relative": report["anchoring"]["scale_sigma_relative"],
        "damaged_stretches": report["damage"]["stretches"],
        "damaged_bytes": report["damage"]["bytes"],
    }
    entry.update({metric: insensitive["metrics"][metric] for metric in METRICS})
    return entry


def find_logs(logs: Path, out: Path) -> List[Path]:
    """The ``*.d2slog`` files under ``logs`` (recursively), leaving out the job's own output."""
    out = out.resolve()
    found = [p for p in sorted(logs.rglob("*.d2slog")) if out not in p.resolve().parents]
    stems: Dict[str, Path] = {}
    for p in found:
        if p.stem in stems:
            raise ValueError(f"two logs are called {p.stem!r}: {stems[p.stem]} and {p}; log ids must be unique")
        stems[p.stem] = p
    return found


def read_manifest(out: Path) -> Dict[str, Dict[str, Any]]:
    """The manifest entries under ``out/_manifest``, by log id."""
    entries = {}
    for path in sorted((out / "_manifest").glob("*.json")):
        entry = json.loads(path.read_text())
        entries[entry["log_id"]] = entry
    return entries


def public_key(given: str) -> str:
    """A public key given as 64 hex digits or as the ``.pub`` file of ``dash2sim keygen``."""
    text = given.strip()
    if len(text) != 64 or any(c not in "0123456789abcdefABCDEF" for c in text):
        try:
            text = Path(given).read_text().strip()
        except OSError as e:
            raise ValueError(f"--require-signed {given}: neither 64 hex digits nor a public key file ({e})") from e
    if len(text) != 64 or any(c not in "0123456789abcdefABCDEF" for c in text):
        raise ValueError(f"--require-signed {given}: not a public key (64 hex digits)")
    return text.lower()


def plan(
    logs: Path, out: Path, default_map: Optional[Path], retry_failed: bool, require_signed: Optional[str] = None
) -> tuple:
    """The tasks to run and the number of logs skipped because their entry is current."""
    done = read_manifest(out)
    tasks, skipped, found = [], 0, find_logs(logs, out)
    for log in found:
        beside = log.with_suffix(".map")
        map_path = beside if beside.exists() or default_map is None else default_map
        fingerprint = f"{file_sha256(log)}:{file_sha256(map_path)}:{dash2sim.__version__}"
        if require_signed:
            # Another requirement is another result: the log is done again.
            fingerprint += f":signed-by:{require_signed}"
        previous = done.get(log.stem)
        if previous and previous["fingerprint"] == fingerprint and not (retry_failed and previous["status"] == "failed"):
            skipped += 1
            continue
        files = previous["files"] if previous else []
        tasks.append(Task(log.stem, str(log), str(map_path), str(out), fingerprint, files, require_signed))
    return tasks, skipped, len(found)


def write_manifest(out: Path) -> Path:
    """All entries as ``out/manifest.parquet`` (one row per log; ``files`` as a list)."""
    entries = list(read_manifest(out).values())
    columns = sorted({key for entry in entries for key in entry})
    table = pa.Table.from_pylist([{key: entry.get(key) for key in columns} for entry in entries])
    path = out / "manifest.parquet"
    tmp = out / ".manifest.parquet.partial"
    pq.write_table(table, tmp, compression="zstd")
    os.replace(tmp, path)
    return path


def run(
    logs: "os.PathLike[str] | str",
    out: "os.PathLike[str] | str",
    *,
    map: "os.PathLike[str] | str | None" = None,
    workers: int = 2,
    scheduler: Optional[str] = None,
    retry_failed: bool = False,
    progress: Optional[Callable[[int, int, Dict[str, Any]], None]] = None,
    require_signed: Optional[str] = None,
) -> CorpusResult:
    """Finish and verify every log under ``logs`` into ``out`` on Dask.

    ``scheduler`` is the address of a running Dask scheduler (``tcp://host:8786``); without
    it a local cluster of ``workers`` single-threaded worker processes is started for the
    run. Workers must see ``logs`` and ``out`` at the same paths (a shared file system).
    ``progress(done, total, entry)`` is called as each log completes. With
    ``require_signed`` (a public key: 64 hex digits or a ``.pub`` file) a log that is not
    signed by that key in every segment, or was altered, or whose chain of segments is
    broken, fails with the reason in its manifest entry.
    """
    started = time.perf_counter()
    logs_path, out_path = Path(logs), Path(out)
    if not logs_path.is_dir():
        raise FileNotFoundError(f"{logs_path}: not a folder of logs")
    out_path.mkdir(parents=True, exist_ok=True)
    key = public_key(require_signed) if require_signed else None
    tasks, skipped, total = plan(logs_path, out_path, Path(map) if map else None, retry_failed, key)
    used_workers, cluster_seconds = 0, 0.0
    if tasks:
        used_workers, cluster_seconds = _run_on_dask(tasks, workers, scheduler, progress)
    manifest = out_path / "manifest.parquet"
    if tasks or not manifest.exists():
        write_manifest(out_path)
    statuses = [entry["status"] for entry in read_manifest(out_path).values()]
    return CorpusResult(
        logs=total,
        processed=len(tasks),
        skipped=skipped,
        verified=statuses.count("verified"),
        rejected=statuses.count("rejected"),
        failed=statuses.count("failed"),
        seconds=time.perf_counter() - started,
        cluster_seconds=cluster_seconds,
        workers=used_workers,
        manifest=manifest,
    )


def _run_on_dask(
    tasks: List[Task],
    workers: int,
    scheduler: Optional[str],
    progress: Optional[Callable[[int, int, Dict[str, Any]], None]],
) -> tuple:
    """Run the tasks: the number of workers, and the seconds spent starting and stopping the cluster."""
    from dask.distributed import Client, LocalCluster, as_completed

    started = time.perf_counter()
    if scheduler is None:
        if workers < 1:
            raise ValueError(f"workers={workers}: at least one worker")
        cluster: Any = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
        )
    else:
        cluster = None
    try:
        with Client(cluster if cluster is not None else scheduler) as client:
            used = len(client.scheduler_info()["workers"])
            working = time.perf_counter()
            futures = client.map(process_log, tasks, key=[f"dash2sim-{t.log_id}-{t.fingerprint[:16]}" for t in tasks])
            for done, future in enumerate(as_completed(futures), start=1):
                entry = future.result()
                if progress is not None:
                    progress(done, len(tasks), entry)
            worked = time.perf_counter() - working
    finally:
        if cluster is not None:
            cluster.close()
    return used, time.perf_counter() - started - worked


def _print_progress(done: int, total: int, entry: Dict[str, Any]) -> None:
    if entry["status"] == "failed":
        print(f"[{done}/{total}] {entry['log_id']}: failed: {entry['reason']}", file=sys.stderr)
    elif done % 25 == 0 or done == total:
        print(f"[{done}/{total}] logs done", file=sys.stderr)


def main(argv: Optional[Iterable[str]] = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m dash2sim.corpus",
        description="Finish and verify a folder of dash2sim logs on Dask distributed: a partitioned "
        "Parquet dataset (date / region / verified) and a manifest (docs/fleet.md).",
    )
    parser.add_argument("logs", type=Path, help="folder of *.d2slog logs (searched recursively); NAME.map beside a log is its map")
    parser.add_argument("out", type=Path, help="output folder: dataset/, finished/, _manifest/, manifest.parquet")
    parser.add_argument("--map", type=Path, help="map tile for the logs without NAME.map beside them")
    parser.add_argument("--workers", type=int, default=2, help="worker processes of the local cluster (default 2)")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler instead of a local cluster")
    parser.add_argument("--retry-failed", action="store_true", help="process again the logs that failed before")
    parser.add_argument(
        "--require-signed",
        metavar="PUB",
        help="refuse (as failed, with the reason) every log not signed by this public key in every segment: "
        "64 hex digits or the .pub file of dash2sim keygen",
    )
    parser.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    parser.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    args = parser.parse_args(list(argv) if argv is not None else None)
    try:
        result = run(
            args.logs,
            args.out,
            map=args.map,
            workers=args.workers,
            scheduler=args.scheduler,
            retry_failed=args.retry_failed,
            progress=None if args.quiet else _print_progress,
            require_signed=args.require_signed,
        )
    except (OSError, ValueError) as e:
        print(f"dash2sim.corpus: error: {e}", file=sys.stderr)
        return 1
    if args.json:
        fields = {k: (str(v) if isinstance(v, Path) else v) for k, v in result.__dict__.items()}
        print(json.dumps(fields))
    else:
        print(result.summary())
    return 0


if __name__ == "__main__":
    # Run as the package's module, not as __main__, so the workers unpickle the tasks and
    # `process_log` by their importable names.
    from dash2sim.corpus import main as _main

    sys.exit(_main())
