#!/usr/bin/env python3
"""Write pymap3d's geodetic and ENU coordinates of the comma2k19 camera positions.

dash2sim's `geo` module is checked against pymap3d (an independent, widely used
implementation) on real positions: tests/tests/geo_pymap3d.rs reads the ECEF inputs from
the shared data folder and compares with the values this script writes. Only pymap3d's
outputs are stored in the repository, not the recording.

Usage (pymap3d in a venv; it is never a runtime dependency):
    python3 -m venv /tmp/venv && /tmp/venv/bin/pip install pymap3d
    /tmp/venv/bin/python scripts/crosscheck_geo_pymap3d.py \
        ../shared/data/comma2k19/expected/global_pose_frames.csv tests/fixtures/pymap3d_comma2k19.csv
"""
import csv
import sys

import pymap3d


def main(src: str, dst: str) -> None:
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    ecef = [(float(r["ecef_x_m"]), float(r["ecef_y_m"]), float(r["ecef_z_m"])) for r in rows]
    lat0, lon0, h0 = pymap3d.ecef2geodetic(*ecef[0])
    with open(dst, "w", newline="") as f:
        f.write(f"# pymap3d {pymap3d.__version__}: geodetic (WGS84) and ENU at frame 0 of comma2k19 global_pose_frames.csv\n")
        f.write(f"# origin {float(lat0)!r} {float(lon0)!r} {float(h0)!r}\n")
        f.write("frame_idx,lat_deg,lon_deg,h_m,e_m,n_m,u_m\n")
        for k, (x, y, z) in enumerate(ecef):
            lat, lon, h = pymap3d.ecef2geodetic(x, y, z)
            e, n, u = pymap3d.ecef2enu(x, y, z, lat0, lon0, h0)
            f.write(f"{k},{float(lat)!r},{float(lon)!r},{float(h)!r},{float(e)!r},{float(n)!r},{float(u)!r}\n")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
