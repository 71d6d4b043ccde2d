//! Geodesy against pymap3d on the real comma2k19 positions: geodetic and ENU within 1 mm.
//! The pymap3d values come from `scripts/crosscheck_geo_pymap3d.py`.

use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_tests::{data_dir, workspace_root};

fn numbers(line: &str) -> Vec<f64> {
    line.split(',').map(|v| v.trim().parse().expect("number")).collect()
}

#[test]
fn geodetic_and_enu_agree_with_pymap3d_within_a_millimetre() {
    let Some(dir) = data_dir("comma2k19") else { return };
    let frames = std::fs::read_to_string(dir.join("expected/global_pose_frames.csv")).expect("frames");
    let ecef: Vec<Vector3<f64>> = frames.lines().skip(1).map(numbers).map(|v| Vector3::new(v[4], v[5], v[6])).collect();
    let fixture =
        std::fs::read_to_string(workspace_root().join("tests/fixtures/pymap3d_comma2k19.csv")).expect("fixture");
    let expected: Vec<Vec<f64>> =
        fixture.lines().filter(|l| !l.starts_with('#') && !l.starts_with("frame")).map(numbers).collect();
    assert_eq!(expected.len(), ecef.len());

    let origin = Geodetic::from_ecef(&ecef[0]).expect("origin");
    let frame = LocalFrame::new(origin);
    let (mut worst_geo, mut worst_enu) = (0.0f64, 0.0f64);
    for (p, want) in ecef.iter().zip(&expected) {
        let g = Geodetic::from_ecef(p).expect("geodetic");
        let want_g = Geodetic::new(want[1], want[2], want[3]).expect("valid");
        // Compare geodetic positions as the distance between their ECEF points.
        worst_geo = worst_geo.max((g.to_ecef() - want_g.to_ecef()).norm()).max((g.height_m - want[3]).abs());
        let enu = frame.ecef_to_enu(p);
        worst_enu = worst_enu.max((enu - Vector3::new(want[4], want[5], want[6])).norm());
    }
    eprintln!(
        "worst difference to pymap3d: geodetic {worst_geo:.3e} m, ENU {worst_enu:.3e} m over {} positions",
        ecef.len()
    );
    assert!(worst_geo < 1e-3 && worst_enu < 1e-3);
}
