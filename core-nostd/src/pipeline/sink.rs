//! The log a pipeline writes: the writer and its header, the clock that turns device time
//! into log time, the issues counted and the totals. Every stage writes through it.

use core::fmt::Write as _;

use embedded_io::Write;

use super::clock::{Clock, OffsetChange};
use super::issues::{Issue, Issues};
use super::{PipelineError, PipelineStats};
use crate::binlog::{ClockOffset, EventRecord, Header, Record, WriteError, Writer, WriterConfig, MAX_TEXT};
use crate::decimal::Decimal;
use crate::time::Timestamp;

/// The log sink and what goes with writing it.
#[derive(Debug)]
pub(super) struct LogSink<W: Write, const BUF: usize> {
    pub(super) header: Header,
    pub(super) writer: Writer<W, BUF>,
    /// Logs started on new sinks ([`super::Pipeline::rotate`]).
    pub(super) rotations: u32,
    pub(super) clock: Clock,
    /// The latest monotonic time of any input.
    pub(super) now: Timestamp,
    pub(super) issues: Issues,
    pub(super) stats: PipelineStats,
}

impl<W: Write, const BUF: usize> LogSink<W, BUF> {
    pub(super) fn new(io: W, header: Header, config: WriterConfig) -> Self {
        LogSink {
            header,
            writer: Writer::buffered(io, &header, config),
            rotations: 0,
            clock: Clock::new(),
            now: Timestamp::ZERO,
            issues: Issues::default(),
            stats: PipelineStats::default(),
        }
    }

    pub(super) fn write(&mut self, record: &Record) -> Result<(), PipelineError<W::Error>> {
        match self.writer.write(record) {
            Ok(()) => {
                self.stats.records = self.stats.records.saturating_add(1);
                Ok(())
            }
            Err(WriteError::RecordTooLarge) => {
                self.issues.count(Issue::RecordRefused, 1, self.now.micros());
                Ok(())
            }
            Err(e) => Err(e),
        }
    }

    pub(super) fn time(&self, t: Timestamp) -> i64 {
        self.clock.log_time(t)
    }

    pub(super) fn event(
        &mut self,
        t: Timestamp,
        level: u8,
        args: core::fmt::Arguments<'_>,
    ) -> Result<(), PipelineError<W::Error>> {
        let mut text: heapless::String<MAX_TEXT> = heapless::String::new();
        // A text longer than an event holds is cut where it no longer fits.
        let _ = text.write_fmt(args);
        let mut e = EventRecord { t_us: self.time(t), level, ..EventRecord::default() };
        let _ = e.text.extend_from_slice(text.as_bytes());
        self.write(&Record::Event(e))
    }

    /// Count an issue and write its event when due.
    pub(super) fn issue(&mut self, t: Timestamp, issue: Issue, n: u64) -> Result<(), PipelineError<W::Error>> {
        match self.issues.count(issue, n, t.micros()) {
            Some(total) => self.event(t, 3, format_args!("{} ({total} so far)", issue.text())),
            None => Ok(()),
        }
    }

    /// A change of the clock's offset at `t`: its `ClockOffset` record, and an event where
    /// it says something a reader should know.
    pub(super) fn offset_changed(&mut self, t: Timestamp, change: OffsetChange) -> Result<(), PipelineError<W::Error>> {
        let (offset, reason, text) = match change {
            OffsetChange::None | OffsetChange::Ignored(_) => return Ok(()),
            OffsetChange::First(o) => (o, 0, "UTC known from the first fix: the log is in UTC from here"),
            OffsetChange::Drift(o) => (o, 1, ""),
            OffsetChange::Step { offset, .. } => (offset, 2, "GNSS time stepped; the clock offset follows"),
            OffsetChange::AfterReset(o) => (o, 3, "UTC taken again after the device clock reset"),
            OffsetChange::Latency(o) => (o, 4, ""),
        };
        self.write(&Record::ClockOffset(ClockOffset { t_us: self.time(t), offset_us: offset, reason }))?;
        if text.is_empty() {
            return Ok(());
        }
        self.event(t, 2, format_args!("{text} (offset {offset} µs)"))
    }

    pub(super) fn monotonic(&mut self, device: Timestamp) -> Result<Timestamp, PipelineError<W::Error>> {
        let (t, reset) = self.clock.monotonic(device);
        if t > self.now {
            self.now = t;
        }
        let slewed = self.clock.slew(self.now);
        self.offset_changed(self.now, slewed)?;
        if let Some(back) = reset {
            self.issues.count(Issue::ClockReset, 1, t.micros());
            self.event(
                t,
                3,
                format_args!(
                    "device clock reset: went back {} s; monotonic time goes on, UTC is taken again from the next fix",
                    Decimal::new(back as f64 * 1e-6, 3)
                ),
            )?;
        }
        Ok(t)
    }
}
