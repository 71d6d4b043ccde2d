//! **The test rig**, above the product: the seeded work-zone drives with their truth
//! ([`scenario`]: road, actors, sensors under a profile, the files a dashcam would give, a
//! camera process publishing them), the sweep that runs many of them through the product
//! and judges each log's verdict against the truth's ([`fidelity`]), and the real
//! recordings of the shared data folder run through the product and measured against
//! their own references ([`datasets`]); the demo, the whole product on one generated drive
//! or on the real recordings, with its typed report (`demo`, feature `demo`). Takes seeds
//! and profiles; gives drives, corpora, the fidelity tables and the demo's report. Only the judging side reads a generator's parameters, and no
//! product crate depends on this one.

#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![deny(clippy::print_stdout, clippy::print_stderr)]

pub mod datasets;
#[cfg(feature = "demo")]
pub mod demo;
pub mod fidelity;
pub mod scenario;

pub use dash2sim_linux::{Error, Field, Result};
