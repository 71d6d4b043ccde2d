//! dash2sim on a microcontroller: anchor a synthetic VO track (scale 0.4, rotated) to
//! GNSS fixes and wheel speed on a Cortex-M7, then report the estimate over semihosting.
//! Exits with failure if the recovered scale or rotation is wrong, so CI can run it
//! under QEMU as a test of the bare-metal build.
#![no_std]
#![no_main]

use core::panic::PanicInfo;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use dash2sim_core::anchor::{AnchorConfig, Anchorer, Observability};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_core::sim3::{rotation_z, Sim3};
use dash2sim_core::time::Timestamp;

/// A curving, accelerating drive in ENU (m) at `t` seconds.
fn drive(t: f64) -> Vector3<f64> {
    let s = 10.0 * t + 0.25 * t * t;
    let heading = s / 400.0;
    Vector3::new(400.0 * libm::sin(heading), 400.0 * (1.0 - libm::cos(heading)), 0.0)
}

#[entry]
fn main() -> ! {
    let truth = Sim3 { rotation: rotation_z(2.0), translation: Vector3::new(5.0, -3.0, 1.0), scale: 0.4 };
    let to_vo = truth.inverse();
    let mut anchorer: Anchorer = Anchorer::new(AnchorConfig::default());
    let mut first_observable = None;
    for k in 0..=3000u32 {
        let t = f64::from(k) * 0.01;
        let stamp = Timestamp::from_micros(i64::from(k) * 10_000);
        if k % 2 == 0 {
            let speed = (drive(t + 0.01) - drive(t)).norm() * 100.0;
            let _ = anchorer.push_speed(stamp, speed);
        }
        if k % 10 == 0 && k > 0 {
            let _ = anchorer.push_gnss(stamp, drive(t), 1.0);
        }
        if k % 5 == 0 {
            let _ = anchorer.push_vo(stamp, to_vo.transform_point(&drive(t)));
        }
        if first_observable.is_none() && anchorer.quality().observability == Observability::Observable {
            first_observable = Some(t);
        }
    }
    let ok = match anchorer.estimate() {
        Some(est) => {
            let q = anchorer.quality();
            hprintln!("dash2sim-core on Cortex-M7: observable after {:?} s", first_observable);
            hprintln!(
                "scale {} (truth 0.4), anchors used {}, rms residual {} m",
                est.scale,
                q.anchors_used,
                q.rms_residual_m
            );
            libm::fabs(est.scale / 0.4 - 1.0) < 1e-4 && (est.rotation - truth.rotation).norm() < 1e-4
        }
        None => {
            hprintln!("no estimate: {:?}", anchorer.quality().observability);
            false
        }
    };
    debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &PanicInfo<'_>) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
