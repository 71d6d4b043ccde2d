//! The tile's byte format: the header, the section sizes and constants, the body's
//! CRC-32C, the little-endian readers every accessor goes through (out of range reads give
//! 0 or NaN, never a panic), and why a tile is refused.

use crc::{Crc, CRC_32_ISCSI};

/// The file's first six bytes.
pub const MAGIC: [u8; 6] = *b"D2SMAP";
/// Format major version written by this crate; this view reads it and version 1 (the
/// same without item boxes).
pub const VERSION_MAJOR: u8 = 2;
/// Format minor version written by this crate (a reader accepts any minor of its major).
pub const VERSION_MINOR: u8 = 0;
/// Header length in bytes.
pub const HEADER_LEN: usize = 88;
/// Bytes per point (x, y as f32).
pub const POINT_LEN: usize = 8;
/// Bytes per lane record.
pub const LANE_LEN: usize = 28;
/// Bytes per polygon record.
pub const POLYGON_LEN: usize = 8;
/// Bytes per item box (lo x, lo y, hi x, hi y as f32; format 2).
pub const BOX_LEN: usize = 16;
/// "No neighbour".
pub const NONE: u32 = u32::MAX;
/// Grid entries with this bit set name a polygon, otherwise a lane.
pub const POLYGON_BIT: u32 = 0x8000_0000;

/// CRC-32C (Castagnoli), the checksum of the tile's body.
pub const CRC32C: Crc<u32> = Crc::<u32>::new(&CRC_32_ISCSI);

/// Why a tile was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapError {
    /// Shorter than the header.
    TooShort,
    /// Not a dash2sim map tile.
    BadMagic,
    /// A major version this reader does not know.
    UnsupportedVersion(u8),
    /// The body does not match its CRC-32C.
    BadChecksum,
    /// The sections do not add up to the tile's length.
    BadLength,
    /// A record refers outside its section (section name, record index).
    BadReference(&'static str, u32),
    /// A coordinate, size or origin is not finite or out of range (section, index).
    BadValue(&'static str, u32),
}

impl core::fmt::Display for MapError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            MapError::TooShort => write!(f, "shorter than the {HEADER_LEN}-byte header"),
            MapError::BadMagic => write!(f, "not a dash2sim map tile (bad magic)"),
            MapError::UnsupportedVersion(v) => {
                write!(f, "format version {v} is not supported (this reader: 1 and {VERSION_MAJOR})")
            }
            MapError::BadChecksum => write!(f, "CRC-32C mismatch: the tile is corrupted"),
            MapError::BadLength => write!(f, "section lengths do not match the tile length (truncated?)"),
            MapError::BadReference(section, i) => write!(f, "{section} {i} refers outside the tile"),
            MapError::BadValue(section, i) => write!(f, "{section} {i} has a value out of range"),
        }
    }
}

impl core::error::Error for MapError {}

pub(super) fn u16_at(b: &[u8], at: usize) -> u16 {
    match b.get(at..at + 2) {
        Some(&[x, y]) => u16::from_le_bytes([x, y]),
        _ => 0,
    }
}

pub(super) fn u32_at(b: &[u8], at: usize) -> u32 {
    match b.get(at..at + 4) {
        Some(&[a, c, d, e]) => u32::from_le_bytes([a, c, d, e]),
        _ => 0,
    }
}

pub(super) fn f32_at(b: &[u8], at: usize) -> f32 {
    f32::from_bits(u32_at(b, at))
}

pub(super) fn f64_at(b: &[u8], at: usize) -> f64 {
    match b.get(at..at + 8) {
        Some(s) => {
            let mut a = [0u8; 8];
            a.copy_from_slice(s);
            f64::from_le_bytes(a)
        }
        None => f64::NAN,
    }
}

/// The counts and grid geometry of a tile, from its header.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Header {
    /// ENU origin: latitude, longitude (degrees), height (m).
    pub origin: [f64; 3],
    /// Points.
    pub points: u32,
    /// Lanes.
    pub lanes: u32,
    /// Successor entries.
    pub successors: u32,
    /// Drivable polygons.
    pub polygons: u32,
    /// Grid entries.
    pub grid_entries: u32,
    /// Grid cell size, m.
    pub cell_size: f32,
    /// Grid lower-left corner (x, y), m.
    pub grid_min: [f32; 2],
    /// Grid columns and rows.
    pub grid_size: [u16; 2],
    /// What the source file held: nodes, ways, highway ways, relations (for `map info`).
    pub source_counts: [u32; 4],
    /// Whether the tile has a box per lane and polygon (format 2; format 1 has none).
    pub boxes: bool,
}

