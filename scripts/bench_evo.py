#!/usr/bin/env python3
"""Time evo's Python pipeline on KITTI 00 (4541 poses): the work `dash2sim traj ape/rpe`
does, in-process (file reading, alignment, metric, statistics). Best of N runs.

Usage: /tmp/venv/bin/python scripts/bench_evo.py ../shared/data/evo
(evo in a venv: pip install evo; evo is never a runtime dependency of dash2sim.)
"""
import sys
import timeit

from evo.core import metrics
from evo.tools import file_interface


def main(data: str) -> None:
    gt, orb = f"{data}/KITTI_00_gt.txt", f"{data}/KITTI_00_ORB.txt"

    def ape_sim3():
        ref = file_interface.read_kitti_poses_file(gt)
        est = file_interface.read_kitti_poses_file(orb)
        est.align(ref, correct_scale=True)
        m = metrics.APE(metrics.PoseRelation.translation_part)
        m.process_data((ref, est))
        return m.get_all_statistics()

    def rpe_10m():
        ref = file_interface.read_kitti_poses_file(gt)
        est = file_interface.read_kitti_poses_file(orb)
        m = metrics.RPE(metrics.PoseRelation.translation_part, 10.0, metrics.Unit.meters, 0.1, False)
        m.process_data((ref, est))
        return m.get_all_statistics()

    print("rmse check:", ape_sim3()["rmse"], rpe_10m()["rmse"])
    for name, fn in [("ape_sim3_end_to_end", ape_sim3), ("rpe_10m_end_to_end", rpe_10m)]:
        best = min(timeit.repeat(fn, number=1, repeat=7))
        print(f"evo {name}: {best * 1e3:.1f} ms (best of 7)")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/evo")
