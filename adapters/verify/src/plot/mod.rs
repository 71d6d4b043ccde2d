//! `dash2sim plot`: a drive at a glance (`docs/plot.md`). A bird's-eye view like the
//! Dash2Sim paper's trajectory figure — map lanes in grey, raw GNSS fixes in red, the online
//! anchored ego in orange, the finished ego in blue, 3D tracks by class with distinct
//! markers; scale bar, north arrow, legend — above the speed and the verification metrics
//! over time, verified windows shaded. SVG or PNG; the PNG's text is drawn with a font
//! shipped in the binary (DejaVu Sans), so it renders the same on every machine.

mod scene;

use std::path::{Path, PathBuf};

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

use dash2sim_core::score::Decision;
use dash2sim_linux::log;
use dash2sim_linux::{Error, Result};
use scene::Scene;

/// Picture size, px: the map on top, speed and scores below.
const SIZE: (u32, u32) = (1200, 1400);
const MAP_HEIGHT: u32 = 900;
/// Colours: the paper's (GNSS red, online orange, finished blue), lanes grey.
const LANE: RGBColor = RGBColor(205, 205, 205);
/// The GNSS fixes' colour (the sweep's picture draws with the same).
pub const GNSS: RGBColor = RGBColor(214, 39, 40);
/// The device's (online) ego's colour.
pub const ONLINE: RGBColor = RGBColor(255, 127, 14);
/// The finished ego's colour.
pub const FINISHED: RGBColor = RGBColor(31, 119, 180);
const VERIFIED: RGBColor = RGBColor(200, 235, 200);
const UNDECIDED: RGBColor = RGBColor(250, 230, 180);
/// The font the PNG's text is drawn with.
static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// A drive to draw (`dash2sim plot`).
#[derive(Debug, Clone)]
pub struct PlotRequest {
    /// The log (the device's, or a finished one).
    pub log: PathBuf,
    /// A map tile (`map build`): its lanes under the drive, in grey.
    pub map: Option<PathBuf>,
    /// The finished log of the same drive (`finish`), drawn in blue over the online one.
    pub finished: Option<PathBuf>,
    /// The picture: `.svg` or `.png`.
    pub output: PathBuf,
}

/// What a plot shows, for the caller's summary and the tests.
#[derive(Debug, Clone, PartialEq)]
pub struct Drawn {
    /// Map lanes drawn.
    pub lanes: usize,
    /// Online and finished ego poses, GNSS fixes.
    pub poses: (usize, usize, usize),
    /// Tracks by class.
    pub tracks: Vec<(&'static str, usize)>,
    /// Verification windows, and how many verified.
    pub windows: (usize, usize),
}

/// Draw `args.log` (and its map and finished log) to `args.output`.
pub fn plot(args: &PlotRequest) -> Result<Drawn> {
    let read = |p: &Path| log::read(p).map_err(|e| Error::file(p, e));
    let log = read(&args.log)?;
    let finished = args.finished.as_deref().map(read).transpose()?;
    let tile = args.map.as_deref().map(|p| std::fs::read(p).map_err(|e| Error::file(p, e))).transpose()?;
    let scene = Scene::new(&log, finished.as_ref(), tile.as_deref()).map_err(|e| Error::file(&args.log, e))?;
    register_font()?;
    let extension = args.output.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase();
    match extension.as_str() {
        "svg" => draw(SVGBackend::new(&args.output, SIZE).into_drawing_area(), &scene),
        "png" => draw(BitMapBackend::new(&args.output, SIZE).into_drawing_area(), &scene),
        _ => Err(Error::file(&args.output, "the picture must end in .svg or .png")),
    }?;
    Ok(scene.drawn())
}

/// Make the shipped font the `sans-serif` of every picture. Both backends measure text with
/// it (SVG to lay out the legend). Registering twice is harmless; a font that does not
/// parse is a build fault.
pub fn register_font() -> Result<()> {
    plotters::style::register_font("sans-serif", FontStyle::Normal, FONT)
        .map_err(|_| Error::invalid("the shipped font does not parse"))
}

/// A drawing backend's error as the library's.
pub fn err<E: std::fmt::Debug>(e: E) -> Error {
    Error::other(format!("drawing: {e:?}"))
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, scene: &Scene) -> Result<()> {
    root.fill(&WHITE).map_err(err)?;
    let (map_area, rest) = root.split_vertically(MAP_HEIGHT);
    let (speed_area, score_area) = rest.split_vertically((SIZE.1 - MAP_HEIGHT) / 2);
    draw_map(&map_area, scene)?;
    draw_speed(&speed_area, scene)?;
    draw_scores(&score_area, scene)?;
    root.present().map_err(err)
}

/// The chart's legend: every labelled series, on a white box.
fn legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    position: SeriesLabelPosition,
    font_size: u32,
) -> Result<()> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", font_size))
        .draw()
        .map_err(err)
}

