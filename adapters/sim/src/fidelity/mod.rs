//! How faithful the product's logs are, measured on generated drives whose truth is known:
//! one drive on the product's path judged against its truth ([`drive`]), many of them in
//! parallel (`dash2sim scenario sweep`, [`sweep`]) as one row each ([`rows`]), the
//! statistics over them ([`summary`]) and their picture ([`plot`]). `docs/fidelity.md`
//! holds the figures.

pub mod drive;
#[cfg(feature = "plot")]
pub mod plot;
pub mod rows;
pub mod summary;
pub mod sweep;
