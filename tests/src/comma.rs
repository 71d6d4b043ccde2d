//! The comma2k19 minute in the forms a device sees: the real u-blox fixes as the NMEA a
//! receiver would send (from comma's CSV: UTC, position, speed, course), stamped with the
//! device's receive time (`t_boot`).

use std::path::Path;

fn nmea_line(body: &str) -> String {
    let checksum = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{checksum:02X}\r\n")
}

fn angle(deg: f64, width: usize, hemispheres: [char; 2]) -> (String, char) {
    let a = deg.abs();
    let whole = a.floor();
    let minutes = (a - whole) * 60.0;
    (format!("{:0width$}{minutes:09.6}", whole as u32), if deg >= 0.0 { hemispheres[0] } else { hemispheres[1] })
}

/// comma's u-blox CSV as GGA + RMC sentences (UTC from its millisecond stamps, HDOP 0.9):
/// the raw NMEA text, the same as a serial capture (`(t_boot) sentence` per line), and
/// the offset boot time − UTC of the first fix, s.
pub fn ublox_nmea(csv: &Path) -> (String, String, f64) {
    let text = std::fs::read_to_string(csv).expect("live_gnss_ublox.csv");
    let (mut raw, mut stamped) = (String::new(), String::new());
    let mut offset = None;
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().expect("number")).collect();
        let [t_boot, lat, lon, speed, utc_ms, alt, bearing] = v[..] else { panic!("7 columns") };
        offset.get_or_insert(t_boot - utc_ms / 1000.0);
        let secs = utc_ms / 1000.0;
        let day = (secs / 86_400.0).floor();
        let tod = secs - day * 86_400.0;
        let hms = format!("{:02}{:02}{:05.2}", (tod / 3600.0) as u32, ((tod % 3600.0) / 60.0) as u32, tod % 60.0);
        // 2018-08-02 (the drive's date), as ddmmyy.
        let (la, ns) = angle(lat, 2, ['N', 'S']);
        let (lo, ew) = angle(lon, 3, ['E', 'W']);
        for sentence in [
            nmea_line(&format!("GPGGA,{hms},{la},{ns},{lo},{ew},1,10,0.9,{alt:.2},M,0.0,M,,")),
            nmea_line(&format!("GPRMC,{hms},A,{la},{ns},{lo},{ew},{:.3},{bearing:.2},020818,,,A", speed / 0.514_444)),
        ] {
            stamped += &format!("({t_boot:.6}) {sentence}");
            raw += &sentence;
        }
    }
    (raw, stamped, offset.expect("rows"))
}
