//! What the plot draws, gathered from the logs and the map in the online log's ENU frame
//! (the map tile and the finished log are taken through geodetic coordinates, so that
//! their origins need not agree with the log's).

use dash2sim_core::binlog::{Record, Verification};
use dash2sim_core::geo::LocalFrame;
use dash2sim_core::map::MapView;
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::score::Decision;

use dash2sim_core::class::name_of as class_name;
use dash2sim_linux::geometry::capsule;
use dash2sim_linux::log::views::last_tracks;
use dash2sim_linux::log::{frame, LogContents};
use dash2sim_linux::{Error, Result};

/// The eight nuPlan metrics of a `Verification` record, in its field order.
pub const METRICS: [&str; 8] = [
    "no at-fault collisions",
    "drivable area",
    "driving direction",
    "making progress",
    "progress",
    "time to collision",
    "speed limit",
    "comfort",
];

/// A polygon ring, m.
type Ring = Vec<(f64, f64)>;

/// Margin around the drive, m.
const MARGIN_M: f64 = 20.0;

/// A line over time: (t s, a, b) — (t, x, y) for a trajectory, (t, v, 0) for a speed.
#[derive(Debug, Clone, Default)]
pub struct Series {
    /// Legend text.
    pub label: &'static str,
    /// The points.
    pub points: Vec<(f64, f64, f64)>,
}

/// One verification window.
#[derive(Debug, Clone)]
pub struct Window {
    /// Start and end, s since the first ego pose.
    pub from_s: f64,
    /// End.
    pub to_s: f64,
    /// The score, 0–100.
    pub score: f64,
    /// The metrics, in [`METRICS`] order.
    pub metrics: [f64; 8],
    /// The window's decision within the log's doubt (none in a log that did not decide it).
    pub decision: Option<Decision>,
}

impl Window {
    /// What the window was decided, or, undecided by its log, nuPlan's verdict of its score.
    pub fn verdict(&self) -> Decision {
        self.decision.unwrap_or_else(|| Decision::of_interval(self.score, self.score))
    }
}

/// Everything the plot shows.
#[derive(Debug, Clone)]
pub struct Scene {
    /// The view: x0, y0, x1, y1 (m).
    pub bounds: [f64; 4],
    /// Map lanes under the view, as capsules (and the tile's drivable polygons).
    pub lanes: Vec<Ring>,
    /// Raw GNSS fixes.
    pub fixes: Vec<(f64, f64)>,
    /// The online anchored ego.
    pub online: Series,
    /// The finished ego.
    pub finished: Series,
    /// Each 3D track's last position, by class.
    pub tracks: Vec<(&'static str, Vec<(f64, f64)>)>,
    /// Speeds: the vehicle's (wheel / CAN), the online ego's and the finished ego's.
    pub speeds: [Series; 3],
    /// Verification windows (the finished log's when there is one).
    pub windows: Vec<Window>,
    /// Seconds from the first ego pose to the last.
    pub duration_s: f64,
    /// Tile lanes drawn.
    lanes_drawn: usize,
}

/// Moves ENU points of one frame into another through geodetic coordinates.
struct Reframe {
    from: LocalFrame,
    to: LocalFrame,
    same: bool,
}

impl Reframe {
    fn new(from: LocalFrame, to: LocalFrame, same: bool) -> Self {
        Self { from, to, same }
    }

