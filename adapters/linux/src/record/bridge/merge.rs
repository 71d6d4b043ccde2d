//! The camera's inputs put back into the order they were published (issue #57).
//!
//! Each service is its own FIFO, and a subscriber drains them one after another. A camera
//! process publishing while the logger drains (or while the logger is starved of CPU and
//! drains a backlog in one go) splits a frame across two passes: the logger saw frame
//! k + 1's VO pose before the IMU samples published ahead of it, or its 3D detections
//! before its pose — the pipeline then refused them (detections without a pose) or wrote
//! them in another order, so two live runs of the same inputs gave different logs.
//!
//! A camera process publishes in the order of its stamps: the IMU samples up to a frame,
//! then the frame, its VO pose, its 3D and its 2D detections (keep marks are about the file
//! being recorded now and are handed on at once, by the subscriber). So the
//! inputs are ordered by (epoch, stamp, service rank, arrival), the epoch counting a
//! service's stamps going back by more than a second (a restarted camera process replaying
//! its files: what it publishes comes after what the old one did). A drain takes the frame
//! service first: every input published before the newest frame seen is then in hand when
//! the other services are drained, and everything up to that frame is released in order.
//! What is published after it waits for the next frame — one frame period — or, when no
//! frame comes (a camera that stalls, an IMU-only process), until it is [`HOLD_US`] older
//! than the newest stamp held. The recording's end releases the rest.
//!
//! Draining the frame service first is not enough for the IMU: a starved logger has seen a
//! frame while the IMU samples published before it were not yet there to drain (iceoryx2
//! orders each service's samples, not one service's against another's), and released the
//! frame ahead of them — two runs of the same publication gave logs of the same records in
//! another order (issue #57). So a frame says how many IMU samples its publisher had sent
//! ([`CameraInput::Frame`]'s `imu_published`, the IMU's own numbering), and it waits until
//! the sample of that number has been received — or, if it was lost, until it is
//! [`HOLD_US`] old.
//!
//! "Old" is measured against the newest stamp held when the pass began, not the newest one
//! drained in it: a starved logger's pass can drain the frame service before the camera
//! publishes frames 1–9 and the other services after it has; measured against what those
//! drained, the 2D detections of frames 1–5 looked half a second old and went before their
//! frames (the Python publisher's contract test, starved, issue #57). What is older than
//! the previous pass's newest stamp by [`HOLD_US`] was published before that pass ended, and
//! so was its frame: this pass's frame drain has it.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, VecDeque};

use super::CameraInput;

/// How long an input waits for a frame at most, µs of stamps: past it, inputs are released
/// without the frame's guarantee (the order is then by stamp as far as it is known).
pub const HOLD_US: i64 = 500_000;
/// A service's stamp going back by more than this starts a new epoch, µs (the pipeline's own
/// clock-reset threshold).
const RESET_US: i64 = 1_000_000;
/// The services in publication order within one stamp.
const SERVICES: usize = 6;

/// Where an input goes in the order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Key {
    epoch: u32,
    t_us: i64,
    rank: u8,
    arrival: u64,
}

/// An input waiting for its turn.
#[derive(Debug)]
struct Held {
    key: Key,
    input: CameraInput,
}

impl PartialEq for Held {
    fn eq(&self, other: &Self) -> bool {
        self.key == other.key
    }
}

impl Eq for Held {}

impl PartialOrd for Held {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Held {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.key.cmp(&other.key)
    }
}

/// The reorder buffer.
#[derive(Debug, Default)]
pub struct Merge {
    held: BinaryHeap<Reverse<Held>>,
    /// Per service: its epoch and its last stamp.
    clocks: [(u32, Option<i64>); SERVICES],
    /// The newest frame released up to: every frame drained before it has its IMU samples.
    barrier: Option<Key>,
    /// Frames drained after the barrier, in order, with the IMU number each waits for.
    framed: VecDeque<(Key, u32)>,
    /// The newest IMU number received (the publisher's count).
    imu_received: u32,
    /// The newest key held.
    newest: Option<Key>,
    /// [`Merge::newest`] as the previous [`Merge::release`] left it: what staleness is
    /// measured against.
    settled: Option<Key>,
    arrivals: u64,
}

/// An input's service rank and stamp.
fn rank_and_stamp(input: &CameraInput) -> (u8, i64) {
    match input {
        CameraInput::Imu(t, _) => (0, t.micros()),
        CameraInput::Frame { t, .. } => (1, t.micros()),
        CameraInput::Vo(t, ..) => (2, t.micros()),
        CameraInput::Detections3d(t, ..) => (3, t.micros()),
        CameraInput::Detections2d(t, ..) => (4, t.micros()),
        CameraInput::Keep(t) => (5, t.micros()),
    }
}

