"""The package against the command line: same reports, same files, errors with the Rust
message, the GIL released while Rust works."""

import json
import sys
import threading
import warnings
from pathlib import Path

import pyarrow.parquet as pq
import pytest

import dash2sim
from dash2sim import _native

from conftest import run_cli


def intact(corpus_plan, driver="careful"):
    return [i for i, e in corpus_plan.items() if e["damage"] is None and e["driver"] == driver]


def paths(corpus, log_id):
    return corpus / f"{log_id}.d2slog", corpus / f"{log_id}.map"


def test_read_log_has_the_parquet_export_s_tables_and_the_log_s_counts(corpus, corpus_plan, dash2sim_bin, tmp_path):
    log, _ = paths(corpus, intact(corpus_plan)[0])
    tables = dash2sim.read_log(log)
    assert tuple(tables) == dash2sim.TABLES
    counts = dash2sim.inspect(log)["by_type"]
    assert tables["ego"].num_rows == counts.get("EgoPose", 0)
    assert tables["gnss"].num_rows == counts["GnssFix"] > 0
    assert tables["speed"].num_rows == counts["VehicleSpeed"] > 0
    assert tables["events"].num_rows == counts["Event"]
    metadata = tables["ego"].schema.metadata
    assert metadata[b"dash2sim.log_id"] == log.stem.encode()
    header = dash2sim.inspect(log)["header"]["origin"]
    assert metadata[b"dash2sim.origin"].decode().split(",")[:2] == [str(header["lat"]), str(header["lon"])]
    result = run_cli(dash2sim_bin, "export", log, "--parquet", tmp_path)
    assert result.returncode == 0, result.stderr
    for name, table in tables.items():
        assert table.equals(pq.read_table(tmp_path / f"{name}.parquet")), name
    assert dash2sim.read_log(log, log_id="other")["gnss"].column("log_id")[0].as_py() == "other"


def test_finish_and_verify_give_the_command_line_s_reports_and_bytes(corpus, corpus_plan, dash2sim_bin, tmp_path):
    for log_id in [intact(corpus_plan)[0], intact(corpus_plan, "careless")[0]]:
        log, tile = paths(corpus, log_id)
        cli_out, py_out = tmp_path / f"{log_id}.cli.d2slog", tmp_path / f"{log_id}.py.d2slog"
        result = run_cli(dash2sim_bin, "finish", log, "-o", cli_out, "--map", tile, "--json")
        assert result.returncode == 0, result.stderr
        cli = json.loads(result.stdout)
        report = dash2sim.finish(log, py_out, map=tile)
        assert py_out.read_bytes() == cli_out.read_bytes()
        cli.pop("output"), report.pop("output")
        assert report == cli
        for sensitive in (False, True):
            args = ["verify", py_out, "--map", tile, "--json"] + (["--channel-sensitive"] if sensitive else [])
            result = run_cli(dash2sim_bin, *args)
            assert result.returncode == 0, result.stderr
            assert dash2sim.verify(py_out, tile, channel_sensitive=sensitive) == json.loads(result.stdout)
        # No doubt: the decision is nuPlan's verdict, its interval the point score.
        sure = dash2sim.verify(py_out, tile, decide_at=0.0)
        assert sure["decided"]["score_interval"] == [sure["score"], sure["score"]]
        assert sure["decided"]["decision"] == ("verified" if sure["verified"] else "rejected")
    verdicts = {dash2sim.verify(tmp_path / f"{i}.py.d2slog", paths(corpus, i)[1])["verified"] for i in
                [intact(corpus_plan)[0], intact(corpus_plan, "careless")[0]]}
    assert False in verdicts, "the careless driver's log is rejected"


def test_finish_writes_the_factor_graph_the_command_line_writes(corpus, corpus_plan, dash2sim_bin, tmp_path):
    log, _ = paths(corpus, intact(corpus_plan)[0])
    cli_graph, py_graph = tmp_path / "cli.json", tmp_path / "py.json"
    result = run_cli(dash2sim_bin, "finish", log, "-o", tmp_path / "cli.d2slog", "--factor-graph", cli_graph)
    assert result.returncode == 0, result.stderr
    dash2sim.finish(log, tmp_path / "py.d2slog", factor_graph=py_graph)
    graph = json.loads(py_graph.read_text())
    assert graph == json.loads(cli_graph.read_text())
    assert graph["format"] == "dash2sim-factor-graph 1" and graph["sessions"]
    session = graph["sessions"][0]
    keyframes = len(session["keyframe_vo"])
    assert len(session["finish"]["p"]) == len(session["initial"]["rho"]) == keyframes > 1
    assert len(session["factors"]["vo_chord"]) == keyframes - 1
    assert session["finish_cost"] > 0


