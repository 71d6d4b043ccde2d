//! CAN ingest for dash2sim (SocketCAN, candump replay, DBC signal tables).
//!
//! The decoders land with issue #3; this crate is a workspace member so that its place
//! in the build, lints and CI exists from the start.
#![forbid(unsafe_code)]
