//! Arbitrary bytes as a map tile: parsing refuses or accepts, and an accepted tile answers
//! every query without panicking. The magic, version and CRC are fixed up so that the
//! fuzzer spends its time on the structure, not on guessing a checksum.
#![no_main]

use dash2sim_core::map::{body_checksum, Item, MapView, CRC_AT, HEADER_LEN, MAGIC};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = MapView::parse(data);
    let mut bytes = data.to_vec();
    if bytes.len() < HEADER_LEN {
        return;
    }
    bytes[..6].copy_from_slice(&MAGIC);
    bytes[6] = 1;
    let crc = body_checksum(&bytes);
    bytes[CRC_AT..CRC_AT + 4].copy_from_slice(&crc.to_le_bytes());
    let Ok(view) = MapView::parse(&bytes) else { return };
    let h = *view.header();
    for i in 0..h.lanes.min(1000) {
        let lane = view.lane(i).expect("valid index");
        let _ = lane.points().count() + lane.successors().count();
        let _ = lane.nearest(1.0, 2.0);
    }
    for i in 0..h.polygons.min(1000) {
        let _ = view.polygon_distance(i, 0.5, -0.5);
    }
    for (x, y, r) in [(0.0, 0.0, 10.0), (1e9, -1e9, 1e12), (f64::NAN, 0.0, 5.0), (3.0, 4.0, f64::INFINITY)] {
        let _ = view.distance_to_drivable(x, y, r, |_: Item| true);
    }
});
