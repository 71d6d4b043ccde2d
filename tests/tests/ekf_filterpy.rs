//! The core Kalman filter against filterpy's `KalmanFilter` with AB3DMOT's settings
//! (fixture from `scripts/make_ekf_fixture.py`): every predicted and updated state and
//! covariance within 1e-9, and the RTS-smoothed track equals filterpy's `rts_smoother`.

use dash2sim_core::ekf::{rts_smooth, Kalman, SmoothStep};
use dash2sim_core::nalgebra::{SMatrix, SVector};

#[test]
fn ab3dmot_sequence_equals_filterpy() {
    let path = dash2sim_tests::workspace_root().join("tests/fixtures/ekf_ab3dmot_filterpy.csv");
    let text = std::fs::read_to_string(&path).expect("fixture");
    let rows: Vec<Vec<f64>> =
        text.lines().map(|l| l.split(',').map(|v| v.parse().expect("number")).collect()).collect();
    let state = |r: &[f64]| SVector::<f64, 10>::from_column_slice(&r[8..18]);
    let cov = |r: &[f64]| SMatrix::<f64, 10, 10>::from_row_slice(&r[18..118]);
    let mut f = SMatrix::<f64, 10, 10>::identity();
    f[(0, 7)] = 1.0;
    f[(1, 8)] = 1.0;
    f[(2, 9)] = 1.0;
    let mut q = SMatrix::<f64, 10, 10>::identity();
    for i in 7..10 {
        q[(i, i)] = 0.01;
    }
    let mut h = SMatrix::<f64, 7, 10>::zeros();
    for i in 0..7 {
        h[(i, i)] = 1.0;
    }
    let r = SMatrix::<f64, 7, 7>::identity();
    assert_eq!(rows[0][0], 0.0);
    let mut kf = Kalman::new(state(&rows[0]), cov(&rows[0]));
    let (mut updates, mut worst) = (0, 0.0f64);
    // The posterior of every frame, for the smoother (F and Q led into it).
    let mut steps = vec![SmoothStep { x: kf.x, p: kf.p, f, q }];
    let filtered: Vec<&Vec<f64>> = rows[1..].iter().filter(|r| r[0] != 3.0).collect();
    for row in filtered {
        match row[0] as u8 {
            1 => {
                kf.predict(&f, &q);
                steps.push(SmoothStep { x: kf.x, p: kf.p, f, q });
            }
            2 => {
                kf.update(&SVector::<f64, 7>::from_column_slice(&row[1..8]), &h, &r).expect("update");
                updates += 1;
                let last = steps.last_mut().expect("a predicted frame");
                (last.x, last.p) = (kf.x, kf.p);
            }
            k => panic!("kind {k}"),
        }
        let scale = 1.0 + state(row).abs().max().max(cov(row).abs().max());
        let diff = (kf.x - state(row)).abs().max().max((kf.p - cov(row)).abs().max()) / scale;
        assert!(diff < 1e-9, "step {row:?}: relative difference {diff}");
        worst = worst.max(diff);
    }
    println!(
        "{} steps ({updates} updates) equal filterpy, worst relative difference {worst:.1e}",
        steps.len() - 1 + updates
    );
    assert_eq!(updates, 32);

    let expected: Vec<&Vec<f64>> = rows.iter().filter(|r| r[0] == 3.0).collect();
    assert_eq!(expected.len(), steps.len());
    let before = steps.clone();
    assert_eq!(rts_smooth(&mut steps), 0);
    let mut worst = 0.0f64;
    for (k, (step, row)) in steps.iter().zip(&expected).enumerate() {
        let scale = 1.0 + state(row).abs().max().max(cov(row).abs().max());
        let diff = (step.x - state(row)).abs().max().max((step.p - cov(row)).abs().max()) / scale;
        assert!(diff < 1e-9, "smoothed frame {k}: relative difference {diff}");
        worst = worst.max(diff);
    }
    // Smoothing changed the early frames (the test would pass vacuously otherwise).
    assert!((before[0].x - steps[0].x).norm() > 0.1);
    println!("{} smoothed frames equal filterpy's rts_smoother, worst relative difference {worst:.1e}", steps.len());
}
