// The byte format of the `anchor_inputs` fuzz target, shared (via `include!`) with the
// core test that replays pinned crash inputs, so both decode them the same way.
// The includer imports `AnchorConfig`, `AnchorMode`, `Anchorer`, `Timestamp`, `Vector3`.

/// Little-endian f64 from up to 8 bytes (missing bytes read as 0).
fn f64_at(bytes: &[u8]) -> f64 {
    let mut b = [0u8; 8];
    for (d, s) in b.iter_mut().zip(bytes) {
        *d = *s;
    }
    f64::from_le_bytes(b)
}

/// Byte 0 picks the mode; then 27-byte records: kind, time in ms (u16), three f64.
/// Every estimate reported on the way must be finite with a positive scale.
fn replay_anchor_input(data: &[u8]) {
    let Some((&mode, mut rest)) = data.split_first() else { return };
    let mode = if mode & 1 == 0 { AnchorMode::Full } else { AnchorMode::GravityAligned };
    let mut anchorer: Anchorer = Anchorer::new(AnchorConfig { mode, ..AnchorConfig::default() });
    while rest.len() >= 27 {
        let (record, tail) = rest.split_at(27);
        rest = tail;
        let t = Timestamp::from_micros(i64::from(u16::from_le_bytes([record[1], record[2]])) * 1000);
        let v = Vector3::new(f64_at(&record[3..]), f64_at(&record[11..]), f64_at(&record[19..]));
        let _ = match record[0] % 3 {
            0 => anchorer.push_vo(t, v),
            1 => anchorer.push_gnss(t, v, v.x.abs() % 10.0 + 0.1),
            _ => anchorer.push_speed(t, v.y),
        };
        if let Some(est) = anchorer.estimate() {
            assert!(est.is_valid(), "{est:?}");
        }
    }
}
