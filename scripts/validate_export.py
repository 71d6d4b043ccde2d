#!/usr/bin/env python3
"""Read dash2sim's exports back with independent tools (CI runs this).

* MCAP: the Python `mcap` package reads every file with CRC validation; every message whose
  schema is a Foxglove one (`foxglove.*`) must validate against Foxglove's *official* JSON
  schema (npm @foxglove/schemas, dumped by scripts/foxglove_schemas.js), others against the
  schema embedded in the file.
* TUM: `evo_ape tum REF EST` must run on the exported trajectory, and evo's APE against the
  trajectory that was imported must stay below 1 mm (the log stores millimetres).
* GeoJSON: a FeatureCollection whose coordinates are longitude/latitude pairs.

    python scripts/validate_export.py --schemas foxglove.json --mcap a.mcap [--mcap b.mcap] \\
        --tum-ref ego.tum --tum-est exported.tum --geojson drive.geojson
"""
import argparse
import collections
import json
import os
import subprocess
import sys

import jsonschema
from mcap.reader import make_reader


def check_mcap(path, official):
    counts = collections.Counter()
    validators = {}
    errors = []
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages():
            name = schema.name
            if name not in validators:
                if name.startswith("foxglove."):
                    if name not in official:
                        errors.append(f"{path}: {name} is not an official Foxglove schema")
                        continue
                    spec = official[name]
                else:
                    spec = json.loads(schema.data)
                validators[name] = jsonschema.Draft202012Validator(spec)
            data = json.loads(message.data)
            for e in validators[name].iter_errors(data):
                errors.append(f"{path}: {channel.topic} ({name}) at {message.log_time}: {e.message}")
                break
            counts[channel.topic] += 1
    total = sum(counts.values())
    if summary is None or summary.statistics is None or summary.statistics.message_count != total:
        errors.append(f"{path}: statistics do not match the {total} messages read")
    return counts, errors


def check_tum(reference, estimate):
    # evo's CLI from the same environment as this interpreter.
    evo_ape = os.path.join(os.path.dirname(sys.executable), "evo_ape")
    cli = subprocess.run([evo_ape, "tum", reference, estimate], capture_output=True, text=True)
    if cli.returncode != 0:
        return None, [f"evo_ape failed on {estimate}: {cli.stderr.strip()}"]
    from evo.core import metrics, sync
    from evo.tools import file_interface

    ref = file_interface.read_tum_trajectory_file(reference)
    est = file_interface.read_tum_trajectory_file(estimate)
    ref, est = sync.associate_trajectories(ref, est, max_diff=0.001)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    stats = ape.get_all_statistics()
    errors = [] if stats["max"] < 1e-3 else [f"APE max {stats['max']} m ≥ 1 mm"]
    return {"poses": ref.num_poses, "ape_max_m": stats["max"], "ape_rmse_m": stats["rmse"]}, errors


def check_geojson(path):
    g = json.load(open(path))
    errors = []
    if g.get("type") != "FeatureCollection" or not g.get("features"):
        errors.append(f"{path}: not a non-empty FeatureCollection")
    for f in g.get("features", []):
        geom = f["geometry"]
        coords = geom["coordinates"] if geom["type"] == "LineString" else [geom["coordinates"]]
        if not all(-180 <= lon <= 180 and -90 <= lat <= 90 for lon, lat in coords):
            errors.append(f"{path}: coordinates out of range in {f['properties']}")
    kinds = collections.Counter(f["geometry"]["type"] for f in g.get("features", []))
    return dict(kinds), errors


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--schemas", required=True)
    ap.add_argument("--mcap", action="append", default=[])
    ap.add_argument("--tum-ref")
    ap.add_argument("--tum-est")
    ap.add_argument("--geojson", action="append", default=[])
    args = ap.parse_args()
    official = json.load(open(args.schemas))
    report, errors = {}, []
    for path in args.mcap:
        counts, e = check_mcap(path, official)
        report[path] = dict(counts)
        errors += e
    if args.tum_ref and args.tum_est:
        result, e = check_tum(args.tum_ref, args.tum_est)
        report["tum"] = result
        errors += e
    for path in args.geojson:
        kinds, e = check_geojson(path)
        report[path] = kinds
        errors += e
    print(json.dumps(report, indent=1))
    for e in errors[:20]:
        print("error:", e, file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
