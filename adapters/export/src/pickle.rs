//! Python pickles of plain values and numpy arrays, as ScenarioNet stores its scenarios.
//!
//! ScenarioNet's files are `pickle.dump` of dicts of strings, numbers, lists and numpy arrays.
//! This writes the same objects in pickle protocol 4 (unframed, no memo: both optional), and an
//! array the way numpy's own `ndarray.__reduce__` does — `numpy.core.multiarray._reconstruct`
//! and a `BUILD` with the shape, the dtype and the raw little-endian bytes — so the reader gets
//! an ordinary writable array. The module path is numpy 1's, which numpy 2 still loads without
//! a warning; numpy 2's own `numpy._core` would not load in numpy 1.
//!
//! No crate fits: `serde-pickle` writes plain values but no numpy arrays.

/// A Python value.
#[derive(Clone, Debug, PartialEq)]
pub enum Py {
    /// `None`.
    None,
    /// `True` / `False`.
    Bool(bool),
    /// An `int`.
    Int(i64),
    /// A `float`.
    Float(f64),
    /// A `str`.
    Str(String),
    /// A `list`.
    List(Vec<Py>),
    /// A `set`.
    Set(Vec<Py>),
    /// A `dict` with string keys, in this order.
    Dict(Vec<(String, Py)>),
    /// A numpy array.
    Array(Array),
}

impl From<&str> for Py {
    fn from(s: &str) -> Self {
        Py::Str(s.to_string())
    }
}

impl From<String> for Py {
    fn from(s: String) -> Self {
        Py::Str(s)
    }
}

impl From<f64> for Py {
    fn from(v: f64) -> Self {
        Py::Float(v)
    }
}

impl From<i64> for Py {
    fn from(v: i64) -> Self {
        Py::Int(v)
    }
}

impl From<usize> for Py {
    fn from(v: usize) -> Self {
        Py::Int(i64::try_from(v).unwrap_or(i64::MAX))
    }
}

impl From<bool> for Py {
    fn from(v: bool) -> Self {
        Py::Bool(v)
    }
}

impl From<Array> for Py {
    fn from(a: Array) -> Self {
        Py::Array(a)
    }
}

/// A dict from `(key, value)` pairs.
pub fn dict<const N: usize>(items: [(&str, Py); N]) -> Py {
    Py::Dict(items.into_iter().map(|(k, v)| (k.to_string(), v)).collect())
}

/// An element type of a numpy array.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dtype {
    /// `float32`.
    F32,
    /// `float64`.
    F64,
    /// `bool`.
    Bool,
}

impl Dtype {
    /// numpy's name of the type and its byte order mark.
    fn code(self) -> (&'static str, &'static str) {
        match self {
            Dtype::F32 => ("f4", "<"),
            Dtype::F64 => ("f8", "<"),
            Dtype::Bool => ("b1", "|"),
        }
    }
}

/// A C-ordered numpy array.
#[derive(Clone, Debug, PartialEq)]
pub struct Array {
    dtype: Dtype,
    shape: Vec<usize>,
    data: Vec<u8>,
}

impl Array {
    /// A `float32` array of `shape` from `values` in C order.
    pub fn f32(shape: &[usize], values: impl IntoIterator<Item = f64>) -> Self {
        let data = values.into_iter().flat_map(|v| (v as f32).to_le_bytes()).collect();
        Array { dtype: Dtype::F32, shape: shape.to_vec(), data }
    }

    /// A `float64` array.
    pub fn f64(shape: &[usize], values: impl IntoIterator<Item = f64>) -> Self {
        let data = values.into_iter().flat_map(f64::to_le_bytes).collect();
        Array { dtype: Dtype::F64, shape: shape.to_vec(), data }
    }

    /// A `bool` array.
    pub fn bool(shape: &[usize], values: impl IntoIterator<Item = bool>) -> Self {
        let data = values.into_iter().map(u8::from).collect();
        Array { dtype: Dtype::Bool, shape: shape.to_vec(), data }
    }
}

