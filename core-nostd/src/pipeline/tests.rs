//! Pipeline tests: see below.
