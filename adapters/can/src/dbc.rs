//! DBC files → a compact table of core [`Signal`]s, looked up by CAN id.
//!
//! Parsing is [`can_dbc`]'s; this module validates every signal once (it must fit a
//! classic 8-byte frame, be an integer, have finite scaling) so the hot path — the
//! core's [`decode_message`] — only shifts bits. Signals that cannot be decoded here are
//! listed as warnings, not silently dropped.

use std::collections::HashMap;
use std::fmt;
use std::path::Path;

use can_dbc::{ByteOrder as DbcByteOrder, MessageId, MultiplexIndicator, SignalExtendedValueType, ValueType};
use dash2sim_core::can::frame::{id_from_raw, raw_id};
use dash2sim_core::can::signal::{decode_message, ByteOrder, Multiplex, Signal};
use embedded_can::Id;

/// A DBC file that could not be used at all.
#[derive(Debug)]
pub enum DbcError {
    /// Reading the file failed.
    Io(std::io::Error),
    /// The text is not valid DBC.
    Parse(String),
    /// The text is neither UTF-8 nor Windows-1252.
    Encoding,
    /// An id offset moves a message's id out of its range (standard 0–0x7FF, extended
    /// 0–0x1FFFFFFF).
    IdOutOfRange {
        /// The message.
        message: String,
        /// Its id in the file.
        id: u32,
        /// The offset.
        offset: i64,
    },
}

impl fmt::Display for DbcError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DbcError::Io(e) => write!(f, "{e}"),
            DbcError::Parse(e) => write!(f, "not a valid DBC file: {e}"),
            DbcError::Encoding => write!(f, "neither UTF-8 nor Windows-1252 text"),
            DbcError::IdOutOfRange { message, id, offset } => {
                write!(f, "message {message} (id {id:#X}) moved by {offset:+#X} leaves the CAN id range")
            }
        }
    }
}

impl std::error::Error for DbcError {}

/// One message of the table.
#[derive(Clone, Debug, PartialEq)]
pub struct DbcMessage {
    /// Its CAN id.
    pub id: Id,
    /// The DBC's message name.
    pub name: String,
    /// Decodable signals, in DBC order.
    pub signals: Vec<Signal>,
    /// `signal_names[i]` names `signals[i]`.
    pub signal_names: Vec<String>,
    /// `units[i]` is the unit of `signals[i]` (may be empty).
    pub units: Vec<String>,
}

impl DbcMessage {
    /// Call `emit(name, value)` for every signal present in `data` (multiplexing
    /// respected). Returns how many signals the frame was too short to carry.
    pub fn decode(&self, data: &[u8], mut emit: impl FnMut(&str, f64)) -> usize {
        decode_message(&self.signals, data, |i, value| {
            if let Some(name) = self.signal_names.get(i) {
                emit(name, value);
            }
        })
    }

    /// The index of a signal by name.
    pub fn signal_index(&self, name: &str) -> Option<usize> {
        self.signal_names.iter().position(|n| n == name)
    }
}

/// Messages of one or more DBC files.
#[derive(Clone, Debug, Default)]
pub struct SignalTable {
    messages: Vec<DbcMessage>,
    by_id: HashMap<(bool, u32), usize>,
}

