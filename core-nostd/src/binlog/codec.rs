//! Payload coding: each field is a zigzag varint of its difference to a prediction from
//! the previous record of the same kind in the segment ([`Mode`]).
//!
//! Differences wrap (two's complement), so any i64 survives the round trip exactly, even
//! hostile ones; well-behaved values just take few bytes.

use super::varint::{get, put, unzigzag, zigzag};
use super::{Kind, Mode, Record, Track3d, Tracks3d, MAX_PAYLOAD, MAX_TEXT};

/// Track ids whose last state is remembered for prediction (least recently used leave).
pub const TRACK_SLOTS: usize = 64;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct TrackSlot {
    last: Track3d,
    t_us: i64,
    used: u64,
}

const STATIC: u64 = 1;
const SAME_SIZE: u64 = 2;
const SAME_CLASS: u64 = 4;
const STATIC_VALUE: u64 = 8;

/// Most fields a record kind has.
pub const MAX_FIELDS: usize = 16;

/// What the previous record of one kind left behind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Stream {
    previous: [i64; MAX_FIELDS],
    change: [i64; MAX_FIELDS],
    /// Records seen in this segment, saturating at 2 (enough for every mode).
    seen: u8,
}

/// Predictor state of every kind, reset at each segment start. After damage a reader
/// cannot know what the lost records changed: it marks the streams broken until the next
/// segment, and records in between are reported lost.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Streams {
    streams: [Stream; Kind::ALL.len()],
    tracks: heapless::Vec<TrackSlot, TRACK_SLOTS>,
    tick: u64,
    t0: i64,
    broken: bool,
}

impl Default for Streams {
    fn default() -> Self {
        Streams {
            streams: [Stream::default(); Kind::ALL.len()],
            tracks: heapless::Vec::new(),
            tick: 0,
            t0: 0,
            broken: true,
        }
    }
}

/// What follows a track's head (id difference · 4 + code).
const NEW: u64 = 0;
const UNCHANGED: u64 = 1;
const CHANGED: u64 = 2;

/// Where a known track is expected now: its last position advanced by its velocity.
fn advanced(position_mm: i64, velocity_mm_s: i64, dt_us: i64) -> i64 {
    let step = i128::from(velocity_mm_s) * i128::from(dt_us) / 1_000_000;
    position_mm.wrapping_add(step as i64)
}

/// A track as its id's last state predicts it at `t_us`.
fn predicted(slot: &TrackSlot, t_us: i64) -> Track3d {
    let l = &slot.last;
    let dt = t_us.wrapping_sub(slot.t_us);
    Track3d { x_mm: advanced(l.x_mm, l.vx_mm_s, dt), y_mm: advanced(l.y_mm, l.vy_mm_s, dt), ..*l }
}

fn static_flags(is_static: i64) -> u64 {
    match is_static {
        0 => 0,
        1 => STATIC,
        _ => STATIC_VALUE,
    }
}