// The opcodes used (CPython's Lib/pickletools.py names them).
const PROTO: u8 = 0x80;
const STOP: u8 = b'.';
const NONE: u8 = b'N';
const NEWTRUE: u8 = 0x88;
const NEWFALSE: u8 = 0x89;
const BININT: u8 = b'J';
const LONG1: u8 = 0x8a;
const BINFLOAT: u8 = b'G';
const SHORT_BINUNICODE: u8 = 0x8c;
const BINUNICODE: u8 = b'X';
const SHORT_BINBYTES: u8 = b'C';
const BINBYTES: u8 = b'B';
const EMPTY_LIST: u8 = b']';
const APPENDS: u8 = b'e';
const EMPTY_DICT: u8 = b'}';
const SETITEMS: u8 = b'u';
const EMPTY_SET: u8 = 0x8f;
const ADDITEMS: u8 = 0x90;
const MARK: u8 = b'(';
const TUPLE: u8 = b't';
const TUPLE1: u8 = 0x85;
const TUPLE3: u8 = 0x87;
const GLOBAL: u8 = b'c';
const REDUCE: u8 = b'R';
const BUILD: u8 = b'b';

/// `value` as a protocol 4 pickle.
pub fn dumps(value: &Py) -> Vec<u8> {
    let mut out = vec![PROTO, 4];
    write(&mut out, value);
    out.push(STOP);
    out
}

fn write(out: &mut Vec<u8>, value: &Py) {
    match value {
        Py::None => out.push(NONE),
        Py::Bool(b) => out.push(if *b { NEWTRUE } else { NEWFALSE }),
        Py::Int(i) => int(out, *i),
        Py::Float(f) => {
            out.push(BINFLOAT);
            out.extend_from_slice(&f.to_be_bytes());
        }
        Py::Str(s) => string(out, s),
        Py::List(items) => {
            out.push(EMPTY_LIST);
            if !items.is_empty() {
                out.push(MARK);
                items.iter().for_each(|v| write(out, v));
                out.push(APPENDS);
            }
        }
        Py::Set(items) => {
            out.push(EMPTY_SET);
            if !items.is_empty() {
                out.push(MARK);
                items.iter().for_each(|v| write(out, v));
                out.push(ADDITEMS);
            }
        }
        Py::Dict(items) => {
            out.push(EMPTY_DICT);
            if !items.is_empty() {
                out.push(MARK);
                for (k, v) in items {
                    string(out, k);
                    write(out, v);
                }
                out.push(SETITEMS);
            }
        }
        Py::Array(a) => array(out, a),
    }
}

fn int(out: &mut Vec<u8>, i: i64) {
    if let Ok(small) = i32::try_from(i) {
        out.push(BININT);
        out.extend_from_slice(&small.to_le_bytes());
    } else {
        out.extend_from_slice(&[LONG1, 8]);
        out.extend_from_slice(&i.to_le_bytes());
    }
}

fn string(out: &mut Vec<u8>, s: &str) {
    match u8::try_from(s.len()) {
        Ok(n) => out.extend_from_slice(&[SHORT_BINUNICODE, n]),
        Err(_) => {
            out.push(BINUNICODE);
            out.extend_from_slice(&(s.len() as u32).to_le_bytes());
        }
    }
    out.extend_from_slice(s.as_bytes());
}

fn bytes(out: &mut Vec<u8>, b: &[u8]) {
    match u8::try_from(b.len()) {
        Ok(n) => out.extend_from_slice(&[SHORT_BINBYTES, n]),
        Err(_) => {
            out.push(BINBYTES);
            out.extend_from_slice(&(b.len() as u32).to_le_bytes());
        }
    }
    out.extend_from_slice(b);
}

fn global(out: &mut Vec<u8>, module: &str, name: &str) {
    out.push(GLOBAL);
    out.extend_from_slice(module.as_bytes());
    out.push(b'\n');
    out.extend_from_slice(name.as_bytes());
    out.push(b'\n');
}