impl Merge {
    /// Take one drained input (services in [`super::CameraSubscriber::receive`]'s order).
    pub fn push(&mut self, input: CameraInput) {
        let (rank, t_us) = rank_and_stamp(&input);
        let (epoch, last) = &mut self.clocks[usize::from(rank)];
        if last.is_some_and(|last| t_us < last.saturating_sub(RESET_US)) {
            *epoch = epoch.saturating_add(1);
        }
        *last = Some(t_us);
        let key = Key { epoch: *epoch, t_us, rank, arrival: self.arrivals };
        self.arrivals += 1;
        if let CameraInput::Frame { imu_published, .. } = input {
            self.framed.push_back((key, imu_published));
        }
        self.newest = self.newest.max(Some(key));
        self.held.push(Reverse(Held { key, input }));
    }

    /// The IMU sample numbered `number` (the publisher's count, [`super::sequence`]) has been
    /// drained: frames published after it may go.
    pub fn imu_received(&mut self, number: u32) {
        self.imu_received = number;
    }

    /// Everything that can go now, in order: up to the newest frame whose IMU samples are in,
    /// and what has waited [`HOLD_US`].
    pub fn release(&mut self, mut on: impl FnMut(CameraInput)) -> usize {
        let waited = self.settled.map(|n| (n.epoch, n.t_us.saturating_sub(HOLD_US)));
        self.settled = self.newest;
        let stale = |key: &Key| waited.is_some_and(|(epoch, t)| (key.epoch, key.t_us) < (epoch, t));
        while let Some(&(key, wanted)) = self.framed.front() {
            // 0: a publisher that does not count; numbers compare across their wrap.
            let imu_in = wanted == 0 || self.imu_received.wrapping_sub(wanted) < 1 << 31;
            if !(imu_in || stale(&key)) {
                break;
            }
            self.barrier = self.barrier.max(Some(key));
            self.framed.pop_front();
        }
        let mut n = 0;
        while let Some(Reverse(next)) = self.held.peek() {
            let framed = self.barrier.is_some_and(|b| next.key <= b);
            if !(framed || stale(&next.key)) {
                break;
            }
            let Some(Reverse(next)) = self.held.pop() else { break };
            on(next.input);
            n += 1;
        }
        n
    }

    /// Everything held, in order (the recording ends).
    pub fn flush(&mut self, mut on: impl FnMut(CameraInput)) -> usize {
        self.framed.clear();
        let mut n = 0;
        while let Some(Reverse(next)) = self.held.pop() {
            on(next.input);
            n += 1;
        }
        n
    }

