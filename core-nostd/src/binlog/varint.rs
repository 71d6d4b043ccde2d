//! LEB128 varints and zigzag signs: small magnitudes take few bytes, in either sign.

/// Longest varint of a u64.
pub const MAX_VARINT: usize = 10;

/// Map a signed value to unsigned so that small magnitudes stay small (0, −1, 1, −2 → 0, 1, 2, 3).
pub const fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

/// Inverse of [`zigzag`].
pub const fn unzigzag(u: u64) -> i64 {
    ((u >> 1) as i64) ^ -((u & 1) as i64)
}

/// Append `v` to `out` at `*at`; false (nothing written) when it does not fit.
pub fn put(out: &mut [u8], at: &mut usize, mut v: u64) -> bool {
    let mut bytes = [0u8; MAX_VARINT];
    let mut n = 0;
    loop {
        let byte = (v & 0x7f) as u8;
        v >>= 7;
        if v == 0 {
            bytes[n] = byte;
            n += 1;
            break;
        }
        bytes[n] = byte | 0x80;
        n += 1;
    }
    match out.get_mut(*at..*at + n) {
        Some(slot) => {
            slot.copy_from_slice(&bytes[..n]);
            *at += n;
            true
        }
        None => false,
    }
}

/// Bytes `v` takes as a varint.
pub fn len(v: u64) -> usize {
    let bits = 64 - v.leading_zeros() as usize;
    bits.div_ceil(7).max(1)
}

/// Read a varint from `input` at `*at`. `None` when the input ends inside it or it is
/// longer than ten bytes / overflows a u64.
pub fn get(input: &[u8], at: &mut usize) -> Option<u64> {
    let mut v: u64 = 0;
    for k in 0..MAX_VARINT {
        let byte = *input.get(*at + k)?;
        let bits = u64::from(byte & 0x7f);
        if k == MAX_VARINT - 1 && byte > 1 {
            return None;
        }
        v |= bits << (7 * k);
        if byte & 0x80 == 0 {
            *at += k + 1;
            return Some(v);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_at_the_edges() {
        for v in [0u64, 1, 127, 128, 16_383, 16_384, u64::from(u32::MAX), u64::MAX - 1, u64::MAX] {
            let mut buf = [0u8; MAX_VARINT];
            let mut at = 0;
            assert!(put(&mut buf, &mut at, v));
            assert_eq!(at, len(v));
            let mut back = 0;
            assert_eq!(get(&buf, &mut back), Some(v));
            assert_eq!(back, at);
        }
        for v in [0i64, -1, 1, -64, 63, i64::MIN, i64::MAX] {
            assert_eq!(unzigzag(zigzag(v)), v);
        }
        assert_eq!((zigzag(-1), zigzag(1), zigzag(-64)), (1, 2, 127));
    }

    #[test]
    fn truncated_and_overlong_varints_are_refused() {
        let mut at = 0;
        assert_eq!(get(&[0x80, 0x80], &mut at), None);
        assert_eq!(get(&[0xff; 11], &mut at), None);
        assert_eq!(get(&[0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02], &mut at), None);
        assert_eq!(at, 0, "nothing consumed on failure");
        let mut small = [0u8; 1];
        let mut at = 0;
        assert!(!put(&mut small, &mut at, 300) && at == 0);
    }
}
