"""comma2k19's IMU (NumPy arrays) as the `dash2sim record --imu` CSV, written independently of
dash2sim: the raw gyro (`gyro_uncalibrated`, rad/s) and the accelerometer (m/s²), axes forward,
right, down, stamped with the device's boot time. Usage: comma_imu_csv.py COMMA2K19_DIR OUT.csv"""
import sys

import numpy as np

d = sys.argv[1] + "/b0c9d2329ad1606b_2018-08-02--08-34-47_40/processed_log/IMU/"
t, g = np.load(d + "gyro_uncalibrated/t"), np.load(d + "gyro_uncalibrated/value")
ta, a = np.load(d + "accelerometer/t"), np.load(d + "accelerometer/value")
assert (t == ta).all(), "the gyro and the accelerometer are sampled together"
with open(sys.argv[2], "w") as f:
    f.write("t_s,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z\n")
    for k in range(len(t)):
        f.write(",".join(["%.6f" % t[k]] + ["%.17g" % v for v in (*g[k], *a[k])]) + "\n")
