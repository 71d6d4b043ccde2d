//! TUM text (evo's trajectory format): the ego poses of a log, `t x y z qx qy qz qw`.

use std::fmt::Write as _;

use dash2sim_linux::log::views::{ego_enu, ego_poses};
use dash2sim_linux::log::{seconds, LogContents};

/// The ego trajectory as TUM text (`t x y z qx qy qz qw`, heading about z).
pub fn tum(log: &LogContents) -> String {
    let mut out = String::from("# dash2sim export: ego (rear axle) in the log's ENU frame\n");
    for p in ego_poses(log) {
        let (v, yaw) = ego_enu(p);
        let (s, c) = (yaw / 2.0).sin_cos();
        let _ = writeln!(out, "{:.6} {:.3} {:.3} {:.3} 0 0 {s:.9} {c:.9}", seconds(p.t_us), v.x, v.y, v.z);
    }
    out
}
