//! The camera's inputs and the bus's fed to the pipeline in the order of their stamps
//! (issue #57).
//!
//! The camera's come out of [`super::bridge::merge`] in publication order, up to the newest
//! frame; the serial port's and the CAN bus's are stamped by their reader threads as they
//! arrive and queued. A logger that stalls — a card busy for seconds, a CPU given to the
//! video encoder — finds seconds of both waiting. Fed one source after the other, the bus's
//! older stamps came after the camera's newer ones: the device clock seemed to go back, the
//! pipeline took it for a clock reset and shifted the rest of the log by the stall (the
//! stress test caught it: 3 "resets" in a 15 s drive with two 5 s stalls).
//!
//! So a bus input waits while it is newer than the newest camera input released — the
//! camera's next frame releases it — but at most [`HOLD_US`] of the device clock (a camera
//! that stalls, or none), and the two are merged by stamp. Without a camera, bus inputs go
//! on at once.

use std::collections::VecDeque;

use dash2sim_core::time::Timestamp;

/// How long a bus input waits for the camera at most, µs of the device clock (the camera
/// merge's own bound, [`super::bridge::merge::HOLD_US`]).
pub const HOLD_US: i64 = super::bridge::merge::HOLD_US;

/// An input of either source, in the order it is to be fed.
#[derive(Debug)]
pub enum Next<C, B> {
    /// The camera's.
    Camera(C),
    /// The serial port's or the bus's, with its stamp.
    Bus(Timestamp, B),
}

/// The bus inputs waiting for the camera's.
#[derive(Debug)]
pub struct Interleave<B> {
    pending: VecDeque<(Timestamp, B)>,
    /// The newest camera stamp released; `None` before the first (or without a camera).
    horizon: Option<Timestamp>,
    /// Whether a camera is subscribed (else bus inputs never wait).
    camera: bool,
}

impl<B> Interleave<B> {
    /// Interleaving for a recording with (`camera`) or without a camera.
    pub fn new(camera: bool) -> Self {
        Interleave { pending: VecDeque::new(), horizon: None, camera }
    }

    /// A bus input stamped `t` (the reader's stamps go forward).
    pub fn push_bus(&mut self, t: Timestamp, input: B) {
        self.pending.push_back((t, input));
    }

    /// The camera's `released` inputs (in their order, stamped by `stamp`) and the bus
    /// inputs due by `now` (the device clock), merged by stamp into `on`.
    pub fn release<C>(
        &mut self,
        released: impl IntoIterator<Item = C>,
        stamp: impl Fn(&C) -> Timestamp,
        now: Timestamp,
        mut on: impl FnMut(Next<C, B>),
    ) {
        for c in released {
            let t = stamp(&c);
            while self.pending.front().is_some_and(|(b, _)| *b <= t) {
                if let Some((tb, b)) = self.pending.pop_front() {
                    on(Next::Bus(tb, b));
                }
            }
            self.horizon = self.horizon.max(Some(t));
            on(Next::Camera(c));
        }
        let waited = now - dash2sim_core::time::Duration::from_micros(HOLD_US);
        while let Some((t, _)) = self.pending.front() {
            let due = !self.camera || self.horizon.is_some_and(|h| *t <= h) || *t < waited;
            if !due {
                break;
            }
            if let Some((tb, b)) = self.pending.pop_front() {
                on(Next::Bus(tb, b));
            }
        }
    }

    /// Everything: the camera's last inputs and every bus input, merged by stamp (the
    /// recording ends).
    pub fn flush<C>(
        &mut self,
        released: impl IntoIterator<Item = C>,
        stamp: impl Fn(&C) -> Timestamp,
        mut on: impl FnMut(Next<C, B>),
    ) {
        self.release(released, stamp, Timestamp::from_micros(i64::MAX), &mut on);
        self.pending.drain(..).for_each(|(t, b)| on(Next::Bus(t, b)));
    }

    /// Bus inputs waiting.
    pub fn waiting(&self) -> usize {
        self.pending.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: i64) -> Timestamp {
        Timestamp::from_micros(ms * 1000)
    }

    fn order(interleave: &mut Interleave<i64>, camera: &[i64], now_ms: i64) -> Vec<String> {
        let mut out = Vec::new();
        interleave.release(
            camera.iter().copied(),
            |c| at(*c),
            at(now_ms),
            |n| {
                out.push(match n {
                    Next::Camera(c) => format!("c{c}"),
                    Next::Bus(_, b) => format!("b{b}"),
                })
            },
        );
        out
    }

    #[test]
    fn a_stalled_logger_s_backlog_is_fed_in_stamp_order() {
        // Five seconds of bus inputs queued while the logger stalled, then the camera's last
        // two seconds (the older frames lost to the bridge's buffers).
        let mut i = Interleave::new(true);
        for ms in (0..=5000).step_by(1000) {
            i.push_bus(at(ms), ms);
        }
        let fed = order(&mut i, &[3000, 3033, 5000], 5100);
        assert_eq!(fed, ["b0", "b1000", "b2000", "b3000", "c3000", "c3033", "b4000", "b5000", "c5000"]);
        assert_eq!(i.waiting(), 0);
    }

    #[test]
    fn a_bus_input_waits_for_the_camera_at_most_half_a_second() {
        let mut i = Interleave::new(true);
        let none: &[i64] = &[];
        i.push_bus(at(1000), 1000);
        assert_eq!(order(&mut i, &[900], 1100), ["c900"], "newer than the camera: it waits");
        assert_eq!(order(&mut i, none, 1400), Vec::<String>::new());
        assert_eq!(order(&mut i, none, 1501), ["b1000"], "0.5 s without a newer frame");
        let mut alone = Interleave::new(false);
        alone.push_bus(at(1000), 1000);
        assert_eq!(order(&mut alone, none, 1000), ["b1000"], "without a camera, at once");
    }
}
