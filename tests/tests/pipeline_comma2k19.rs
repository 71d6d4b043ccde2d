//! The comma2k19 minute through `dash2sim record` (issue #12): the real u-blox fixes as a
//! serial capture, the real Toyota CAN through the DBC (0xB4 SPEED), and VO made from the
//! fused poses through an unknown Sim(3) with drift (as the anchoring test builds it).
//! Targets: the anchoring test's — scale error < 0.3 % at 60 s, ATE ≤ 1.35 m.

use dash2sim_core::binlog::Record;
use dash2sim_core::nalgebra::Vector3;
use dash2sim_sim::datasets::comma::record_minute;
use dash2sim_sim::scenario::vo::VoModel;
use dash2sim_tests::recorded::scratch;

#[test]
fn the_comma2k19_minute_anchors_through_the_pipeline_as_in_the_anchoring_test() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let work = scratch("comma-record");
    let model = VoModel::arbitrary();
    let recorded = record_minute(&dir, &work, &model, 1).expect("record");
    let (truth, log, device) = (&recorded.truth, &recorded.log, &recorded.device);
    let t0 = truth.stamps[0];
    let truth_at = |t: f64| {
        let k = truth.stamps.iter().position(|s| (s - t).abs() < 1e-4).unwrap_or_else(|| {
            panic!(
                "no pose at {t}: nearest {:?}",
                truth.stamps.iter().map(|s| (s - t).abs()).fold(f64::INFINITY, f64::min)
            )
        });
        truth.poses[k].translation
    };
    let (mut sse, mut n, mut first) = (0.0, 0, None);
    for (r, &t) in log.records.iter().zip(device) {
        if let Record::EgoPose(p) = r {
            first.get_or_insert(t - t0);
            let e = Vector3::new(p.x_mm as f64, p.y_mm as f64, p.z_mm as f64) * 1e-3 - truth_at(t);
            sse += e.norm_squared();
            n += 1;
        }
    }
    let ate = (sse / n as f64).sqrt();
    let (t, scale) = log
        .records
        .iter()
        .zip(device)
        .rev()
        .find_map(|(r, t)| if let Record::AnchorEstimate(a) = r { Some((*t, a.scale_e6 as f64 * 1e-6)) } else { None })
        .expect("an anchor estimate");
    let scale_error = scale / model.scale_at(t - t0) - 1.0;
    let clock = log.records.iter().filter(|r| matches!(r, Record::ClockOffset(_))).count();
    let speeds = log.records.iter().filter(|r| matches!(r, Record::VehicleSpeed(_))).count();
    let fixes = log.records.iter().filter(|r| matches!(r, Record::GnssFix(_))).count();
    println!(
        "comma2k19 through record: anchored after {:.2} s, {n} ego poses, ATE {ate:.3} m, scale error {:+.3} % at {:.1} s; {fixes} fixes, {speeds} speeds, {clock} clock offsets, {} bytes",
        first.unwrap_or(f64::NAN),
        100.0 * scale_error,
        t - t0,
        log.bytes
    );
    assert_eq!((fixes, speeds), (579, 2487), "every u-blox fix and every 0xB4 frame");
    assert!(t - t0 > 59.0, "the last estimate is at the end");
    assert!(scale_error.abs() < 0.003, "scale error {scale_error}");
    assert!(ate <= 1.35, "ATE {ate}");
    assert!(first.expect("anchored") < 10.0);
}
