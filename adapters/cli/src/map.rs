//! `dash2sim map build|info|lanes|check|export`: the tiles' commands rendered.

use std::io::Write as _;
use std::path::Path;

use dash2sim_core::geo::Geodetic;
use dash2sim_linux::ingest::map_tile::{self, check};
use dash2sim_linux::{Error, Result};

/// Warnings shown of a build; the rest are counted.
const WARNINGS_SHOWN: usize = 10;

/// `dash2sim map build`.
pub fn build(osm: &Path, output: &Path, origin: Option<Geodetic>, bbox: Option<[f64; 4]>, cell: f64) -> Result<()> {
    let built = map_tile::build_file(osm, output, origin, bbox, cell)?;
    for w in built.warnings.iter().take(WARNINGS_SHOWN) {
        eprintln!("warning: {w}");
    }
    if built.warnings.len() > WARNINGS_SHOWN {
        eprintln!("warning: … and {} more", built.warnings.len() - WARNINGS_SHOWN);
    }
    println!(
        "{}: {} lanes, {:.2} lane-km, {} bytes ({:.0} bytes per lane-km), {} warnings",
        output.display(),
        built.lanes,
        built.lane_km,
        built.bytes,
        built.bytes as f64 / built.lane_km.max(1e-9),
        built.warnings.len()
    );
    Ok(())
}

/// `dash2sim map lanes`.
pub fn lanes(path: &Path) -> Result<()> {
    let json = crate::render::json_of(&map_tile::lanes(path)?)?;
    match writeln!(std::io::stdout().lock(), "{json}") {
        // A reader that stops early (`| head`) is not an error.
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(Error::invalid(format!("stdout: {e}"))),
        _ => Ok(()),
    }
}

/// `dash2sim map info`.
pub fn info(path: &Path, as_json: bool) -> Result<()> {
    let info = map_tile::info(path)?;
    if as_json {
        println!("{}", crate::render::json_of(&info)?);
        return Ok(());
    }
    let (h, lane_km) = (&info.header, info.lane_km);
    let [nodes, ways, highway_ways, relations] = h.source_counts;
    println!("map tile {} (format v{})", path.display(), info.version);
    println!("  origin      {:.7}, {:.7}, height {} m", h.origin[0], h.origin[1], h.origin[2]);
    println!("  source      {nodes} nodes, {ways} ways ({highway_ways} highway), {relations} relations");
    println!("  lanes       {} ({lane_km:.2} lane-km), {} polygons, {} points", h.lanes, h.polygons, h.points);
    println!(
        "  grid        {} × {} cells of {} m, {} entries",
        h.grid_size[0], h.grid_size[1], h.cell_size, h.grid_entries
    );
    println!("  size        {} bytes ({:.0} per lane-km)", info.bytes, info.bytes as f64 / lane_km.max(1e-9));
    Ok(())
}

/// `dash2sim map check`.
pub fn check(map: &Path, poses: &Path, passes: u32, as_json: bool) -> Result<()> {
    let c = check::check_file(map, poses, passes)?;
    if as_json {
        println!("{}", crate::render::json_of(&c)?);
    } else {
        println!(
            "{} poses: {} compliant, {} corners outside, {} with nothing drivable within 10 m; {:.2} µs per pose (fastest of {} passes)",
            c.poses, c.compliant, c.corners_outside, c.corners_nothing_near, c.us_per_pose, c.passes
        );
        if let Some(s) = c.channel_sensitive {
            println!(
                "channel-sensitive ({} lanes on the poses' channel): {} compliant, {} corners outside, {} with nothing of the channel within 10 m; {:.2} µs per pose",
                s.channel_lanes, s.compliant, s.corners_outside, s.corners_nothing_near, s.us_per_pose
            );
        }
    }
    Ok(())
}

/// `dash2sim map export --opendrive`.
pub fn export(map: &Path, opendrive: &Path) -> Result<()> {
    let written = dash2sim_export::opendrive::write(map, opendrive)?;
    println!("{}", dash2sim_export::opendrive_line(opendrive, &written));
    Ok(())
}
