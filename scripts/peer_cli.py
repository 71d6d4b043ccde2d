"""The arguments every peer check in `scripts/` takes: the dash2sim binary, a log, its map,
an output folder (`nuplan_crosscheck.py`, `commonroad_check.py`, `scenarionet_check.py`)."""
import argparse


def parser(description: str) -> argparse.ArgumentParser:
    """A parser with `--dash2sim`, `--log`, `--map`, `--out` (all required) and `--json`."""
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--dash2sim", required=True, help="the dash2sim binary")
    p.add_argument("--log", required=True, help="the 4D log")
    p.add_argument("--map", required=True, help="its map tile or OpenStreetMap file")
    p.add_argument("--out", required=True, help="folder for the exports and the reports")
    p.add_argument("--json", action="store_true", help="print the results as JSON")
    return p