    fn point(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        if self.same {
            return Some((x, y));
        }
        let g = self.from.enu_to_geodetic(&Vector3::new(x, y, 0.0)).ok()?;
        let v = self.to.geodetic_to_enu(&g);
        Some((v.x, v.y))
    }
}

fn ego(log: &LogContents, reframe: &Reframe, t0_us: i64, label: &'static str) -> Series {
    let points = dash2sim_linux::log::views::ego_poses(log)
        .filter_map(|p| {
            let (x, y) = reframe.point(p.x_mm as f64 * 1e-3, p.y_mm as f64 * 1e-3)?;
            Some(((p.t_us - t0_us) as f64 * 1e-6, x, y))
        })
        .collect();
    Series { label, points }
}

/// Speed along a trajectory by differences over about half a second.
fn speed_of(series: &Series, label: &'static str) -> Series {
    let p = &series.points;
    let points = (0..p.len())
        .filter_map(|k| {
            let (a, b) = (p.get(k.saturating_sub(2))?, p.get((k + 2).min(p.len() - 1))?);
            let dt = b.0 - a.0;
            (dt > 0.0).then(|| (p[k].0, (b.1 - a.1).hypot(b.2 - a.2) / dt, 0.0))
        })
        .collect();
    Series { label, points }
}

fn windows(log: &LogContents, t0_us: i64, start_s: f64) -> Vec<Window> {
    let mut out: Vec<Window> = Vec::new();
    let mut from_s = start_s;
    for v in log.records.iter().filter_map(|r| match r {
        Record::Verification(v) => Some(v),
        _ => None,
    }) {
        let to_s = (v.t_us - t0_us) as f64 * 1e-6;
        if to_s > from_s {
            out.push(window(v, from_s, to_s));
            from_s = to_s;
        }
    }
    out
}

fn window(v: &Verification, from_s: f64, to_s: f64) -> Window {
    let m = |e4: i64| e4 as f64 * 1e-4;
    Window {
        from_s,
        to_s,
        score: v.score_e2 as f64 * 1e-2,
        metrics: [
            m(v.collisions_e4),
            m(v.drivable_e4),
            m(v.direction_e4),
            m(v.making_progress_e4),
            m(v.progress_e4),
            m(v.ttc_e4),
            m(v.speed_limit_e4),
            m(v.comfort_e4),
        ],
        decision: Decision::of_code(v.decision),
    }
}

impl Scene {
    /// The scene of `log`, its finished log and map tile.
    pub fn new(log: &LogContents, finished: Option<&LogContents>, tile: Option<&[u8]>) -> Result<Self> {
        let header =
            log.header.ok_or_else(|| Error::invalid("the header is damaged: no geodetic origin to draw in"))?;
        let here = frame(&header).ok_or_else(|| Error::invalid("the log's origin is not a valid position"))?;
        let t0_us = dash2sim_linux::log::views::ego_poses(log).next().map(|p| p.t_us).ok_or_else(|| {
            Error::invalid("no ego poses to plot (a log with GNSS and speed only has no anchored trajectory)")
        })?;
        let online = ego(log, &Reframe::new(here, here, true), t0_us, "online anchored ego");
        let finished_series = match finished {
            Some(f) => {
                let h = f.header.ok_or_else(|| Error::invalid("the finished log's header is damaged"))?;
                let there =
                    frame(&h).ok_or_else(|| Error::invalid("the finished log's origin is not a valid position"))?;
                ego(f, &Reframe::new(there, here, h.origin == header.origin), t0_us, "finished ego")
            }
            None => Series::default(),
        };
        let fixes: Vec<(f64, f64)> = log
            .records
            .iter()
            .filter_map(|r| match r {
                Record::GnssFix(f) => {
                    let g =
                        dash2sim_core::geo::Geodetic::new(f.lat_e7 as f64 * 1e-7, f.lon_e7 as f64 * 1e-7, 0.0).ok()?;
                    let v = here.geodetic_to_enu(&g);
                    Some((v.x, v.y))
                }
                _ => None,
            })
            .collect();
        // Tracks: the finished log's when there is one (placed by the finished ego).
        let source = finished.unwrap_or(log);
        let mut by_class: Vec<(&'static str, Vec<(f64, f64)>)> = Vec::new();
        for (_, (_, track)) in last_tracks(source) {
            let class = class_name(track.class);
            let p = (track.x_mm as f64 * 1e-3, track.y_mm as f64 * 1e-3);
            match by_class.iter_mut().find(|(c, _)| *c == class) {
                Some((_, points)) => points.push(p),
                None => by_class.push((class, vec![p])),
            }
        }
        by_class.sort_by_key(|(c, _)| *c);
        // The view: everything drawn but the map, and a margin.
        let mut bounds = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        let mut grow = |(x, y): (f64, f64)| {
            bounds = [bounds[0].min(x), bounds[1].min(y), bounds[2].max(x), bounds[3].max(y)];
        };
        online.points.iter().chain(&finished_series.points).for_each(|&(_, x, y)| grow((x, y)));
        by_class.iter().flat_map(|(_, p)| p).for_each(|&p| grow(p));
        let bounds = [bounds[0] - MARGIN_M, bounds[1] - MARGIN_M, bounds[2] + MARGIN_M, bounds[3] + MARGIN_M];
        let visible = |p: (f64, f64)| p.0 >= bounds[0] && p.0 <= bounds[2] && p.1 >= bounds[1] && p.1 <= bounds[3];
        // Fixes far outside the drive would squash it: they are drawn only inside the view.
        let fixes = fixes.into_iter().filter(|&p| visible(p)).collect();
        let (lanes, lanes_drawn) = match tile {
            Some(bytes) => map_lanes(bytes, here, bounds)?,
            None => (Vec::new(), 0),
        };
        let vehicle: Vec<(f64, f64, f64)> = log
            .records
            .iter()
            .filter_map(|r| match r {
                Record::VehicleSpeed(s) => Some(((s.t_us - t0_us) as f64 * 1e-6, s.speed_mm_s as f64 * 1e-3, 0.0)),
                _ => None,
            })
            .collect();
        let speeds = [
            Series { label: "vehicle speed (wheel / CAN)", points: vehicle },
            speed_of(&online, "online ego"),
            speed_of(&finished_series, "finished ego"),
        ];
        let duration_s = online.points.iter().chain(&finished_series.points).map(|p| p.0).fold(0.0, f64::max);
        let windows = windows(source, t0_us, 0.0);
        Ok(Self {
            bounds,
            lanes,
            fixes,
            online,
            finished: finished_series,
            tracks: by_class,
            speeds,
            windows,
            duration_s,
            lanes_drawn,
        })
    }

    /// What is drawn, in numbers.
    pub fn drawn(&self) -> super::Drawn {
        super::Drawn {
            lanes: self.lanes_drawn,
            poses: (self.online.points.len(), self.finished.points.len(), self.fixes.len()),
            tracks: self.tracks.iter().map(|(c, p)| (*c, p.len())).collect(),
            windows: (self.windows.len(), self.windows.iter().filter(|w| w.verdict() == Decision::Verified).count()),
        }
    }
}

/// The tile's lanes within 50 m of the view as capsules (the drivable area's shape), and its
/// polygons; how many lanes.
fn map_lanes(bytes: &[u8], here: LocalFrame, bounds: [f64; 4]) -> Result<(Vec<Ring>, usize)> {
    let view = MapView::parse(bytes).map_err(|e| Error::refused("map", e))?;
    let [lat, lon, h] = view.header().origin;
    let origin = dash2sim_core::geo::Geodetic::new(lat, lon, h).map_err(|e| Error::refused("map origin", e))?;
    let reframe = Reframe::new(LocalFrame::new(origin), here, false);
    let near = |p: &(f64, f64)| {
        p.0 >= bounds[0] - 50.0 && p.0 <= bounds[2] + 50.0 && p.1 >= bounds[1] - 50.0 && p.1 <= bounds[3] + 50.0
    };
    let (mut rings, mut lanes) = (Vec::new(), 0);
    for i in 0..view.len() as u32 {
        let Some(lane) = view.lane(i) else { continue };
        let points: Vec<(f64, f64)> = lane.points().filter_map(|(x, y)| reframe.point(x, y)).collect();
        if !points.iter().any(near) {
            continue;
        }
        lanes += 1;
        rings.extend(points.windows(2).map(|w| capsule(w[0], w[1], lane.width / 2.0)));
    }
    for g in 0..view.header().polygons {
        if let Some(points) = view.polygon(g) {
            let ring: Vec<(f64, f64)> = points.filter_map(|(x, y)| reframe.point(x, y)).collect();
            if ring.iter().any(near) {
                rings.push(ring);
            }
        }
    }
    Ok((rings, lanes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_is_shaded_as_its_log_decided_it_else_by_its_score() {
        let v = |score_e2, decision| Verification { score_e2, decision, ..Verification::default() };
        // A device's window verified with the benefit of its doubt, undecided with it held against it.
        assert_eq!(
            window(&v(9970, dash2sim_core::binlog::DECISION_UNDECIDED), 0.0, 15.0).verdict(),
            Decision::Undecided
        );
        assert_eq!(window(&v(9970, dash2sim_core::binlog::DECISION_VERIFIED), 0.0, 15.0).verdict(), Decision::Verified);
        // An older log's window, not decided: nuPlan's verdict of its score.
        assert_eq!(window(&v(9500, 0), 0.0, 15.0).verdict(), Decision::Verified);
        assert_eq!(window(&v(6875, 0), 0.0, 15.0).verdict(), Decision::Rejected);
    }
}
