//! Examples for dash2sim. The bare-metal example lives in `examples/mcu` (its own
//! workspace, built only for `thumbv7em-none-eabihf`); the camera publisher and the
//! on-device logger arrive with the ingest and binlog issues (#3, #6).
#![forbid(unsafe_code)]
