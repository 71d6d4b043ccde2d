"""The corpus job on Dask: every log recorded with the command line's verdict or its reason,
re-runs that do no work, changed logs redone, and a dataset DuckDB reads."""

import json
import os
import shutil
from pathlib import Path

import duckdb
import pyarrow.dataset as ds
import pyarrow.parquet as pq
import pytest

import dash2sim
from dash2sim import corpus as job

from conftest import run_cli

FAILING = {"garbage": "bad magic", "header-cut": "shorter than the 48-byte header",
           "no-gnss": "nothing to anchor to", "no-map": "No such file or directory"}


@pytest.fixture(scope="module")
def cluster():
    """A running 2-worker Dask cluster, reached by its scheduler's address."""
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        yield c.scheduler_address


@pytest.fixture(scope="module")
def finished(corpus, tmp_path_factory):
    """The corpus through the job once, on a local cluster it starts itself."""
    out = tmp_path_factory.mktemp("out")
    seen = []
    result = job.run(corpus, out, workers=2, progress=lambda done, total, entry: seen.append((done, total)))
    assert seen[-1] == (18, 18)
    return out, result


def manifest(out: Path) -> dict:
    return {row["log_id"]: row for row in pq.read_table(out / "manifest.parquet").to_pylist()}


def snapshot(out: Path) -> dict:
    return {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}


def test_every_log_is_recorded_with_the_command_line_s_verdict_or_reason(finished, corpus, corpus_plan, dash2sim_bin, tmp_path):
    out, result = finished
    assert (result.logs, result.processed, result.skipped, result.workers) == (18, 18, 0, 2)
    rows = manifest(out)
    assert set(rows) == set(corpus_plan)
    assert result.failed == len(FAILING)
    for log_id, plan in corpus_plan.items():
        row = rows[log_id]
        cli = run_cli(dash2sim_bin, "finish", corpus / f"{log_id}.d2slog", "-o", tmp_path / "f.d2slog",
                      "--map", corpus / f"{log_id}.map", "--json")
        if plan["damage"] in FAILING:
            assert row["status"] == "failed" and FAILING[plan["damage"]] in row["reason"], row
            assert cli.returncode == 1 and cli.stderr.strip() == f"dash2sim: error: {row['reason']}"
            assert row["files"] == []
            continue
        assert cli.returncode == 0, cli.stderr
        drive = json.loads(cli.stdout)["verification"]["drive"]["channel_insensitive"]
        assert row["status"] == ("verified" if drive["verified"] else "rejected")
        assert row["score"] == drive["score"]
        assert row["decision"] == drive["decision"] in ("verified", "rejected", "undecided")
        assert row["score_low"] <= row["score"] <= row["score_high"]
        for metric in job.METRICS:
            assert row[metric] == drive["metrics"][metric], (log_id, metric)
        assert (tmp_path / "f.d2slog").read_bytes() == Path(out / "finished" / f"{log_id}.d2slog").read_bytes()
        partition = f"date={row['date']}/region={row['region']}/verdict={row['status']}"
        for table in dash2sim.TABLES:
            assert (out / "dataset" / table / partition / f"{log_id}.parquet").exists(), (log_id, table)
        if plan["damage"]:
            assert row["damaged_bytes"] > 0 or plan["damage"] == "tail-cut", row
        if plan["driver"] == "careless" and plan["damage"] != "tail-cut":
            # A cut tail may take the conflict with it: drive-0009's careless driver comes too
            # close to the taper after 13.5 s, and the truth's first 13.5 s verify too.
            assert row["status"] == "rejected"
    assert {r["region"] for r in rows.values() if r["region"]} == {job.geohash(*e["origin"][:2]) for e in corpus_plan.values() if e["damage"] not in FAILING}


def test_a_rerun_does_no_work(finished, corpus):
    out, _ = finished
    before = snapshot(out)
    again = job.run(corpus, out, workers=2)
    assert (again.processed, again.skipped, again.workers) == (0, 18, 0)
    assert snapshot(out) == before, "a re-run wrote nothing"


def test_duckdb_reads_the_dataset_and_its_verified_share_is_the_manifest_s(finished):
    out, result = finished
    con = duckdb.connect()
    ego = f"read_parquet('{out}/dataset/ego/*/*/*/*.parquet', hive_partitioning = true)"
    verified, logs = con.execute(f"SELECT count(DISTINCT log_id) FILTER (verdict = 'verified'), count(DISTINCT log_id) FROM {ego}").fetchone()
    assert (verified, logs) == (result.verified, result.verified + result.rejected)
    rows = manifest(out)
    assert verified == sum(r["status"] == "verified" for r in rows.values())
    for table in dash2sim.TABLES:
        files = sorted((out / "dataset" / table).rglob("*.parquet"))
        duck = con.execute(f"SELECT count(*) FROM read_parquet('{out}/dataset/{table}/*/*/*/*.parquet', hive_partitioning = true)").fetchone()[0]
        assert duck == sum(pq.ParquetFile(f).metadata.num_rows for f in files), table
        # pyarrow reads the partitions as columns; none clashes with a table's own column.
        dataset = ds.dataset(out / "dataset" / table, format="parquet", partitioning="hive")
        assert dataset.count_rows() == duck, table
        assert {"date", "region", "verdict"} <= set(dataset.schema.names), table