def test_errors_are_dash2sim_errors_carrying_the_rust_message(corpus, corpus_plan, dash2sim_bin, tmp_path):
    by_damage = {e["damage"]: i for i, e in corpus_plan.items() if e["damage"]}
    garbage, _ = paths(corpus, by_damage["garbage"])
    for call in (lambda: dash2sim.read_log(garbage), lambda: dash2sim.inspect(garbage),
                 lambda: dash2sim.finish(garbage, tmp_path / "x.d2slog")):
        with pytest.raises(dash2sim.Dash2SimError, match="bad magic") as error:
            call()
        assert str(garbage) in str(error.value)
    cli = run_cli(dash2sim_bin, "finish", garbage, "-o", tmp_path / "x.d2slog")
    assert cli.stderr.strip() == f"dash2sim: error: {error.value}"
    no_gnss, tile = paths(corpus, by_damage["no-gnss"])
    with pytest.raises(dash2sim.Dash2SimError, match="nothing to anchor to"):
        dash2sim.finish(no_gnss, tmp_path / "x.d2slog", map=tile)
    with pytest.raises(dash2sim.Dash2SimError, match="No such file"):
        dash2sim.verify(tmp_path / "missing.d2slog", tile)
    log, tile = paths(corpus, intact(corpus_plan)[0])
    with pytest.raises(dash2sim.Dash2SimError, match='mode "sideways"'):
        dash2sim.finish(log, tmp_path / "x.d2slog", mode="sideways")
    with pytest.raises(dash2sim.Dash2SimError, match="nothing to export") as error:
        dash2sim.export(log)
    assert "--" not in str(error.value), "a library message names no command-line flag"
    with pytest.raises(dash2sim.Dash2SimError, match='mount "1,2": expected 3 or 6 numbers'):
        dash2sim.finish(log, tmp_path / "x.d2slog", mount="1,2")
    assert issubclass(dash2sim.Dash2SimError, Exception)


def test_a_damaged_log_exports_its_intact_records_with_a_warning(corpus, corpus_plan, tmp_path):
    log_id = next(i for i, e in corpus_plan.items() if e["damage"] == "bit-flips")
    log, _ = paths(corpus, log_id)
    # One bit in 300 flipped loses most records, and may lose every ego pose (the TUM export
    # then has nothing to write): Parquet and GeoJSON take whatever is intact.
    with pytest.warns(UserWarning, match="damaged stretches"):
        written = dash2sim.export(log, parquet=tmp_path / "pq", geojson=tmp_path / "ego.geojson")
    assert len(written) == 2 and (tmp_path / "pq" / "gnss.parquet").exists() and (tmp_path / "ego.geojson").exists()
    intact_log, _ = paths(corpus, intact(corpus_plan)[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dash2sim.export(intact_log, geojson=tmp_path / "a.geojson")


def test_simulator_exports_are_the_command_line_s_bytes(corpus, corpus_plan, dash2sim_bin, tmp_path):
    log, tile = paths(corpus, intact(corpus_plan)[0])
    for side in ("py", "cli"):
        (tmp_path / side).mkdir()
    written = dash2sim.export(log, map=tile, commonroad=tmp_path / "py" / "s.xml", scenarionet=tmp_path / "py" / "sn",
                              openscenario=tmp_path / "py" / "osc", scenario_seconds=10)
    assert "CommonRoad" in written[0] and "OpenSCENARIO" in written[-1], written
    result = run_cli(dash2sim_bin, "export", log, "--map", tile, "--commonroad", tmp_path / "cli" / "s.xml",
                     "--scenarionet", tmp_path / "cli" / "sn", "--openscenario", tmp_path / "cli" / "osc",
                     "--scenario-seconds", "10")
    assert result.returncode == 0, result.stderr
    py_files = sorted(p.relative_to(tmp_path / "py") for p in (tmp_path / "py").rglob("*") if p.is_file())
    cli_files = sorted(p.relative_to(tmp_path / "cli") for p in (tmp_path / "cli").rglob("*") if p.is_file())
    assert py_files == cli_files and any(p.suffix == ".pkl" for p in py_files)
    assert any(p.suffix == ".xosc" for p in py_files) and any(p.suffix == ".xodr" for p in py_files)
    for name in py_files:
        assert (tmp_path / "py" / name).read_bytes() == (tmp_path / "cli" / name).read_bytes(), name
    with pytest.raises(dash2sim.Dash2SimError, match="the map: the ScenarioNet export needs one") as error:
        dash2sim.export(log, scenarionet=tmp_path / "no-map")
    assert "--" not in str(error.value), "a library message names no command-line flag"


def test_the_gil_is_released_while_rust_works(corpus, corpus_plan, tmp_path):
    """With a switch interval far longer than the test, a thread that holds the GIL keeps it
    until it blocks: another thread's counter can only move during a native call if that
    call released the GIL."""
    log, tile = paths(corpus, intact(corpus_plan)[0])
    counter, stop = [0], threading.Event()

    def count():
        while not stop.is_set():
            counter[0] += 1
            stop.wait(0.0005)  # releases the GIL, then needs it back

    interval = sys.getswitchinterval()
    sys.setswitchinterval(30.0)
    thread = threading.Thread(target=count)
    thread.start()
    try:
        moved = []
        for call in (lambda: dash2sim.finish(log, tmp_path / "f.d2slog", map=tile),
                     lambda: dash2sim.verify(tmp_path / "f.d2slog", tile),
                     lambda: dash2sim.export(tmp_path / "f.d2slog", parquet=tmp_path / "pq")):
            # Held, the counter never moves however often the call is made; released, it
            # moves unless the other thread is never scheduled in all the tries.
            for _ in range(20):
                before = counter[0]
                call()
                if counter[0] > before:
                    break
            moved.append(counter[0] - before)
    finally:
        sys.setswitchinterval(interval)
        stop.set()
        thread.join()
    assert all(m > 0 for m in moved), moved


def test_the_type_hints_name_what_the_module_has():
    stub = (Path(dash2sim.__file__).parent / "_native.pyi").read_text()
    public = {name for name in dir(_native) if not name.startswith("_")}
    for name in public:
        assert f"def {name}(" in stub or f"class {name}(" in stub, name
    assert (Path(dash2sim.__file__).parent / "py.typed").exists()
    assert dash2sim.__version__ == _native.__version__