/// One track's bytes: against its id's last state (`slot`) when known — a single byte
/// when it moved exactly as predicted —, else against `previous` (the track before it in
/// the frame).
fn encode_track(
    track: &Track3d,
    slot: Option<&TrackSlot>,
    previous: &Track3d,
    t_us: i64,
    out: &mut [u8],
) -> Option<usize> {
    let id = zigzag(track.id.wrapping_sub(previous.id));
    let mut values: heapless::Vec<i64, 12> = heapless::Vec::new();
    let (code, flags) = match slot.map(|s| predicted(s, t_us)) {
        Some(p) if p == *track => (UNCHANGED, None),
        Some(p) => {
            let mut flags = static_flags(track.is_static);
            let _ = values.extend_from_slice(&[
                track.x_mm.wrapping_sub(p.x_mm),
                track.y_mm.wrapping_sub(p.y_mm),
                track.z_mm.wrapping_sub(p.z_mm),
            ]);
            if (track.l_mm, track.w_mm, track.h_mm) == (p.l_mm, p.w_mm, p.h_mm) {
                flags |= SAME_SIZE;
            } else {
                let _ = values.extend_from_slice(&[
                    track.l_mm.wrapping_sub(p.l_mm),
                    track.w_mm.wrapping_sub(p.w_mm),
                    track.h_mm.wrapping_sub(p.h_mm),
                ]);
            }
            if track.class == p.class {
                flags |= SAME_CLASS;
            } else {
                let _ = values.push(track.class);
            }
            let _ = values.extend_from_slice(&[
                track.yaw_e4.wrapping_sub(p.yaw_e4),
                track.vx_mm_s.wrapping_sub(p.vx_mm_s),
                track.vy_mm_s.wrapping_sub(p.vy_mm_s),
            ]);
            (CHANGED, Some(flags))
        }
        None => {
            let p = previous;
            let _ = values.extend_from_slice(&[
                track.class,
                track.x_mm.wrapping_sub(p.x_mm),
                track.y_mm.wrapping_sub(p.y_mm),
                track.z_mm.wrapping_sub(p.z_mm),
                track.l_mm.wrapping_sub(p.l_mm),
                track.w_mm.wrapping_sub(p.w_mm),
                track.h_mm.wrapping_sub(p.h_mm),
                track.yaw_e4,
                track.vx_mm_s,
                track.vy_mm_s,
            ]);
            (NEW, Some(static_flags(track.is_static)))
        }
    };
    // The id difference takes the head's upper 62 bits.
    if id >= 1 << 62 {
        return None;
    }
    let mut at = 0;
    let mut ok = put(out, &mut at, id << 2 | code);
    if let Some(flags) = flags {
        ok &= put(out, &mut at, flags);
        if flags & STATIC_VALUE != 0 {
            let _ = values.push(track.is_static);
        }
    }
    for v in values {
        ok &= put(out, &mut at, zigzag(v));
    }
    ok.then_some(at)
}

/// Inverse of [`encode_track`].
fn decode_track(input: &[u8], at: &mut usize, streams: &Streams, previous: &Track3d, t_us: i64) -> Option<Track3d> {
    let head = get(input, at)?;
    let id = previous.id.wrapping_add(unzigzag(head >> 2));
    let code = head & 3;
    if code == UNCHANGED {
        return Some(Track3d { id, ..predicted(streams.slot(id)?, t_us) });
    }
    let flags = get(input, at)?;
    let mut next = || get(input, at).map(unzigzag);
    let mut t = Track3d { id, is_static: i64::from(flags & STATIC != 0), ..Track3d::default() };
    match code {
        CHANGED => {
            let p = predicted(streams.slot(id)?, t_us);
            t.x_mm = p.x_mm.wrapping_add(next()?);
            t.y_mm = p.y_mm.wrapping_add(next()?);
            t.z_mm = p.z_mm.wrapping_add(next()?);
            (t.l_mm, t.w_mm, t.h_mm) = if flags & SAME_SIZE != 0 {
                (p.l_mm, p.w_mm, p.h_mm)
            } else {
                (p.l_mm.wrapping_add(next()?), p.w_mm.wrapping_add(next()?), p.h_mm.wrapping_add(next()?))
            };
            t.class = if flags & SAME_CLASS != 0 { p.class } else { next()? };
            t.yaw_e4 = p.yaw_e4.wrapping_add(next()?);
            t.vx_mm_s = p.vx_mm_s.wrapping_add(next()?);
            t.vy_mm_s = p.vy_mm_s.wrapping_add(next()?);
        }
        NEW => {
            let p = previous;
            t.class = next()?;
            t.x_mm = p.x_mm.wrapping_add(next()?);
            t.y_mm = p.y_mm.wrapping_add(next()?);
            t.z_mm = p.z_mm.wrapping_add(next()?);
            t.l_mm = p.l_mm.wrapping_add(next()?);
            t.w_mm = p.w_mm.wrapping_add(next()?);
            t.h_mm = p.h_mm.wrapping_add(next()?);
            t.yaw_e4 = next()?;
            t.vx_mm_s = next()?;
            t.vy_mm_s = next()?;
        }
        _ => return None,
    }
    if flags & STATIC_VALUE != 0 {
        t.is_static = next()?;
    }
    Some(t)
}