def test_a_changed_log_is_redone_and_its_old_files_go(corpus, corpus_plan, cluster, tmp_path):
    logs = tmp_path / "logs"
    shutil.copytree(corpus, logs)
    out = tmp_path / "out"
    first = job.run(logs, out, scheduler=cluster)
    assert first.processed == 18 and first.workers == 2
    careful = next(i for i, e in corpus_plan.items() if e["damage"] is None and e["driver"] == "careful"
                   and manifest(out)[i]["status"] == "verified")
    careless = next(i for i, e in corpus_plan.items() if e["damage"] is None and e["driver"] == "careless")
    old_files = manifest(out)[careful]["files"]
    shutil.copy(logs / f"{careless}.d2slog", logs / f"{careful}.d2slog")
    shutil.copy(logs / f"{careless}.map", logs / f"{careful}.map")
    second = job.run(logs, out, scheduler=cluster)
    assert (second.processed, second.skipped) == (1, 17)
    row = manifest(out)[careful]
    assert row["status"] == "rejected"
    gone = [f for f in old_files if "verdict=verified" in f]
    assert gone and not any(os.path.exists(f) for f in gone)
    assert all(os.path.exists(f) for f in row["files"])
    third = job.run(logs, out, scheduler=cluster, retry_failed=True)
    assert (third.processed, third.failed) == (len(FAILING), len(FAILING))


def test_the_command_line_reports_bad_folders_and_runs(corpus, tmp_path, capsys):
    assert job.main([str(tmp_path / "none"), str(tmp_path / "out")]) == 1
    assert "not a folder of logs" in capsys.readouterr().err
    one = tmp_path / "one"
    one.mkdir()
    shutil.copy(corpus / "drive-0001.d2slog", one)
    shutil.copy(corpus / "drive-0001.map", one)
    assert job.main([str(one), str(tmp_path / "out"), "--workers", "1", "--json", "-q"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["processed"] == 1 and printed["logs"] == 1
    with pytest.raises(SystemExit):
        job.main(["--help"])
    assert "partitioned" in capsys.readouterr().out


def test_geohash_matches_the_reference_cells():
    # Values from the geohash definition (Niemeyer): the 57.64911, 10.40744 example.
    assert job.geohash(57.64911, 10.40744, 11) == "u4pruydqqvj"
    assert job.geohash(60.2711, 24.8572) == "ud9w"


def test_require_signed_refuses_unsigned_altered_and_foreign_logs(dash2sim_bin, cluster, tmp_path):
    """`--require-signed`: a log signed by the key goes through; an altered one, one with two
    segments swapped, one with a segment removed, an unsigned one and another device's fail
    with the reason `finish --require-signed` gives."""
    from conftest import REPO

    mcu = REPO / "examples" / "mcu"
    logs = tmp_path / "logs"
    logs.mkdir()
    run_cli(dash2sim_bin, "keygen", "-o", tmp_path / "other")

    def record(name: str, *key: str) -> Path:
        path = logs / f"{name}.d2slog"
        done = run_cli(dash2sim_bin, "record", "--replay", mcu / "drive.d2sin", "--map", mcu / "drive.d2smap",
                       *key, "-o", path)
        assert done.returncode == 0, done.stderr
        shutil.copy(mcu / "drive.d2smap", path.with_suffix(".map"))
        return path

    signed = record("signed", "--key", str(mcu / "demo.key"))
    altered = bytearray(signed.read_bytes())
    altered[len(altered) // 2] ^= 0x01
    (logs / "altered.d2slog").write_bytes(bytes(altered))
    shutil.copy(signed.with_suffix(".map"), logs / "altered.map")
    record("unsigned")
    record("foreign", "--key", str(tmp_path / "other.key"))
    # The second and third segments swapped; the second removed.
    data = signed.read_bytes()
    sync = b"\xd2\x5c\x0f\xe1"
    starts = [i for i in range(len(data)) if data.startswith(sync, i)] + [len(data)]
    s = starts
    (logs / "swapped.d2slog").write_bytes(data[: s[1]] + data[s[2] : s[3]] + data[s[1] : s[2]] + data[s[3] :])
    (logs / "removed.d2slog").write_bytes(data[: s[1]] + data[s[2] :])
    for name in ("swapped", "removed"):
        shutil.copy(signed.with_suffix(".map"), logs / f"{name}.map")

    out = tmp_path / "out"
    result = job.run(logs, out, scheduler=cluster, require_signed=str(mcu / "demo.pub"))
    rows = manifest(out)
    assert result.failed == 5 and rows["signed"]["status"] in ("verified", "rejected"), rows["signed"]
    assert "segment 2 of 6: chain broken" in rows["swapped"]["reason"]
    assert "segment 2 of 5: chain broken" in rows["removed"]["reason"]
    assert "bad signature" in rows["altered"]["reason"]
    assert "segment 0 of 6: unsigned" in rows["unsigned"]["reason"]
    assert "signed by another key (key id" in rows["foreign"]["reason"]
    cli = run_cli(dash2sim_bin, "finish", logs / "altered.d2slog", "-o", tmp_path / "f.d2slog",
                  "--require-signed", mcu / "demo.pub")
    assert cli.stderr.strip() == f"dash2sim: error: {rows['altered']['reason']}"
    # Without the requirement the same folder is processed again (another fingerprint), and
    # the unsigned and foreign logs finish.
    again = job.run(logs, out, scheduler=cluster)
    assert again.processed == 6 and manifest(out)["unsigned"]["status"] != "failed"
    with pytest.raises(ValueError, match="not a public key|neither 64 hex digits"):
        job.run(logs, out, scheduler=cluster, require_signed=str(tmp_path / "nothing.pub"))
