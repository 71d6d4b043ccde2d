//! comma2k19's Toyota RAV4: wheel speeds from the raw bus (`raw_can.candump.log`, bus 0,
//! id 0xAA WHEEL_SPEEDS) decoded with opendbc's `_toyota_2017.dbc` must equal comma's own
//! decoding (`expected/can_wheel_speeds_mps.csv`), sample for sample.

use dash2sim_tests::can::{decode_capture, printed_tolerance, read_csv};
use dash2sim_tests::data_dir;

#[test]
fn toyota_wheel_speeds_equal_commas_decoding() {
    let Some(comma) = data_dir("comma2k19") else { return };
    let (messages, problems, summary) =
        decode_capture(&comma.join("raw_can.candump.log"), &[comma.join("opendbc-toyota/_toyota_2017.dbc")]);
    assert_eq!(summary.bad_lines, 0, "{problems:?}");
    let (header, rows) = read_csv(&comma.join("expected/can_wheel_speeds_mps.csv"));
    assert_eq!(header, ["t_boot_s", "fl_mps", "fr_mps", "rl_mps", "rr_mps"]);
    let ours: Vec<_> = messages.iter().filter(|m| m["message"] == "WHEEL_SPEEDS" && m["bus"] == "can0").collect();
    assert_eq!(ours.len(), rows.len());
    let mut worst = 0.0f64;
    for (i, (m, row)) in ours.iter().zip(&rows).enumerate() {
        let t = m["t"].as_f64().expect("timestamp");
        assert!((t - row[0].parse::<f64>().expect("t")).abs() < 1e-6, "row {i}");
        for (signal, cell) in
            ["WHEEL_SPEED_FL", "WHEEL_SPEED_FR", "WHEEL_SPEED_RL", "WHEEL_SPEED_RR"].iter().zip(&row[1..])
        {
            let mps = m["fields"][signal].as_f64().expect("signal") / 3.6;
            let want: f64 = cell.parse().expect("number");
            assert!((mps - want).abs() <= printed_tolerance(cell), "row {i} {signal}: {mps} vs {cell}");
            worst = worst.max((mps - want).abs());
        }
    }
    println!("{} WHEEL_SPEEDS frames, 4 wheels each, worst difference {worst:.2e} m/s", rows.len());
}
