"""Fixtures: the dash2sim binary (the command line the package must agree with) and a
small generated corpus with one log of each kind of damage."""

import json
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def dash2sim_bin() -> Path:
    """`$DASH2SIM_BIN`, else the workspace's release or debug build."""
    candidates = [os.environ.get("DASH2SIM_BIN")] if os.environ.get("DASH2SIM_BIN") else []
    candidates += [REPO / "target" / "release" / "dash2sim", REPO / "target" / "debug" / "dash2sim"]
    for candidate in candidates:
        if candidate and Path(candidate).is_file():
            return Path(candidate)
    pytest.fail("no dash2sim binary: build it (cargo build --release -p dash2sim) or set DASH2SIM_BIN")


def run_cli(binary: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True)


@pytest.fixture(scope="session")
def corpus(dash2sim_bin, tmp_path_factory) -> Path:
    """18 logs, every third damaged: one of each kind (garbage, header-cut, tail-cut,
    bit-flips, no-gnss, no-map)."""
    out = tmp_path_factory.mktemp("corpus")
    result = run_cli(dash2sim_bin, "scenario", "corpus", "-o", out, "--logs", "18", "--damaged-every", "3",
                     "--profile", "ideal", "-q")
    assert result.returncode == 0, result.stderr
    return out


@pytest.fixture(scope="session")
def corpus_plan(corpus) -> dict:
    """`corpus.json` by log id."""
    logs = json.loads((corpus / "corpus.json").read_text())["logs"]
    return {entry["log"].removesuffix(".d2slog"): entry for entry in logs}