impl SignalTable {
    /// Parse DBC text; warnings list the signals and messages left out and why.
    pub fn parse(text: &str) -> Result<(Self, Vec<String>), DbcError> {
        let dbc = can_dbc::Dbc::try_from(text).map_err(|e| DbcError::Parse(e.to_string()))?;
        let mut table = SignalTable::default();
        let mut warnings = Vec::new();
        let float_signals: Vec<(MessageId, &str)> = dbc
            .signal_extended_value_type_list
            .iter()
            .filter(|t| t.signal_extended_value_type != SignalExtendedValueType::SignedOrUnsignedInteger)
            .map(|t| (t.message_id, t.signal_name.as_str()))
            .collect();
        let extended_mux: Vec<(MessageId, &str)> =
            dbc.extended_multiplex.iter().map(|m| (m.message_id, m.signal_name.as_str())).collect();
        for message in &dbc.messages {
            let id = match message.id {
                MessageId::Standard(raw) => id_from_raw(u32::from(raw), false),
                MessageId::Extended(raw) => id_from_raw(raw, true),
            };
            let Some(id) = id else {
                // Includes VECTOR__INDEPENDENT_SIG_MSG, the pseudo-message of unused signals.
                if message.name != "VECTOR__INDEPENDENT_SIG_MSG" {
                    warnings.push(format!(
                        "message {}: id {:#X} out of range, skipped",
                        message.name,
                        message.id.raw()
                    ));
                }
                continue;
            };
            let mut entry = DbcMessage {
                id,
                name: message.name.clone(),
                signals: Vec::new(),
                signal_names: Vec::new(),
                units: Vec::new(),
            };
            for signal in &message.signals {
                let skip = |why: &str| format!("{}.{}: {why}, skipped", message.name, signal.name);
                if float_signals.contains(&(message.id, signal.name.as_str())) {
                    warnings.push(skip("IEEE float signals are not supported"));
                    continue;
                }
                if extended_mux.contains(&(message.id, signal.name.as_str())) {
                    warnings.push(skip("extended multiplexing is not supported"));
                    continue;
                }
                let multiplex = match signal.multiplexer_indicator {
                    MultiplexIndicator::Plain => Multiplex::Plain,
                    MultiplexIndicator::Multiplexor => Multiplex::Multiplexor,
                    MultiplexIndicator::MultiplexedSignal(v) => Multiplex::Multiplexed(v),
                    MultiplexIndicator::MultiplexorAndMultiplexedSignal(_) => {
                        warnings.push(skip("nested multiplexing is not supported"));
                        continue;
                    }
                };
                let (Ok(start), Ok(length)) = (u16::try_from(signal.start_bit), u16::try_from(signal.size)) else {
                    warnings.push(skip("bit position out of range"));
                    continue;
                };
                let order = match signal.byte_order {
                    DbcByteOrder::LittleEndian => ByteOrder::Intel,
                    DbcByteOrder::BigEndian => ByteOrder::Motorola,
                };
                let signed = signal.value_type == ValueType::Signed;
                match Signal::new(start, length, order, signed, signal.factor, signal.offset, multiplex) {
                    Ok(s) => {
                        entry.signals.push(s);
                        entry.signal_names.push(signal.name.clone());
                        entry.units.push(signal.unit.clone());
                    }
                    Err(e) => warnings.push(skip(&e.to_string())),
                }
            }
            table.insert(entry);
        }
        Ok((table, warnings))
    }

    /// Read and parse a DBC file (UTF-8 or Windows-1252, as DBC editors write).
    pub fn load(path: &Path) -> Result<(Self, Vec<String>), DbcError> {
        let bytes = std::fs::read(path).map_err(DbcError::Io)?;
        match std::str::from_utf8(&bytes) {
            Ok(text) => Self::parse(text),
            Err(_) => Self::parse(&can_dbc::decode_cp1252(&bytes).ok_or(DbcError::Encoding)?),
        }
    }

    /// Add a message; a later definition of the same id replaces the earlier one.
    fn insert(&mut self, message: DbcMessage) {
        let key = key(message.id);
        match self.by_id.get(&key) {
            Some(&i) => self.messages[i] = message,
            None => {
                self.by_id.insert(key, self.messages.len());
                self.messages.push(message);
            }
        }
    }

    /// Every message's id moved by `offset`: the same module at another base id (a CANedge
    /// CANmod.gps configured to start at 0x65 where its DBC says 1 is `offset` 0x64).
    pub fn shifted(self, offset: i64) -> Result<Self, DbcError> {
        let mut table = SignalTable::default();
        for mut message in self.messages {
            let (extended, raw) = key(message.id);
            let moved = i64::from(raw).checked_add(offset).and_then(|id| u32::try_from(id).ok());
            message.id = moved.and_then(|id| id_from_raw(id, extended)).ok_or_else(|| DbcError::IdOutOfRange {
                message: message.name.clone(),
                id: raw,
                offset,
            })?;
            table.insert(message);
        }
        Ok(table)
    }

    /// Merge another table (e.g. a second `--dbc` file); its messages win on equal ids.
    pub fn extend(&mut self, other: SignalTable) {
        for message in other.messages {
            self.insert(message);
        }
    }

    /// The message with this id.
    pub fn message(&self, id: Id) -> Option<&DbcMessage> {
        self.by_id.get(&key(id)).and_then(|&i| self.messages.get(i))
    }

    /// The first message with this name.
    pub fn message_by_name(&self, name: &str) -> Option<&DbcMessage> {
        self.messages.iter().find(|m| m.name == name)
    }

    /// Number of messages.
    pub fn len(&self) -> usize {
        self.messages.len()
    }

    /// No messages at all.
    pub fn is_empty(&self) -> bool {
        self.messages.is_empty()
    }
}