/// A `Tracks3d` frame being filled by a writer: every track of one time goes into one
/// frame while it fits.
#[derive(Clone, Debug)]
pub struct TracksFrame {
    /// The frame's time, µs.
    pub t_us: i64,
    count: u8,
    count_at: usize,
    len: usize,
    previous: Track3d,
    payload: [u8; MAX_PAYLOAD],
}

impl TracksFrame {
    /// Tracks in the frame.
    pub fn count(&self) -> usize {
        usize::from(self.count)
    }
}

fn index(kind: Kind) -> usize {
    Kind::ALL.iter().position(|k| *k == kind).unwrap_or(0)
}

impl Streams {
    /// Forget everything: a new segment starting at `t0_us`.
    pub fn start_segment(&mut self, t0_us: i64) {
        *self = Streams { t0: t0_us, broken: false, ..Streams::default() };
    }

    fn slot(&self, id: i64) -> Option<&TrackSlot> {
        self.tracks.iter().find(|s| s.last.id == id)
    }

    /// Remember `track` at `t_us` (the least recently used id leaves when full).
    fn remember(&mut self, track: &Track3d, t_us: i64) {
        self.tick += 1;
        let slot = TrackSlot { last: *track, t_us, used: self.tick };
        if let Some(s) = self.tracks.iter_mut().find(|s| s.last.id == track.id) {
            *s = slot;
        } else if let Err(slot) = self.tracks.push(slot) {
            if let Some(oldest) = self.tracks.iter_mut().min_by_key(|s| s.used) {
                *oldest = slot;
            }
        }
    }

    /// Start a `Tracks3d` frame at `t_us`.
    pub fn tracks_begin(&self, t_us: i64) -> TracksFrame {
        let mut f = TracksFrame {
            t_us,
            count: 0,
            count_at: 0,
            len: 0,
            previous: Track3d::default(),
            payload: [0; MAX_PAYLOAD],
        };
        put(&mut f.payload, &mut f.len, zigzag(t_us.wrapping_sub(self.prediction(Kind::Tracks3d, 0))));
        f.count_at = f.len;
        f.len += 1;
        f
    }

    /// Add `track` to `frame`; false (nothing changed) when it does not fit or the frame
    /// already holds 255 tracks.
    pub fn tracks_append(&mut self, frame: &mut TracksFrame, track: &Track3d) -> bool {
        if frame.count == u8::MAX {
            return false;
        }
        let Some(room) = frame.payload.get_mut(frame.len..) else { return false };
        let Some(n) = encode_track(track, self.slot(track.id), &frame.previous, frame.t_us, room) else {
            return false;
        };
        frame.len += n;
        frame.count += 1;
        frame.previous = *track;
        self.remember(track, frame.t_us);
        true
    }