/// Round length near a fifth of `span`, m: 1, 2 or 5 × 10ⁿ.
fn scale_bar_length(span: f64) -> f64 {
    let target = (span / 5.0).max(1.0);
    let magnitude = 10f64.powf(target.log10().floor());
    [1.0, 2.0, 5.0, 10.0].into_iter().map(|m| m * magnitude).rfind(|&l| l <= target).unwrap_or(magnitude)
}

fn draw_map<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, scene: &Scene) -> Result<()> {
    let (w, h) = area.dim_in_pixel();
    // Equal scale in x and y: widen the shorter side of the drive's box.
    let [x0, y0, x1, y1] = scene.bounds;
    let (plot_w, plot_h) = (f64::from(w) - 90.0, f64::from(h) - 90.0);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let per_px = ((x1 - x0) / plot_w).max((y1 - y0) / plot_h);
    let (half_w, half_h) = (per_px * plot_w / 2.0, per_px * plot_h / 2.0);
    let mut chart = ChartBuilder::on(area)
        .caption("bird's-eye view (east, north in the log's ENU frame)", ("sans-serif", 22))
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(cx - half_w..cx + half_w, cy - half_h..cy + half_h)
        .map_err(err)?;
    chart.configure_mesh().x_desc("east, m").y_desc("north, m").light_line_style(WHITE).draw().map_err(err)?;
    if !scene.lanes.is_empty() {
        let mut lanes = scene.lanes.iter();
        if let Some(first) = lanes.next() {
            chart
                .draw_series(std::iter::once(Polygon::new(first.clone(), LANE.filled())))
                .map_err(err)?
                .label("map lanes (drivable area)")
                .legend(|(x, y)| Rectangle::new([(x - 8, y - 5), (x + 8, y + 5)], LANE.filled()));
        }
        chart.draw_series(lanes.map(|ring| Polygon::new(ring.clone(), LANE.filled()))).map_err(err)?;
    }
    if !scene.fixes.is_empty() {
        chart
            .draw_series(scene.fixes.iter().map(|&p| Circle::new(p, 2, GNSS.filled())))
            .map_err(err)?
            .label("GNSS fixes (raw)")
            .legend(|(x, y)| Circle::new((x, y), 3, GNSS.filled()));
    }
    for (series, colour, label) in
        [(&scene.online, ONLINE, "online anchored ego"), (&scene.finished, FINISHED, "finished ego")]
    {
        if series.points.is_empty() {
            continue;
        }
        chart
            .draw_series(LineSeries::new(series.points.iter().map(|&(_, x, y)| (x, y)), colour.stroke_width(3)))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], colour.stroke_width(3)));
    }
    for (class, points) in &scene.tracks {
        let style = marker_style(class);
        let shape = marker_shape(class);
        let series = chart
            .draw_series(points.iter().map(|&p| EmptyElement::at(p) + Polygon::new(shape.clone(), style)))
            .map_err(err)?;
        series.label(*class).legend(move |p| EmptyElement::at(p) + Polygon::new(marker_shape(class), style));
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft, 16)?;
    // Scale bar (bottom right) and north arrow (top right), in pixels.
    let length = scale_bar_length(2.0 * half_w);
    let bar_px = (length / per_px) as i32;
    let (right, bottom) = (w as i32 - 40, h as i32 - 60);
    area.draw(&PathElement::new(vec![(right - bar_px, bottom), (right, bottom)], BLACK.stroke_width(3)))
        .map_err(err)?;
    area.draw(&Text::new(format!("{length:.0} m"), (right - bar_px, bottom - 22), ("sans-serif", 16))).map_err(err)?;
    let (nx, ny) = (w as i32 - 50, 60);
    area.draw(&PathElement::new(vec![(nx, ny + 40), (nx, ny)], BLACK.stroke_width(3))).map_err(err)?;
    area.draw(&Polygon::new(vec![(nx - 8, ny + 10), (nx, ny - 4), (nx + 8, ny + 10)], BLACK.filled())).map_err(err)?;
    area.draw(&Text::new("N", (nx - 6, ny + 44), ("sans-serif", 18))).map_err(err)?;
    Ok(())
}

fn marker_style(class: &str) -> ShapeStyle {
    match class {
        "cone" => RGBColor(255, 140, 0).filled(),
        "drum" => RGBColor(230, 85, 13).filled(),
        "barricade" | "barrier" => RGBColor(120, 60, 160).filled(),
        "sign" => RGBColor(0, 150, 130).filled(),
        "arrow_board" => RGBColor(0, 90, 200).filled(),
        "pedestrian" | "bicycle" => RGBColor(200, 0, 120).filled(),
        "truck" | "bus" => RGBColor(90, 90, 90).filled(),
        _ => BLACK.filled(),
    }
}