/// `_reconstruct(ndarray, (0,), b'b')`, then `BUILD` with `(1, shape, dtype, False, data)`.
fn array(out: &mut Vec<u8>, a: &Array) {
    global(out, "numpy.core.multiarray", "_reconstruct");
    global(out, "numpy", "ndarray");
    int(out, 0);
    out.push(TUPLE1);
    bytes(out, b"b");
    out.extend_from_slice(&[TUPLE3, REDUCE, MARK]);
    int(out, 1);
    out.push(MARK);
    a.shape.iter().for_each(|&n| int(out, i64::try_from(n).unwrap_or(i64::MAX)));
    out.push(TUPLE);
    // dtype(code, False, True), then BUILD with (3, order, None, None, None, -1, -1, 0).
    let (code, order) = a.dtype.code();
    global(out, "numpy", "dtype");
    string(out, code);
    out.extend_from_slice(&[NEWFALSE, NEWTRUE, TUPLE3, REDUCE, MARK]);
    int(out, 3);
    string(out, order);
    out.extend_from_slice(&[NONE, NONE, NONE]);
    int(out, -1);
    int(out, -1);
    int(out, 0);
    out.extend_from_slice(&[TUPLE, BUILD, NEWFALSE]);
    bytes(out, &a.data);
    out.extend_from_slice(&[TUPLE, BUILD]);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bytes of a small scenario-like dict, checked once with CPython 3.11 and numpy 2.4
    /// (`pickle.loads` under `-W error` gives `{'id': 'a', 'ts': array([0. , 0.1],
    /// dtype=float32), 'valid': array([ True, False]), 'n': [1, None, 2.5, -3000000000],
    /// 'kinds': {'VEHICLE'}}`, arrays writable).
    #[test]
    fn a_dict_of_arrays_pickles_as_numpy_reads_it() {
        let value = dict([
            ("id", "a".into()),
            ("ts", Array::f32(&[2], [0.0, 0.1]).into()),
            ("valid", Array::bool(&[2], [true, false]).into()),
            ("n", Py::List(vec![1i64.into(), Py::None, 2.5.into(), Py::Int(-3_000_000_000)])),
            ("kinds", Py::Set(vec!["VEHICLE".into()])),
        ]);
        let bytes = dumps(&value);
        let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(
            hex,
            concat!(
                "80047d288c0269648c01618c027473636e756d70792e636f72652e6d756c746961727261790a5f7265636f6e73747275",
                "63740a636e756d70790a6e6461727261790a4a00000000854301628752284a01000000284a0200000074636e756d7079",
                "0a64747970650a8c02663489888752284a030000008c013c4e4e4e4affffffff4affffffff4a00000000746289430800",
                "000000cdcccc3d74628c0576616c6964636e756d70792e636f72652e6d756c746961727261790a5f7265636f6e737472",
                "7563740a636e756d70790a6e6461727261790a4a00000000854301628752284a01000000284a0200000074636e756d70",
                "790a64747970650a8c02623189888752284a030000008c017c4e4e4e4affffffff4affffffff4a000000007462894302",
                "010074628c016e5d284a010000004e4740040000000000008a0800a22f4dffffffff658c056b696e64738f288c075645",
                "4849434c4590752e",
            )
        );
    }

    #[test]
    fn long_strings_and_byte_strings_take_the_four_byte_length() {
        let long = "x".repeat(300);
        let bytes = dumps(&Py::Str(long.clone()));
        assert_eq!(&bytes[2..7], &[BINUNICODE, 44, 1, 0, 0]);
        assert_eq!(bytes.len(), 2 + 5 + 300 + 1);
        let a = Array::f64(&[40], (0..40).map(f64::from));
        let pickled = dumps(&Py::Array(a));
        let data_at = pickled.windows(5).position(|w| w == [BINBYTES, 64, 1, 0, 0]);
        assert!(data_at.is_some(), "320 bytes of data need BINBYTES");
    }
}
