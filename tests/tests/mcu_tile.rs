//! The MCU example embeds a map tile (`examples/mcu/road.d2smap`); it must be exactly what
//! `dash2sim map build` makes of `examples/mcu/road.osm` today, so the QEMU run checks the
//! current format and builder, not a stale file.

use dash2sim_core::geo::Geodetic;
use dash2sim_linux::ingest::map_tile::{encode, from_osm};

#[test]
fn the_mcu_example_tile_is_built_from_its_osm_file() {
    let root = dash2sim_tests::workspace_root().join("examples/mcu");
    let data = dash2sim_linux::ingest::osm::read(&root.join("road.osm")).expect("road.osm");
    let mut warnings = Vec::new();
    let content = from_osm(&data, Some(Geodetic::new(60.2, 24.9, 0.0).expect("origin")), &mut warnings);
    assert!(warnings.is_empty(), "{warnings:?}");
    let committed = std::fs::read(root.join("road.d2smap")).expect("road.d2smap");
    assert!(
        encode(&content, dash2sim_linux::ingest::map_tile::DEFAULT_CELL_M) == committed,
        "rebuild it: dash2sim map build examples/mcu/road.osm -o examples/mcu/road.d2smap --origin 60.2,24.9"
    );
}
