//! `dash2sim demo --data`'s two real recordings through the product (issue #17), against
//! their peers: cantools' decoding and the module's own odometer for the CSS CANedge drive
//! (GNSS over CAN through `canmod-gps.dbc`), evo's GNSS error and comma's fused poses for
//! the comma2k19 minute.

use dash2sim_sim::datasets::OutputFile;
use dash2sim_sim::datasets::{comma, css};
use dash2sim_tests::recorded::scratch;

fn files_exist(files: &[OutputFile]) {
    for f in files {
        let path = &f.path;
        let len = std::fs::metadata(path).unwrap_or_else(|e| panic!("{path}: {e}")).len();
        assert!(len > 0, "{path} is empty");
    }
}

#[test]
fn the_css_drive_logs_every_can_fix_and_speed_in_utc_and_its_fixes_agree_with_the_odometer_and_obd() {
    let Some(dir) = dash2sim_tests::data_dir("css-electronics-canedge") else { return };
    let s = css::run(&dir, &scratch("recordings-css")).expect("the CSS drive");
    println!("{s:#?}");
    let r = &s.recording;
    assert_eq!(s.candump_files, 5);
    // Every CANmod position frame, as cantools decodes them: 2161 fixes, 111 without one.
    assert_eq!(r.fixes, r.fixes_valid_by_cantools as u64);
    assert_eq!(r.fixes, 2161);
    assert_eq!(r.positions_without_fix, r.positions_without_fix_by_cantools as u64);
    // Every OBD-II PID 0x0D response.
    assert_eq!(r.speeds, r.speeds_in_reference as u64);
    assert_eq!(r.speeds, 4785);
    // The log's clock: logger − GNSS of the first epoch from the raw frames (t of its
    // gnss_pos − its gnss_time Epoch, decoded independently with python) is 4.5281 s; every
    // epoch of the session lies within 4.281–4.793 s.
    let c = &s.clock;
    let first = c.logger_minus_gnss_first_s.expect("clock offsets");
    assert!((first - 4.5281).abs() < 2e-3, "{c:?}");
    let (min, max) = (c.logger_minus_gnss_min_s.expect("min"), c.logger_minus_gnss_max_s.expect("max"));
    assert!(min >= 4.280 && max <= 4.794, "{c:?}");
    // The fixes against the module's trip odometer (40.579 km) and the OBD speed.
    let d = &s.drive;
    assert!((d.distance_km / d.module_odometer_km.expect("odometer") - 1.0).abs() < 0.005, "{d:?}");
    let v = &s.speed_check;
    assert!(v.pairs > 3500 && v.correlation > 0.99 && v.mean_abs_diff_kmh < 1.5, "{v:?}");
    files_exist(&s.files);
}

#[test]
fn the_comma2k19_minute_is_anchored_online_and_finishing_improves_it() {
    let Some(dir) = dash2sim_tests::data_dir("comma2k19") else { return };
    let s = comma::run(&dir, &scratch("recordings-comma")).expect("the comma2k19 minute");
    println!("{s:#?}");
    let p = &s.recording.pipeline.stats;
    assert_eq!((p.fixes, p.speeds), (579, 2487), "every fix and 0xB4 frame");
    assert_eq!(p.fixes, s.recording.fixes_in_csv as u64);
    let gnss = s.gnss_alone.ape_rmse_m.expect("evo's APE");
    let (online, finished) = (&s.online.compared, &s.finished.compared);
    // Anchored VO beats the fixes it was anchored to (evo: 1.81 m); finished beats online
    // where both are (finishing also has the seconds before the device anchored).
    assert!(online.ape_rmse <= 1.35 && online.ape_rmse < gnss, "{online:?}");
    let same_stretch = &s.finished.compared_where_online;
    assert!(same_stretch.matched.abs_diff(online.matched) <= 2, "{same_stretch:?} vs {online:?}");
    assert!(same_stretch.ape_rmse < online.ape_rmse, "{same_stretch:?} vs {online:?}");
    assert!(finished.ape_max < online.ape_max, "{finished:?} vs {online:?}");
    assert!(finished.matched > online.matched && finished.ape_rmse <= 1.3, "{finished:?}");
    assert!(online.first_s < 10.0, "{online:?}");
    let scale = s.online.anchor_scale_error_at_end.expect("a full anchor");
    assert!(scale.abs() < 0.003, "{:?}", s.online);
    assert!(finished.scale_error.abs() <= 1e-3, "{finished:?}");
    files_exist(&s.files);
}