    /// Inputs held.
    pub fn held(&self) -> usize {
        self.held.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::imu::ImuSample;
    use dash2sim_core::sim3::Pose;
    use dash2sim_core::time::Timestamp;

    fn at(ms: i64) -> Timestamp {
        Timestamp::from_micros(ms * 1000)
    }

    /// A frame's messages as a camera publishes them: two IMU samples up to it (numbered
    /// 2k + 1 and 2k + 2), then the frame, its pose, its detections.
    fn frame(k: u64, ms: i64) -> Vec<CameraInput> {
        let imu_published = 2 * k as u32 + 2;
        vec![
            CameraInput::Imu(at(ms - 25), ImuSample::default()),
            CameraInput::Imu(at(ms), ImuSample::default()),
            CameraInput::Frame { sequence: k, t: at(ms), exposure_us: 0, image_bytes: 0, imu_published },
            CameraInput::Vo(at(ms), k, 0, Pose::identity()),
            CameraInput::Detections3d(at(ms), k, Vec::new()),
            CameraInput::Detections2d(at(ms), k, Vec::new()),
        ]
    }

    fn label(input: &CameraInput) -> String {
        let (rank, t) = rank_and_stamp(input);
        format!("{}@{}", ["imu", "frame", "vo", "det3d", "det2d", "keep"][usize::from(rank)], t / 1000)
    }

    /// Drained service by service as `receive` does (frames first), the passes cutting the
    /// publication at `cuts` (how many messages each service had when it was drained).
    fn drained(published: &[CameraInput], cuts: &[[usize; SERVICES]]) -> Vec<String> {
        let mut merge = Merge::default();
        let mut out = Vec::new();
        let mut taken = [0usize; SERVICES];
        for cut in cuts {
            for rank in [1u8, 0, 2, 3, 4, 5] {
                let of_service: Vec<&CameraInput> = published.iter().filter(|i| rank_and_stamp(i).0 == rank).collect();
                let r = usize::from(rank);
                for input in &of_service[taken[r]..cut[r].min(of_service.len())] {
                    merge.push((*input).clone());
                }
                taken[r] = cut[r].min(of_service.len()).max(taken[r]);
                if rank == 0 {
                    merge.imu_received(taken[0] as u32);
                }
            }
            merge.release(|i| out.push(label(&i)));
        }
        merge.flush(|i| out.push(label(&i)));
        out
    }

    #[test]
    fn any_cut_of_the_publication_is_released_in_publication_order() {
        let published: Vec<CameraInput> = (0..4).flat_map(|k| frame(k, 100 + 50 * k as i64)).collect();
        let in_order: Vec<String> = published.iter().map(label).collect();
        // Counts per service (imu, frame, vo, det3d, det2d, keep) at each pass. The second
        // pass saw frame 2's pose but not its detections, and frame 3's IMU but not its frame:
        // a starved logger's view.
        let cuts = [[2, 1, 1, 1, 0, 0], [6, 2, 3, 2, 2, 0], [8, 4, 4, 3, 3, 0], [8, 4, 4, 4, 4, 0]];
        assert_eq!(drained(&published, &cuts), in_order);
        // The frame service ahead of the IMU's: frames 1 and 2 drained while the samples
        // published before them were not yet there (the live failure of issue #57; without
        // the frames' IMU numbers they went first).
        let cuts = [[2, 3, 3, 3, 3, 0], [8, 4, 4, 4, 4, 0]];
        assert_eq!(drained(&published, &cuts), in_order);
        // And a logger that drains once at the end, or after every message.
        assert_eq!(drained(&published, &[[8, 4, 4, 4, 4, 0]]), in_order);
        let mut one_by_one = Vec::new();
        let mut counts = [0usize; SERVICES];
        for input in &published {
            counts[usize::from(rank_and_stamp(input).0)] += 1;
            one_by_one.push(counts);
        }
        assert_eq!(drained(&published, &one_by_one), in_order);
    }

    /// The Python publisher's contract test, starved (issue #57): a pass drained the frame
    /// service before the camera published its first frames and the other services after;
    /// their 2D detections, half a second older than the newest IMU sample drained, went
    /// before their frames.
    #[test]
    fn a_pass_that_drained_the_frames_before_they_were_published_releases_nothing_ahead_of_them() {
        let published: Vec<CameraInput> = (0..14).flat_map(|k| frame(k, 100 + 50 * k as i64)).collect();
        let in_order: Vec<String> = published.iter().map(label).collect();
        // Pass 1: no frame yet when the frame service was drained; everything else by then.
        let cuts = [[28, 0, 14, 14, 14, 0], [28, 14, 14, 14, 14, 0]];
        assert_eq!(drained(&published, &cuts), in_order);
    }

    #[test]
    fn a_restarted_camera_s_earlier_stamps_come_after_the_old_process_s() {
        let mut published: Vec<CameraInput> = (0..3).flat_map(|k| frame(k, 5000 + 50 * k as i64)).collect();
        // The new process replays its files from the start: stamps 5 s earlier.
        published.extend((0..2).flat_map(|k| frame(k, 100 + 50 * k as i64)));
        let in_order: Vec<String> = published.iter().map(label).collect();
        assert_eq!(drained(&published, &[[10, 5, 5, 5, 5, 0]]), in_order);
        assert_eq!(drained(&published, &[[6, 3, 3, 2, 2, 0], [10, 5, 5, 5, 5, 0]]), in_order);
    }

    #[test]
    fn a_frame_whose_imu_sample_never_comes_waits_half_a_second_of_stamps() {
        let mut merge = Merge::default();
        let mut released = Vec::new();
        // Frame 0 wants IMU sample 2; sample 1 came, then the IMU went silent.
        merge.push(CameraInput::Imu(at(75), ImuSample::default()));
        merge.imu_received(1);
        let frame = |k: u64, ms: i64| CameraInput::Frame {
            sequence: k,
            t: at(ms),
            exposure_us: 0,
            image_bytes: 0,
            imu_published: 2,
        };
        merge.push(frame(0, 100));
        merge.release(|i| released.push(label(&i)));
        assert!(released.is_empty(), "the frame waits for its IMU sample, and the sample for the frame");
        // A later sample's number says the wanted one was lost: the frame goes.
        merge.imu_received(3);
        merge.release(|i| released.push(label(&i)));
        assert_eq!(released, ["imu@75", "frame@100"]);
        // No sample comes: frames wait until half a second of stamps has passed them.
        let mut silent = Merge::default();
        let mut out = Vec::new();
        silent.imu_received(1);
        for k in 0..7 {
            silent.push(frame(k, 100 * (k as i64 + 1)));
        }
        silent.release(|i| out.push(label(&i)));
        assert!(out.is_empty(), "staleness is measured from the next pass");
        silent.release(|i| out.push(label(&i)));
        assert_eq!(out, ["frame@100"], "older than the newest (700 ms) by more than 500 ms");
    }

    #[test]
    fn without_frames_an_input_waits_half_a_second_of_stamps() {
        let mut merge = Merge::default();
        for ms in (0..=1000).step_by(10) {
            merge.push(CameraInput::Imu(at(ms), ImuSample::default()));
        }
        let mut released = Vec::new();
        merge.release(|i| released.push(rank_and_stamp(&i).1 / 1000));
        assert!(released.is_empty(), "staleness is measured against the newest stamp of the pass before");
        merge.release(|i| released.push(rank_and_stamp(&i).1 / 1000));
        assert_eq!(released.first(), Some(&0));
        assert_eq!(released.last(), Some(&490), "older than the newest (1000 ms) by more than 500 ms");
        assert_eq!(merge.held(), 51);
    }
}
