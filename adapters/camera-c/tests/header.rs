//! The checked-in C header is what cbindgen makes of the crate today: a function, constant
//! or message field changed in Rust and not in the header fails here.
//! `DASH2SIM_BLESS=1 cargo test -p dash2sim-camera --test header` rewrites it.

use std::path::Path;

#[test]
fn the_checked_in_header_is_current() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(crate_dir.join("cbindgen.toml")).expect("cbindgen.toml");
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_crate(crate_dir)
        .with_config(config)
        .generate()
        .expect("cbindgen")
        .write(&mut generated);
    let path = crate_dir.join("include/dash2sim_camera.h");
    if std::env::var_os("DASH2SIM_BLESS").is_some() {
        std::fs::write(&path, &generated).expect("write the header");
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "{} is not current: regenerate it with DASH2SIM_BLESS=1 cargo test -p dash2sim-camera --test header",
        path.display()
    );
}
