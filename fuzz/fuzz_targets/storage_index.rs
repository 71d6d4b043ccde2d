//! A recording folder's `index.json` from arbitrary bytes: parsing never panics, and an
//! index it accepts names only plain log files in the folder (never a path the quota could
//! delete outside it) and writes back to the same index. The module is the library's own
//! file, read as it is (it depends on std and serde alone).
#![no_main]

use libfuzzer_sys::fuzz_target;

#[path = "../../adapters/linux/src/record/storage/index.rs"]
#[allow(dead_code)]
mod index;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(parsed) = index::Index::parse(text) else { return };
    for e in &parsed.segments {
        assert!(index::is_log_name(&e.file), "{:?}", e.file);
        let path = std::path::Path::new("/folder").join(&e.file);
        assert_eq!(path.parent(), Some(std::path::Path::new("/folder")), "{:?}", e.file);
    }
    let again = serde_json::to_string(&parsed).expect("an index serialises");
    assert_eq!(index::Index::parse(&again).ok().as_ref(), Some(&parsed));
});
