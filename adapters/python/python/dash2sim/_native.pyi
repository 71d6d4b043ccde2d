"""Type hints of the Rust module ``dash2sim._native`` (adapters/python/src/lib.rs).

Use the functions of :mod:`dash2sim` instead: they turn the JSON reports into dicts and the
Arrow IPC streams into ``pyarrow.Table``s.
"""

from typing import List, Optional, Tuple

__version__: str

class Dash2SimError(Exception):
    """An error from dash2sim: the message is the command line's, naming the file and what was wrong."""

def read_log(path: str, log_id: Optional[str] = None) -> List[Tuple[str, bytes]]: ...
def inspect(path: str) -> str: ...
def finish(
    log: str,
    output: str,
    map: Optional[str] = None,
    anchors: Optional[str] = None,
    mount: str = "1.8,0,1.3",
    mode: str = "gravity",
    uere: float = 2.5,
    keyframe: float = 0.5,
    require_signed: Optional[str] = None,
    factor_graph: Optional[str] = None,
) -> str: ...
def verify(
    log: str,
    map: str,
    channel_sensitive: bool = False,
    start: Optional[float] = None,
    end: Optional[float] = None,
    footprint: Optional[Tuple[float, float, float]] = None,
) -> str: ...
def export(
    log: str,
    parquet: Optional[str] = None,
    log_id: Optional[str] = None,
    tum: Optional[str] = None,
    geojson: Optional[str] = None,
    mcap: Optional[str] = None,
    nuplan: Optional[str] = None,
    map: Optional[str] = None,
    commonroad: Optional[str] = None,
    scenarionet: Optional[str] = None,
    openscenario: Optional[str] = None,
    scenario_seconds: Optional[float] = None,
) -> Tuple[Optional[str], List[str]]: ...
def class_id(name: str) -> Optional[int]: ...