fn key(id: Id) -> (bool, u32) {
    (matches!(id, Id::Extended(_)), raw_id(id))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shifted_table_finds_its_messages_at_the_new_ids_only() {
        let (table, _) = SignalTable::parse(DBC).expect("dbc");
        let moved = table.clone().shifted(0x64).expect("in range");
        let at = |t: &SignalTable, raw| t.message(id_from_raw(raw, false).expect("id")).map(|m| m.name.clone());
        assert_eq!(at(&moved, 170 + 0x64).as_deref(), Some("WHEEL_SPEEDS"));
        assert_eq!(at(&moved, 170), None);
        assert_eq!(moved.message_by_name("MUXED").map(|m| raw_id(m.id)), Some((2566844926 & 0x1FFF_FFFF) + 0x64));
        let back = moved.shifted(-0x64).expect("in range");
        assert_eq!(at(&back, 170).as_deref(), Some("WHEEL_SPEEDS"));
        let err = table.shifted(-171).expect_err("below zero");
        assert!(err.to_string().contains("WHEEL_SPEEDS"), "{err}");
    }

    const DBC: &str = r#"VERSION ""

NS_ :

BS_:

BU_: XXX

BO_ 170 WHEEL_SPEEDS: 8 XXX
 SG_ WHEEL_SPEED_FR : 6|15@0+ (0.01,-67.67) [0|250] "km/h" XXX
 SG_ WHEEL_SPEED_FL : 22|15@0+ (0.01,-67.67) [0|250] "km/h" XXX

BO_ 2566844926 MUXED: 8 XXX
 SG_ Selector M : 0|8@1+ (1,0) [0|255] "" XXX
 SG_ Speed m1 : 8|16@1+ (0.1,0) [0|0] "m/s" XXX
 SG_ Temp m2 : 8|8@1- (1,-40) [0|0] "degC" XXX
 SG_ TooLong : 60|8@1+ (1,0) [0|0] "" XXX
 SG_ Ratio : 16|32@1+ (1,0) [0|0] "" XXX

SIG_VALTYPE_ 2566844926 Ratio : 1;
"#;

    #[test]
    fn messages_signals_and_warnings() {
        let (table, warnings) = SignalTable::parse(DBC).expect("valid DBC");
        assert_eq!(table.len(), 2);
        let wheels = table.message(id_from_raw(170, false).expect("11-bit")).expect("0xAA");
        assert_eq!((wheels.name.as_str(), wheels.signal_names.len()), ("WHEEL_SPEEDS", 2));
        let mut values = Vec::new();
        wheels.decode(&[0x1B, 0x52, 0x1B, 0x48, 0, 0, 0, 0], |name, v| values.push((name.to_owned(), v)));
        assert_eq!(values[0].0, "WHEEL_SPEED_FR");
        assert!((values[0].1 - (6994.0 * 0.01 - 67.67)).abs() < 1e-9);

        // 2566844926 = 0x80000000 | 0x18FEF1FE: an extended id.
        let muxed = table.message(id_from_raw(0x18FE_F1FE, true).expect("29-bit")).expect("MUXED");
        assert_eq!(muxed.signal_names, ["Selector", "Speed", "Temp"]);
        assert_eq!(muxed.units[1], "m/s");
        let mut seen = Vec::new();
        muxed.decode(&[2, 0xF6, 0, 0, 0, 0, 0, 0], |name, v| seen.push((name.to_owned(), v)));
        assert_eq!(seen, [("Selector".to_owned(), 2.0), ("Temp".to_owned(), -50.0)]);
        assert!(table.message(id_from_raw(170, true).expect("29-bit")).is_none(), "11 and 29 bits differ");

        assert_eq!(warnings.len(), 2, "{warnings:?}");
        assert!(warnings[0].contains("MUXED.TooLong") && warnings[0].contains("does not fit"), "{warnings:?}");
        assert!(warnings[1].contains("MUXED.Ratio") && warnings[1].contains("float"), "{warnings:?}");
    }

    #[test]
    fn later_tables_override_and_errors_are_reported() {
        let (mut table, _) = SignalTable::parse(DBC).expect("valid");
        let (other, _) = SignalTable::parse(
            "VERSION \"\"\n\nBS_:\n\nBU_:\n\nBO_ 170 OTHER: 8 XXX\n SG_ X : 0|8@1+ (1,0) [0|0] \"\" XXX\n",
        )
        .expect("valid");
        table.extend(other);
        assert_eq!(table.len(), 2);
        assert_eq!(table.message(id_from_raw(170, false).expect("11-bit")).map(|m| m.name.as_str()), Some("OTHER"));
        assert!(matches!(SignalTable::parse("BO_ banana"), Err(DbcError::Parse(_))));
        assert!(matches!(SignalTable::load(Path::new("/nonexistent.dbc")), Err(DbcError::Io(_))));
    }
}
