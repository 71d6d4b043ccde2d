//! `sweep.png`: a sweep at a glance — the distribution (CDF) of the online and finished ego
//! APE, the CDF of the nuPlan-style score of the truth, the online and the finished log,
//! and the confusion tables of the verdicts.

use std::path::Path;

use plotters::prelude::*;

use super::rows::Row;
use super::summary::{Confusion, Summary};
use dash2sim_linux::Result;
use dash2sim_verify::plot::{err, register_font, FINISHED, GNSS, ONLINE};

const SIZE: (u32, u32) = (1400, 900);

/// The empirical CDF of `values` as (value, fraction ≤ value) steps.
fn cdf(values: impl Iterator<Item = Option<f64>>) -> Vec<(f64, f64)> {
    let mut v: Vec<f64> = values.flatten().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len() as f64;
    v.iter().enumerate().flat_map(|(k, &x)| [(x, k as f64 / n), (x, (k + 1) as f64 / n)]).collect()
}

/// Draw the sweep's picture to `path` (PNG).
pub fn draw(rows: &[Row], summary: &Summary, path: &Path) -> Result<()> {
    register_font()?;
    let root = BitMapBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let (top, bottom) = root.split_vertically(560);
    let (ape_area, score_area) = top.split_horizontally(SIZE.0 / 2);
    let ok = || rows.iter().filter(|r| r.error.is_none());

    let ape = [
        ("online ego APE", ONLINE, cdf(ok().map(|r| r.online_ape_m))),
        ("finished ego APE", FINISHED, cdf(ok().map(|r| r.finished_ape_m))),
    ];
    let ape_max = ape.iter().flat_map(|(_, _, c)| c.iter().map(|p| p.0)).fold(1.0f64, f64::max).min(50.0);
    let mut chart = ChartBuilder::on(&ape_area)
        .caption("ego APE per drive (RMSE), CDF (beyond 50 m at the edge)", ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d((0.01f64..ape_max * 1.1).log_scale(), 0.0f64..1.0)
        .map_err(err)?;
    chart.configure_mesh().x_desc("m (log scale)").y_desc("fraction of drives").draw().map_err(err)?;
    for (label, colour, points) in ape {
        chart
            .draw_series(LineSeries::new(points.into_iter().map(|(x, y)| (x.max(0.01), y)), colour.stroke_width(3)))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], colour.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .border_style(BLACK)
        .draw()
        .map_err(err)?;

    let mut chart = ChartBuilder::on(&score_area)
        .caption("nuPlan-style score per drive (channel-insensitive), CDF", ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0f64..100.0, 0.0f64..1.0)
        .map_err(err)?;
    chart.configure_mesh().x_desc("score (> 90 verified)").y_desc("fraction of drives").draw().map_err(err)?;
    let score = |f: fn(&Row) -> Option<f64>| cdf(ok().map(f));
    for (label, colour, points) in [
        ("truth", BLACK, score(|r| r.truth.as_ref().map(|v| v.insensitive.score))),
        ("online", ONLINE, score(|r| r.online.as_ref().map(|v| v.insensitive.score))),
        ("finished", FINISHED, score(|r| r.finished.as_ref().map(|v| v.insensitive.score))),
    ] {
        chart
            .draw_series(LineSeries::new(points, colour.stroke_width(3)))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], colour.stroke_width(3)));
    }
    chart.draw_series(LineSeries::new([(90.0, 0.0), (90.0, 1.0)], GNSS.stroke_width(1))).map_err(err)?;
    chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).border_style(BLACK).draw().map_err(err)?;

    let title = format!(
        "{} drives, seeds {}, {} profile, {} receiver, {} anchors (simulated{}{}); verdicts: rows the truth, columns the log",
        summary.drives,
        summary.seeds,
        summary.profile,
        summary.receiver,
        summary.anchors,
        if summary.oracle_latency { ", ORACLE: true GNSS latency" } else { "" },
        if summary.relative_motion == "imu-wheels" { ", no VO: gyro + wheels" } else { "" }
    );
    bottom.draw(&Text::new(title, (30, 20), ("sans-serif", 20))).map_err(err)?;
    let tables: [(&str, &Confusion); 4] = [
        ("finished", &summary.confusion.finished),
        ("finished, channel-sens.", &summary.confusion.finished_channel_sensitive),
        ("online, whole drive", &summary.confusion.online),
        ("device windows", &summary.confusion.device_windows),
    ];
    for (k, (name, c)) in tables.iter().enumerate() {
        let x = 30 + k as i32 * 340;
        let text = |s: String, dx: i32, dy: i32| Text::new(s, (x + dx, 70 + dy), ("sans-serif", 18));
        let agreement = c.agreement().map_or_else(|| "–".to_owned(), |a| format!("{:.1} %", 100.0 * a));
        bottom.draw(&text(format!("{name}: agree {agreement}"), 0, 0)).map_err(err)?;
        bottom.draw(&text("log ✓".to_owned(), 130, 40)).map_err(err)?;
        bottom.draw(&text("log ✗".to_owned(), 220, 40)).map_err(err)?;
        for (row, (label, a, b)) in [
            ("truth ✓", c.truth_verified_log_verified, c.truth_verified_log_rejected),
            ("truth ✗", c.truth_rejected_log_verified, c.truth_rejected_log_rejected),
        ]
        .into_iter()
        .enumerate()
        {
            let dy = 80 + row as i32 * 40;
            bottom.draw(&text(label.to_owned(), 0, dy)).map_err(err)?;
            bottom.draw(&text(a.to_string(), 140, dy)).map_err(err)?;
            bottom.draw(&text(b.to_string(), 230, dy)).map_err(err)?;
        }
    }
    root.present().map_err(err)
}
