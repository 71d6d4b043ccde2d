//! Street-imagery anchors for a recorded drive: what a place-recognition match of the
//! dashcam's frames to geotagged street images would give finishing (`dash2sim finish
//! --anchors`). **Simulated from the true path**, not matched from images: one anchor every
//! `spacing` metres of the drive, its position off by N(0, σ) per horizontal axis, a
//! fraction of them wrong matches metres away ([`StreetAnchorModel`]), at the log time of
//! the frame that was matched (read from the recorded log's frame numbers, as a matcher
//! working on the recorded frames would). The file says so in its first line.

use std::collections::HashMap;
use std::fmt::Write as _;

use dash2sim_core::binlog::Record;
use dash2sim_core::geo::LocalFrame;
use dash2sim_core::nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::profile::StreetAnchorModel;
use super::{gauss, Scenario};
use dash2sim_linux::log::LogContents;

/// What the anchors file says of itself in its first line.
pub const SIMULATED_NOTE: &str = "# street-imagery anchors simulated from the true path (not matched from images)";

/// The anchors CSV (`t,lat,lon,alt,sigma_m`) of a recorded drive under the drive's anchor
/// model; every anchor reports the model's σ per axis, wrong matches too (a matcher does not
/// know which are wrong). Frames the log does not hold are skipped.
pub fn street_anchors(scenario: &Scenario, log: &LogContents, spacing: f64, seed: u64) -> String {
    let model: StreetAnchorModel = scenario.config.anchors;
    let sigma = model.sigma_per_axis;
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5742_4545_5400);
    let frame_time: HashMap<i64, i64> = log
        .records
        .iter()
        .filter_map(|r| if let Record::FrameMeta(f) = r { Some((f.frame, f.t_us)) } else { None })
        .collect();
    let frame = log.header.as_ref().and_then(dash2sim_linux::log::frame);
    let mut text = format!("{SIMULATED_NOTE}\nt,lat,lon,alt,sigma_m\n");
    let Some(frame) = frame else { return text };
    let (mut travelled, mut next, mut last) = (0.0, 0.0, None::<(f64, f64)>);
    for (index, f) in scenario.frames.iter().enumerate() {
        travelled += last.map_or(0.0, |(x, y)| (f.ego.x - x).hypot(f.ego.y - y));
        last = Some((f.ego.x, f.ego.y));
        if travelled < next {
            continue;
        }
        // Frame numbers start at 1.
        let Some(&t_us) = frame_time.get(&(index as i64 + 1)) else { continue };
        next += spacing;
        let (mut east, mut north) = (f.ego.x + gauss(&mut rng, sigma), f.ego.y + gauss(&mut rng, sigma));
        if model.outlier_rate > 0.0 && rng.random::<f64>() < model.outlier_rate {
            let distance = rng.random_range(model.outlier_m.0..model.outlier_m.1);
            let direction = rng.random_range(0.0..std::f64::consts::TAU);
            (east, north) = (east + distance * direction.cos(), north + distance * direction.sin());
        }
        let Ok(g) = geodetic(&frame, east, north) else { continue };
        let _ = writeln!(text, "{:.6},{:.10},{:.10},{:.3},{sigma}", t_us as f64 * 1e-6, g.0, g.1, g.2);
    }
    text
}

fn geodetic(frame: &LocalFrame, east: f64, north: f64) -> Result<(f64, f64, f64), ()> {
    let g = frame.enu_to_geodetic(&Vector3::new(east, north, 0.0)).map_err(|_| ())?;
    Ok((g.lat_deg, g.lon_deg, g.height_m))
}
