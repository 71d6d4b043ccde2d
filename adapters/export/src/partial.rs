//! Files a simulator export writes under temporary names, so that a refused input leaves
//! nothing half-written behind.

use std::path::PathBuf;

/// Files a simulator export writes under temporary names, removed when dropped unless
/// disarmed (emptied): a refused input leaves nothing partial behind.
pub(super) struct Cleanup(pub(super) Vec<PathBuf>);

impl Drop for Cleanup {
    fn drop(&mut self) {
        for p in &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}
