//! **Simulation**: the seeded work-zone drives with their truth ([`scenario`]: road, actors,
//! sensors under a profile, the files a dashcam would give, a camera process publishing
//! them) and the sweep that runs many of them through the product and judges each log's
//! verdict against the truth's ([`fidelity`]). Takes seeds and profiles; gives drives,
//! corpora and the fidelity tables. Only the judging side reads a generator's parameters.

pub mod fidelity;
pub mod scenario;
