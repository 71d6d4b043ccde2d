//! **Ingest**: what comes from outside, decoded — NMEA 0183 and CAN captures ([`nmea`],
//! [`can`]: the core's decoders run as on the device), trajectory-like files ([`ego`]
//! poses, [`objects`], 3D [`detections`], 2D ones as [`motchallenge`] files), OpenStreetMap ([`osm`]) and the map tiles built
//! from it ([`map_tile`]), the ENU origin as the commands take it ([`origin`]). Takes files; gives decoded values, reports and tiles. Depends on
//! nothing of the other stages.

pub mod can;
pub mod detections;
pub mod ego;
pub mod map_tile;
pub mod motchallenge;
pub mod nmea;
pub mod objects;
pub mod origin;
pub mod osm;
