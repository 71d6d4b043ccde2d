"""dash2sim from Python: read, finish, verify and export 4D driving logs.

A thin layer over the Rust crates: every function runs the same code as the command line
(``dash2sim finish``, ``verify``, ``export``, ``inspect``), so its verdicts are the command
line's. The GIL is released while Rust works, so threads run logs side by side. Errors are
raised as :class:`Dash2SimError` with the Rust message (which names the file and what was
wrong).

>>> import dash2sim
>>> report = dash2sim.finish("drive.d2slog", "finished.d2slog", map="road.map")  # doctest: +SKIP
>>> report["verification"]["drive"]["channel_insensitive"]["verified"]  # doctest: +SKIP
True
>>> tables = dash2sim.read_log("finished.d2slog")  # doctest: +SKIP
>>> tables["ego"].num_rows  # doctest: +SKIP
401

The corpus job (finish and verify a folder of logs on Dask) is :mod:`dash2sim.corpus`.
"""

from __future__ import annotations

import json
import os
import warnings
from typing import Any, Dict, List, Optional, Tuple, Union

import pyarrow as pa
import pyarrow.ipc

from . import _native
from ._native import Dash2SimError

__all__ = ["Dash2SimError", "read_log", "inspect", "finish", "verify", "export", "TABLES", "__version__"]
__version__: str = _native.__version__

#: The tables :func:`read_log` returns and ``export(parquet=...)`` writes (docs/parquet.md).
TABLES: Tuple[str, ...] = (
    "ego",
    "gnss",
    "speed",
    "anchors",
    "tracks3d",
    "verification",
    "imu",
    "imu_estimates",
    "events",
)

PathLike = Union[str, "os.PathLike[str]"]


def read_log(path: PathLike, log_id: Optional[str] = None) -> Dict[str, pa.Table]:
    """Read a 4D log into Arrow tables, one per record kind (the schema of docs/parquet.md).

    ``log_id`` goes into every row (default: the file's name without its extension); the
    log's id, device and origin are in each table's ``schema.metadata``. Damaged stretches
    of the file are skipped, as everywhere in dash2sim; :func:`inspect` counts them.
    """
    streams = _native.read_log(os.fspath(path), log_id)
    return {name: pa.ipc.open_stream(data).read_all() for name, data in streams}


def inspect(path: PathLike) -> Dict[str, Any]:
    """What a log holds: header, records per kind, time span, gaps, damage (``dash2sim inspect --json``)."""
    return json.loads(_native.inspect(os.fspath(path)))


def finish(
    log: PathLike,
    output: PathLike,
    *,
    map: Optional[PathLike] = None,
    anchors: Optional[PathLike] = None,
    mount: str = "1.8,0,1.3",
    mode: str = "gravity",
    uere: float = 2.5,
    keyframe: float = 0.5,
    require_signed: Optional[str] = None,
    factor_graph: Optional[PathLike] = None,
) -> Dict[str, Any]:
    """Finish a device's log offline into ``output`` (``dash2sim finish --json``).

    The whole drive is re-anchored at once from VO, GNSS, wheel speed and the optional
    ``anchors`` CSV; the 3D tracks are smoothed; with a ``map`` tile the finished drive is
    verified per 15 s window and as a whole (``report["verification"]``). Returns the report.
    Raises :class:`Dash2SimError` when the log cannot be read or has nothing to anchor to,
    or — with ``require_signed`` (a public key: 64 hex digits or a ``.pub`` file) — when a
    segment is not signed by that key, was altered, or the chain of segments is broken.
    With ``factor_graph`` (a path) the problem the re-anchoring solved is also written there
    as JSON for an outside solver (``dash2sim finish --factor-graph``, docs/finishing.md).
    """
    report = _native.finish(
        os.fspath(log),
        os.fspath(output),
        _path_or_none(map),
        _path_or_none(anchors),
        mount,
        mode,
        float(uere),
        float(keyframe),
        require_signed,
        _path_or_none(factor_graph),
    )
    return json.loads(report)


def verify(
    log: PathLike,
    map: PathLike,
    *,
    channel_sensitive: bool = False,
    start: Optional[float] = None,
    end: Optional[float] = None,
    footprint: Optional[Tuple[float, float, float]] = None,
    decide_at: float = 2.0,
    object_sigma: float = 0.0,
) -> Dict[str, Any]:
    """Replay a log's ego against a map tile and score it as nuPlan would (``dash2sim verify --json``).

    ``start``/``end`` (UTC seconds) select the poses; ``footprint`` is ``(width, front,
    rear)`` in metres from the rear axle (default: nuPlan's Pacifica). The report has each
    metric, the aggregate ``score`` and ``verified`` (score above 90), and ``decided``: the
    verdict with ``decide_at`` of the log's stated σ of doubt, the ego's and its tracks' (and
    ``object_sigma`` metres for each object whose log states none) — ``decision`` (verified, rejected or undecided), ``score_interval`` and
    each metric ``in_doubt`` in words (docs/verify.md).
    """
    return json.loads(
        _native.verify(
            os.fspath(log), os.fspath(map), channel_sensitive, start, end, footprint, decide_at, object_sigma
        )
    )


def export(
    log: PathLike,
    *,
    parquet: Optional[PathLike] = None,
    log_id: Optional[str] = None,
    tum: Optional[PathLike] = None,
    geojson: Optional[PathLike] = None,
    mcap: Optional[PathLike] = None,
    nuplan: Optional[PathLike] = None,
    map: Optional[PathLike] = None,
    commonroad: Optional[PathLike] = None,
    scenarionet: Optional[PathLike] = None,
    openscenario: Optional[PathLike] = None,
    scenario_seconds: Optional[float] = None,
) -> List[str]:
    """Export a log (``dash2sim export``): Parquet folder, TUM, GeoJSON, MCAP; for simulators
    (each needs ``map``) nuPlan's folder, a CommonRoad scenario file (``F.xml``), a
    ScenarioNet dataset folder and an OpenSCENARIO folder (``road.xodr`` and ``.xosc``
    scenarios), one scenario per ``scenario_seconds`` window when given.

    Returns one line per output written. A damaged log is exported from its intact records
    and a :class:`UserWarning` says what was skipped.
    """
    warning, written = _native.export(
        os.fspath(log),
        _path_or_none(parquet),
        log_id,
        _path_or_none(tum),
        _path_or_none(geojson),
        _path_or_none(mcap),
        _path_or_none(nuplan),
        _path_or_none(map),
        _path_or_none(commonroad),
        _path_or_none(scenarionet),
        _path_or_none(openscenario),
        scenario_seconds,
    )
    if warning is not None:
        warnings.warn(warning, UserWarning, stacklevel=2)
    return list(written)


def _path_or_none(path: Optional[PathLike]) -> Optional[str]:
    return None if path is None else os.fspath(path)