impl Header {
    pub(super) fn read(b: &[u8]) -> Header {
        Header {
            origin: [f64_at(b, 8), f64_at(b, 16), f64_at(b, 24)],
            points: u32_at(b, 32),
            lanes: u32_at(b, 36),
            successors: u32_at(b, 40),
            polygons: u32_at(b, 44),
            grid_entries: u32_at(b, 48),
            cell_size: f32_at(b, 52),
            grid_min: [f32_at(b, 56), f32_at(b, 60)],
            grid_size: [u16_at(b, 64), u16_at(b, 66)],
            source_counts: [u32_at(b, 68), u32_at(b, 72), u32_at(b, 76), u32_at(b, 80)],
            boxes: b.get(6).is_some_and(|&major| major >= 2),
        }
    }

    /// Write the header (CRC left zero) into `out[..HEADER_LEN]`.
    pub fn write(&self, out: &mut [u8]) {
        let Some(h) = out.get_mut(..HEADER_LEN) else { return };
        h.fill(0);
        h[..6].copy_from_slice(&MAGIC);
        h[6] = if self.boxes { VERSION_MAJOR } else { 1 };
        h[7] = VERSION_MINOR;
        for (k, v) in self.origin.iter().enumerate() {
            h[8 + 8 * k..16 + 8 * k].copy_from_slice(&v.to_le_bytes());
        }
        for (at, v) in
            [(32, self.points), (36, self.lanes), (40, self.successors), (44, self.polygons), (48, self.grid_entries)]
        {
            h[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
        for (at, v) in [(52, self.cell_size), (56, self.grid_min[0]), (60, self.grid_min[1])] {
            h[at..at + 4].copy_from_slice(&v.to_le_bytes());
        }
        h[64..66].copy_from_slice(&self.grid_size[0].to_le_bytes());
        h[66..68].copy_from_slice(&self.grid_size[1].to_le_bytes());
        for (k, v) in self.source_counts.iter().enumerate() {
            h[68 + 4 * k..72 + 4 * k].copy_from_slice(&v.to_le_bytes());
        }
    }

    pub(super) fn cells(&self) -> usize {
        usize::from(self.grid_size[0]) * usize::from(self.grid_size[1])
    }

    /// Byte offsets of the sections: points, lanes, successors, polygons, cell starts,
    /// entries, boxes (empty in format 1), end.
    pub fn layout(&self) -> Option<[usize; 8]> {
        let points = HEADER_LEN;
        let lanes = points.checked_add((self.points as usize).checked_mul(POINT_LEN)?)?;
        let successors = lanes.checked_add((self.lanes as usize).checked_mul(LANE_LEN)?)?;
        let polygons = successors.checked_add((self.successors as usize).checked_mul(4)?)?;
        let cells = polygons.checked_add((self.polygons as usize).checked_mul(POLYGON_LEN)?)?;
        let entries = cells.checked_add(self.cells().checked_add(1)?.checked_mul(4)?)?;
        let boxes = entries.checked_add((self.grid_entries as usize).checked_mul(4)?)?;
        let items = if self.boxes { (self.lanes as usize).checked_add(self.polygons as usize)? } else { 0 };
        let end = boxes.checked_add(items.checked_mul(BOX_LEN)?)?;
        Some([points, lanes, successors, polygons, cells, entries, boxes, end])
    }
}

/// Where the body's CRC-32C is stored.
pub const CRC_AT: usize = 84;

/// CRC-32C of a tile body, stored at bytes 84..88.
pub fn body_checksum(tile: &[u8]) -> u32 {
    CRC32C.checksum(tile.get(HEADER_LEN..).unwrap_or(&[]))
}

/// A point as stored: x, y as little-endian f32.
pub(super) type StoredPoint = [u8; POINT_LEN];

/// The coordinates of a stored point.
pub(super) fn xy(p: &StoredPoint) -> [f32; 2] {
    let [a, b, c, d, e, f, g, h] = *p;
    [f32::from_le_bytes([a, b, c, d]), f32::from_le_bytes([e, f, g, h])]
}
