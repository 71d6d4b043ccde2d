//! Examples for dash2sim. `camera_sim` (a binary of this package) is a camera process
//! publishing a generated drive over the shared-memory bridge; the bare-metal example lives
//! in `examples/mcu` (its own workspace, built only for `thumbv7em-none-eabihf`).
#![forbid(unsafe_code)]
