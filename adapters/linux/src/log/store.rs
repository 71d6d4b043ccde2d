//! Records held compactly in memory.
//!
//! A decoded [`Record`] is as large as its largest variant — a batch of 3D tracks, 784
//! bytes inline, because the core allocates nothing — so an hour of driving (270 000
//! records: GNSS, wheel speed, VO) takes 214 MB as a `Vec<Record>` although its log file is
//! 3 MB. A [`RecordStore`] keeps each record as its quantised fields, varint-coded and
//! independent of its neighbours (random access, unlike the file's delta streams): some 20
//! bytes and an offset a record, and the track batches — few, and large in any form —
//! beside them as they are. `finish` holds a drive this way (docs/benchmarks.md).

use dash2sim_core::binlog::varint::{self, unzigzag, zigzag};
use dash2sim_core::binlog::{Kind, Record, Tracks3d, MAX_FIELDS};

/// Records in order, each coded as its fields ([`Record::fields`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecordStore {
    /// Per record: the kind's code, then a batch's index in `batches` or the number of
    /// fields, the fields zigzag-varint-coded and an event's text (length first).
    bytes: Vec<u8>,
    /// Where each record starts in `bytes`.
    starts: Vec<usize>,
    batches: Vec<Tracks3d>,
}

/// The longest coding of one record: code, count, fields, text length and text.
const MAX_CODED: usize = 2 + (MAX_FIELDS + 1) * 10 + dash2sim_core::binlog::MAX_TEXT;

impl RecordStore {
    /// An empty store with room for `records` of about the usual size.
    pub fn with_capacity(records: usize) -> Self {
        RecordStore {
            bytes: Vec::with_capacity(records * 16),
            starts: Vec::with_capacity(records),
            batches: Vec::new(),
        }
    }

    /// How many records it holds.
    pub fn len(&self) -> usize {
        self.starts.len()
    }

    /// Whether it holds none.
    pub fn is_empty(&self) -> bool {
        self.starts.is_empty()
    }

    /// Append `record`.
    pub fn push(&mut self, record: &Record) {
        let mut coded = [0u8; MAX_CODED];
        coded[0] = record.kind().code();
        let mut at = 1;
        // Each `put` fits: `coded` has room for the longest record (10 bytes a varint).
        if let Record::Tracks3d(b) = record {
            varint::put(&mut coded, &mut at, self.batches.len() as u64);
            self.batches.push(b.clone());
        } else {
            let mut fields = [0i64; MAX_FIELDS];
            let n = record.fields(&mut fields);
            varint::put(&mut coded, &mut at, n as u64);
            for v in &fields[..n] {
                varint::put(&mut coded, &mut at, zigzag(*v));
            }
            if let Record::Event(e) = record {
                varint::put(&mut coded, &mut at, e.text.len() as u64);
                coded[at..at + e.text.len()].copy_from_slice(&e.text);
                at += e.text.len();
            }
        }
        self.starts.push(self.bytes.len());
        self.bytes.extend_from_slice(&coded[..at]);
    }

    /// The `k`-th record.
    pub fn get(&self, k: usize) -> Option<Record> {
        let start = *self.starts.get(k)?;
        let end = self.starts.get(k + 1).copied().unwrap_or(self.bytes.len());
        self.decode(self.bytes.get(start..end)?)
    }

    /// The records in order.
    pub fn iter(&self) -> impl DoubleEndedIterator<Item = Record> + ExactSizeIterator + '_ {
        // Every record was coded by `push`, so each decodes: `get` cannot miss here.
        (0..self.len()).map(|k| self.get(k).unwrap_or_else(|| unreachable!("record {k} was coded by push")))
    }

    /// The same records in time order, those of one time in the order they were (a stable
    /// sort).
    pub fn sorted_by_time(&self) -> RecordStore {
        let times: Vec<i64> = self.iter().map(|r| r.t_us()).collect();
        let mut order: Vec<usize> = (0..self.len()).collect();
        order.sort_by_key(|&k| times[k]);
        let mut sorted = RecordStore::with_capacity(self.len());
        for k in order {
            sorted.push_coded_from(self, k);
        }
        sorted
    }

    /// The same records, each changed by `change`, in the same order.
    pub fn map(&self, mut change: impl FnMut(&mut Record)) -> RecordStore {
        let mut changed = RecordStore::with_capacity(self.len());
        for mut r in self.iter() {
            change(&mut r);
            changed.push(&r);
        }
        changed
    }

    /// The records as a `Vec` (each as large as the largest kind: for small logs).
    pub fn to_vec(&self) -> Vec<Record> {
        self.iter().collect()
    }

    /// Append `other`'s `k`-th record as it is coded (a batch moves by a clone).
    fn push_coded_from(&mut self, other: &RecordStore, k: usize) {
        let start = other.starts[k];
        let end = other.starts.get(k + 1).copied().unwrap_or(other.bytes.len());
        let coded = &other.bytes[start..end];
        if coded.first() == Some(&Kind::Tracks3d.code()) {
            if let Some(Record::Tracks3d(b)) = other.decode(coded) {
                self.push(&Record::Tracks3d(b));
                return;
            }
        }
        self.starts.push(self.bytes.len());
        self.bytes.extend_from_slice(coded);
    }

    fn decode(&self, coded: &[u8]) -> Option<Record> {
        let kind = Kind::from_code(*coded.first()?)?;
        let mut at = 1;
        if kind == Kind::Tracks3d {
            let k = usize::try_from(varint::get(coded, &mut at)?).ok()?;
            return self.batches.get(k).cloned().map(Record::Tracks3d);
        }
        let n = usize::try_from(varint::get(coded, &mut at)?).ok().filter(|n| *n <= MAX_FIELDS)?;
        let mut fields = [0i64; MAX_FIELDS];
        for v in &mut fields[..n] {
            *v = unzigzag(varint::get(coded, &mut at)?);
        }
        let text = if kind == Kind::Event {
            let len = usize::try_from(varint::get(coded, &mut at)?).ok()?;
            coded.get(at..at + len)?
        } else {
            &[]
        };
        Record::from_fields(kind, &fields[..n], text)
    }
}

