//! Links dash2sim-core into a `#![no_std]` host binary (see Cargo.toml for why).
#![no_std]
#![no_main]

use core::hint::black_box;
use core::panic::PanicInfo;

use dash2sim_core::anchor::{AnchorConfig, Anchorer};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::sim3::{AlignMode, Moments};
use dash2sim_core::time::Timestamp;

// A no_std binary links with `-nodefaultlibs`: bring in the C library for memcpy and
// the start files that call `main`.
#[link(name = "c")]
extern "C" {}

/// The prebuilt `core` for this host target carries unwind tables that name the
/// personality routine; with `panic = "abort"` it is never called. (If `std` were linked
/// this would collide too — another way the check fails loudly.)
#[no_mangle]
pub extern "C" fn rust_eh_personality() {}

#[panic_handler]
fn panic(_: &PanicInfo<'_>) -> ! {
    loop {}
}

/// Called by the C runtime's `_start`; exercises the core so it is really linked.
#[no_mangle]
pub extern "C" fn main(_argc: i32, _argv: *const *const u8) -> i32 {
    let mut m = Moments::new();
    for k in 0..10 {
        let x = Vector3::new(k as f64, (k * k) as f64, 1.0);
        let _ = m.push(&x, &(x * 2.0), 1.0);
    }
    let mut a: Anchorer = Anchorer::new(AnchorConfig::default());
    let _ = a.push_vo(Timestamp::from_micros(black_box(1)), Vector3::zeros());
    match m.align(black_box(AlignMode::Sim3)) {
        Ok(t) if (t.scale - 2.0).abs() < 1e-9 => 0,
        _ => 1,
    }
}
