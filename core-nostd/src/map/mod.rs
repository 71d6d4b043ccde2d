//! The compact map tile (format v2, `docs/map-tile.md`; v1 is read too) and a zero-copy
//! view of it.
//!
//! A tile is a byte slice — from flash, a file or a `static` — holding an ENU origin,
//! lanes (centreline in driving order, width, speed limit, road class, neighbours and
//! successors), drivable polygons, a uniform grid index so that a query touches only
//! the lanes near it, and (v2) the bounding box of every lane's and polygon's area, so that
//! a lane near a query in the grid but far from it in fact is passed over without reading
//! its points. [`MapView::parse`] checks the whole tile once (magic, version,
//! CRC-32C, every length, index and float); after that every accessor is cheap and none
//! can panic, so a truncated or corrupted tile is an error, never a crash.
//!
//! A lane's area is its centreline buffered by half its width with round caps and joins
//! (the union of one capsule per segment): where ways meet, the round ends cover the
//! junction, which is the lenient junction the verification wants.
//!
//! The module is split as smoltcp splits a protocol: [`wire`] is the byte format (header,
//! constants, checksum, the refusals), [`geometry`] the plane geometry of stored points
//! (centreline distances and projections, polygon edges, the box culls), [`view`] the
//! validated tile and its queries.

pub mod geometry;
pub mod view;
pub mod wire;

pub use geometry::{
    edges_distance, edges_parity, segment_distance, segments_distance, Centreline, Nearest, Projection, CHUNK,
};
pub use view::{Item, Lane, LaneArea, MapView};
pub use wire::{
    body_checksum, Header, MapError, BOX_LEN, CRC32C, CRC_AT, HEADER_LEN, LANE_LEN, MAGIC, NONE, POINT_LEN,
    POLYGON_BIT, POLYGON_LEN, VERSION_MAJOR, VERSION_MINOR,
};