    /// Close `frame`: its payload.
    pub fn tracks_finish<'f>(&mut self, frame: &'f mut TracksFrame) -> &'f [u8] {
        frame.payload[frame.count_at] = frame.count;
        self.update(Kind::Tracks3d, &[frame.t_us]);
        &frame.payload[..frame.len]
    }

    /// Decode a `Tracks3d` payload, handing its tracks to `emit` in records of at most
    /// [`super::MAX_TRACKS`]. Nothing is emitted and the state is unchanged if it is
    /// malformed.
    pub fn decode_tracks(&mut self, payload: &[u8], mut emit: impl FnMut(Record)) -> bool {
        // First pass on a copy: is the payload whole?
        let mut check = self.clone();
        if check.read_tracks(payload, |_| {}).is_none() {
            return false;
        }
        self.read_tracks(payload, |batch| emit(Record::Tracks3d(batch))).is_some()
    }

    fn read_tracks(&mut self, payload: &[u8], mut emit: impl FnMut(Tracks3d)) -> Option<()> {
        let mut at = 0;
        let t_us = unzigzag(get(payload, &mut at)?).wrapping_add(self.prediction(Kind::Tracks3d, 0));
        let n = usize::from(*payload.get(at)?);
        at += 1;
        let mut batch = Tracks3d { t_us, tracks: heapless::Vec::new() };
        let mut previous = Track3d::default();
        for _ in 0..n {
            let track = decode_track(payload, &mut at, self, &previous, t_us)?;
            self.remember(&track, t_us);
            previous = track;
            if batch.tracks.is_full() {
                emit(core::mem::replace(&mut batch, Tracks3d { t_us, tracks: heapless::Vec::new() }));
            }
            let _ = batch.tracks.push(track);
        }
        emit(batch);
        self.update(Kind::Tracks3d, &[t_us]);
        Some(())
    }

    /// Mark the streams broken until the next segment (after damage).
    pub fn break_streams(&mut self) {
        self.broken = true;
    }

    /// Whether records can be decoded (a segment started and no damage since).
    pub fn intact(&self) -> bool {
        !self.broken
    }

    fn prediction(&self, kind: Kind, field: usize) -> i64 {
        let s = &self.streams[index(kind)];
        let mode = kind.modes().get(field).copied().unwrap_or(Mode::Absolute);
        match (mode, s.seen) {
            (Mode::Absolute, _) => 0,
            // The first record's time is predicted by the segment's start.
            (_, 0) if field == 0 => self.t0,
            (_, 0) => 0,
            (Mode::Delta, _) | (Mode::DeltaDelta, 1) => s.previous[field],
            (Mode::DeltaDelta, _) => s.previous[field].wrapping_add(s.change[field]),
        }
    }

    fn update(&mut self, kind: Kind, values: &[i64]) {
        let s = &mut self.streams[index(kind)];
        for (k, &v) in values.iter().enumerate().take(MAX_FIELDS) {
            s.change[k] = if s.seen > 0 { v.wrapping_sub(s.previous[k]) } else { 0 };
            s.previous[k] = v;
        }
        s.seen = s.seen.saturating_add(1).min(2);
    }

    /// Encode `record`'s payload into `out`; its length, or `None` if it does not fit (or
    /// is a `Tracks3d` batch, see [`Streams::tracks_begin`]). The state advances only on
    /// success.
    pub fn encode(&mut self, record: &Record, out: &mut [u8]) -> Option<usize> {
        if let Record::Tracks3d(_) = record {
            // Batches go through `tracks_begin` / `tracks_append` / `tracks_finish`, which
            // join the batches of one time into a frame.
            return None;
        }
        let kind = record.kind();
        let mut values = [0i64; MAX_FIELDS];
        let n = record.fields(&mut values);
        // Appended fields that are 0 are left out from the end (the decoder reads them as 0
        // and its state follows the same values).
        let mut written = n;
        while written > kind.first_fields() && values.get(written - 1) == Some(&0) {
            written -= 1;
        }
        let mut at = 0;
        for (k, &v) in values[..written].iter().enumerate() {
            if !put(out, &mut at, zigzag(v.wrapping_sub(self.prediction(kind, k)))) {
                return None;
            }
        }
        if let Record::Event(e) = record {
            if !put(out, &mut at, e.text.len() as u64) {
                return None;
            }
            out.get_mut(at..at + e.text.len())?.copy_from_slice(&e.text);
            at += e.text.len();
        }
        self.update(kind, &values[..n]);
        Some(at)
    }

    /// Decode a payload of `kind`. Bytes after the known fields are ignored (a later minor
    /// version may append fields); fields an earlier minor version did not have yet — the
    /// payload ends where one would start — are 0. `None` if the payload is cut inside a
    /// field or malformed; the state advances only on success.
    pub fn decode(&mut self, kind: Kind, payload: &[u8]) -> Option<Record> {
        if kind == Kind::Tracks3d {
            // Batches go through `decode_tracks`, which may give several records.
            return None;
        }
        let n = kind.modes().len();
        let mut values = [0i64; MAX_FIELDS];
        let mut at = 0;
        for (k, slot) in values[..n].iter_mut().enumerate() {
            if k > 0 && at == payload.len() && kind != Kind::Event {
                break;
            }
            *slot = unzigzag(get(payload, &mut at)?).wrapping_add(self.prediction(kind, k));
        }
        let text: &[u8] = if kind == Kind::Event {
            let len = usize::try_from(get(payload, &mut at)?).ok().filter(|l| *l <= MAX_TEXT)?;
            payload.get(at..at + len)?
        } else {
            &[]
        };
        let record = Record::from_fields(kind, &values[..n], text)?;
        self.update(kind, &values[..n]);
        Some(record)
    }
}