impl Extend<Record> for RecordStore {
    fn extend<I: IntoIterator<Item = Record>>(&mut self, records: I) {
        for r in records {
            self.push(&r);
        }
    }
}

impl<'a> Extend<&'a Record> for RecordStore {
    fn extend<I: IntoIterator<Item = &'a Record>>(&mut self, records: I) {
        for r in records {
            self.push(r);
        }
    }
}

impl FromIterator<Record> for RecordStore {
    fn from_iter<I: IntoIterator<Item = Record>>(records: I) -> Self {
        let mut store = RecordStore::default();
        store.extend(records);
        store
    }
}

impl<'a> FromIterator<&'a Record> for RecordStore {
    fn from_iter<I: IntoIterator<Item = &'a Record>>(records: I) -> Self {
        let mut store = RecordStore::default();
        store.extend(records);
        store
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dash2sim_core::binlog::{EgoPose, GnssFix, Track3d, VehicleSpeed};

    /// One record of every kind with every field set to something other than 0 (so a
    /// field the store dropped or moved shows), extremes included.
    fn every_kind() -> Vec<Record> {
        let mut records = Vec::new();
        for (k, kind) in Kind::ALL.iter().enumerate() {
            let record = match kind {
                Kind::Tracks3d => {
                    let mut b = Tracks3d { t_us: 7 + k as i64, ..Default::default() };
                    for id in 0..3 {
                        let _ = b.tracks.push(Track3d { id, x_mm: -1_000 * id, ..Default::default() });
                    }
                    Record::Tracks3d(b)
                }
                Kind::Event => crate::log::event(-5, 3, "ein Ereignis — with a long dash"),
                _ => {
                    let n = kind.modes().len();
                    let fields: Vec<i64> = (0..n as i64)
                        .map(|f| match f {
                            0 => 1_700_000_000_000_000 + k as i64,
                            1 => i64::MIN + 1,
                            2 => i64::MAX,
                            _ => -(f * 37 + k as i64),
                        })
                        .collect();
                    // Fields a kind keeps narrower (codes, flags) come back as the record
                    // holds them: compare against the record made from the fields.
                    Record::from_fields(*kind, &fields, &[]).expect("a kind made of fields")
                }
            };
            records.push(record);
        }
        records
    }

    #[test]
    fn every_kind_comes_back_as_it_was_pushed() {
        let records = every_kind();
        let store: RecordStore = records.iter().collect();
        assert_eq!(store.len(), records.len());
        assert_eq!(store.to_vec(), records);
        for (k, r) in records.iter().enumerate() {
            assert_eq!(store.get(k).as_ref(), Some(r), "record {k}");
        }
        assert_eq!(store.get(records.len()), None);
        assert_eq!(store.iter().next_back().as_ref(), records.last());
    }

    #[test]
    fn an_hour_of_sensor_records_is_held_in_a_few_bytes_each() {
        let mut store = RecordStore::default();
        for k in 0..50_000i64 {
            let t_us = 1_700_000_000_000_000 + 20_000 * k;
            store.push(&Record::VehicleSpeed(VehicleSpeed { t_us, speed_mm_s: 13_889, ..Default::default() }));
            store.push(&Record::GnssFix(GnssFix {
                t_us,
                lat_e7: 601_699_999 + k,
                lon_e7: 249_399_999 - k,
                mode: 3,
                ..Default::default()
            }));
        }
        // Held: the coded fields and an offset a record.
        let held = store.bytes.len() + size_of::<usize>() * store.starts.len();
        let per_record = held as f64 / store.len() as f64;
        assert!(per_record <= 32.0, "{per_record:.1} bytes a record");
        assert!(per_record * 20.0 < size_of::<Record>() as f64, "{per_record:.1} bytes a record");
    }

    #[test]
    fn sorting_by_time_is_stable_and_keeps_batches_with_their_records() {
        let pose = |t_us, x_mm| Record::EgoPose(EgoPose { t_us, x_mm, ..Default::default() });
        let batch = |t_us, id| {
            let mut b = Tracks3d { t_us, ..Default::default() };
            let _ = b.tracks.push(Track3d { id, ..Default::default() });
            Record::Tracks3d(b)
        };
        let records = [pose(30, 1), batch(20, 9), pose(10, 2), pose(20, 3), batch(10, 8), pose(20, 4)];
        let store: RecordStore = records.iter().collect();
        let sorted = store.sorted_by_time().to_vec();
        let mut expected = records.to_vec();
        expected.sort_by_key(Record::t_us);
        assert_eq!(sorted, expected);
        assert_eq!(sorted[0], pose(10, 2), "the pose first at 10 µs, as pushed");
        let shifted = store.map(|r| r.set_t_us(r.t_us() + 5)).to_vec();
        assert!(shifted.iter().zip(&records).all(|(a, b)| a.t_us() == b.t_us() + 5 && a.kind() == b.kind()));
    }
}
