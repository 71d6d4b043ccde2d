//! Little-endian fields of CAN payloads, with "not available" as `None`.
//!
//! NMEA 2000 and J1939 reserve the top of each field's range: all ones in an unsigned
//! field and the largest positive value in a signed one mean "not available".

/// `N` bytes at `offset`, or `None` past the end of `data`.
pub(crate) fn array<const N: usize>(data: &[u8], offset: usize) -> Option<[u8; N]> {
    data.get(offset..offset.checked_add(N)?)?.try_into().ok()
}

pub(crate) fn u8_at(data: &[u8], offset: usize) -> Option<u8> {
    data.get(offset).copied().filter(|&v| v != u8::MAX)
}

pub(crate) fn u16_at(data: &[u8], offset: usize) -> Option<u16> {
    array(data, offset).map(u16::from_le_bytes).filter(|&v| v != u16::MAX)
}

pub(crate) fn u32_at(data: &[u8], offset: usize) -> Option<u32> {
    array(data, offset).map(u32::from_le_bytes).filter(|&v| v != u32::MAX)
}

pub(crate) fn i16_at(data: &[u8], offset: usize) -> Option<i16> {
    array(data, offset).map(i16::from_le_bytes).filter(|&v| v != i16::MAX)
}

pub(crate) fn i32_at(data: &[u8], offset: usize) -> Option<i32> {
    array(data, offset).map(i32::from_le_bytes).filter(|&v| v != i32::MAX)
}

pub(crate) fn i64_at(data: &[u8], offset: usize) -> Option<i64> {
    array(data, offset).map(i64::from_le_bytes).filter(|&v| v != i64::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reserved_values_and_short_data_are_none() {
        let data = [0xFF, 0xFF, 0xFF, 0x7F, 0x01, 0x00];
        assert_eq!(u8_at(&data, 0), None);
        assert_eq!(u16_at(&data, 0), None);
        assert_eq!(i32_at(&data, 0), None);
        assert_eq!(u32_at(&data, 0), Some(0x7FFF_FFFF));
        assert_eq!(i16_at(&data, 0), Some(-1), "all ones is -1 in a signed field");
        assert_eq!(u16_at(&data, 4), Some(1));
        assert_eq!(u16_at(&data, 5), None, "runs past the end");
        assert_eq!(array::<2>(&data, usize::MAX), None);
    }
}