/// A class's marker shape in pixels: cones triangles, drums discs, barricades and barriers
/// squares, signs diamonds, road users crosses.
fn marker_shape(class: &str) -> Vec<(i32, i32)> {
    match class {
        "cone" => vec![(0, -8), (7, 5), (-7, 5)],
        "drum" => (0..12)
            .map(|k| {
                let a = f64::from(k) * std::f64::consts::TAU / 12.0;
                ((6.0 * a.cos()).round() as i32, (6.0 * a.sin()).round() as i32)
            })
            .collect(),
        "barricade" | "barrier" => vec![(-5, -5), (5, -5), (5, 5), (-5, 5)],
        "sign" | "arrow_board" => vec![(0, -7), (7, 0), (0, 7), (-7, 0)],
        _ => vec![
            (-6, -4),
            (-4, -6),
            (0, -2),
            (4, -6),
            (6, -4),
            (2, 0),
            (6, 4),
            (4, 6),
            (0, 2),
            (-4, 6),
            (-6, 4),
            (-2, 0),
        ],
    }
}

/// Time axis of the panels below the map: seconds since the log's first ego pose.
fn time_range(scene: &Scene) -> std::ops::Range<f64> {
    0.0..scene.duration_s.max(1.0)
}

fn draw_speed<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, scene: &Scene) -> Result<()> {
    let top = scene.speeds.iter().flat_map(|s| s.points.iter().map(|&(_, v, _)| v)).fold(1.0f64, f64::max) * 1.1;
    let mut chart = ChartBuilder::on(area)
        .caption("speed", ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(55)
        .build_cartesian_2d(time_range(scene), 0.0..top)
        .map_err(err)?;
    chart.configure_mesh().x_desc("time, s").y_desc("m/s").draw().map_err(err)?;
    shade_verified(&mut chart, scene, top)?;
    for (series, colour) in scene.speeds.iter().zip([RGBColor(90, 90, 90), ONLINE, FINISHED]) {
        if series.points.is_empty() {
            continue;
        }
        chart
            .draw_series(LineSeries::new(series.points.iter().map(|&(t, v, _)| (t, v)), colour.stroke_width(2)))
            .map_err(err)?
            .label(series.label)
            .legend(move |(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], colour.stroke_width(2)));
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight, 14)
}

/// Shades the windows verified (green) and undecided within the log's doubt (amber); a
/// window its log did not decide counts as nuPlan's verdict of its score.
fn shade_verified<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    scene: &Scene,
    top: f64,
) -> Result<()> {
    for (decision, colour, label) in [
        (Decision::Verified, VERIFIED, "verified window (score > 90)"),
        (Decision::Undecided, UNDECIDED, "undecided window (within the log's doubt)"),
    ] {
        let spans: Vec<(f64, f64)> =
            scene.windows.iter().filter(|w| w.verdict() == decision).map(|w| (w.from_s, w.to_s)).collect();
        if spans.is_empty() {
            continue;
        }
        chart
            .draw_series(spans.iter().map(|&(a, b)| Rectangle::new([(a, 0.0), (b, top)], colour.filled())))
            .map_err(err)?
            .label(label)
            .legend(move |(x, y)| Rectangle::new([(x - 8, y - 5), (x + 8, y + 5)], colour.filled()));
    }
    Ok(())
}

/// The metrics' colours, in `scene::METRICS` order.
const METRIC_COLOURS: [RGBColor; 8] = [
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(44, 160, 44),
];

fn draw_scores<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, scene: &Scene) -> Result<()> {
    let mut chart = ChartBuilder::on(area)
        .caption("verification per window (nuPlan metrics, score / 100)", ("sans-serif", 20))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(55)
        .build_cartesian_2d(time_range(scene), 0.0..1.05)
        .map_err(err)?;
    chart.configure_mesh().x_desc("time, s").y_desc("metric").draw().map_err(err)?;
    shade_verified(&mut chart, scene, 1.05)?;
    // Each window's value held over the window (a step line).
    let steps = |value: &dyn Fn(&scene::Window) -> f64| -> Vec<(f64, f64)> {
        scene.windows.iter().flat_map(|w| [(w.from_s, value(w)), (w.to_s, value(w))]).collect()
    };
    for (k, (name, colour)) in scene::METRICS.iter().zip(METRIC_COLOURS).enumerate() {
        let offset = 0.004 * k as f64; // metrics at 1 would hide each other
        chart
            .draw_series(LineSeries::new(steps(&|w| w.metrics[k] - offset), colour.stroke_width(2)))
            .map_err(err)?
            .label(*name)
            .legend(move |(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], colour.stroke_width(2)));
    }
    chart
        .draw_series(LineSeries::new(steps(&|w| w.score / 100.0), BLACK.stroke_width(3)))
        .map_err(err)?
        .label("score / 100")
        .legend(|(x, y)| PathElement::new(vec![(x - 10, y), (x + 10, y)], BLACK.stroke_width(3)));
    legend(&mut chart, SeriesLabelPosition::LowerLeft, 13)
}

#[cfg(test)]
mod tests {
    #[test]
    fn scale_bars_are_round_and_about_a_fifth_of_the_view() {
        assert_eq!(super::scale_bar_length(1000.0), 200.0);
        assert_eq!(super::scale_bar_length(240.0), 20.0);
        assert_eq!(super::scale_bar_length(30.0), 5.0);
        assert_eq!(super::scale_bar_length(2.0), 1.0);
    }
}
