//! An ENU origin written `LAT,LON[,H]`: the one form every front end takes it in (the
//! command line's `map build`, `record`, `import`), the height above the ellipsoid in
//! metres (0 when absent).

use dash2sim_core::geo::Geodetic;

use crate::numbers::comma_separated;
use crate::{Error, Result};

/// Parse `LAT,LON[,H]` (degrees, degrees, metres above the WGS84 ellipsoid).
pub fn parse_origin(text: &str) -> Result<Geodetic> {
    let values = comma_separated(text, "LAT,LON[,H] numbers")?;
    match values[..] {
        [lat, lon] | [lat, lon, _] if (-90.0..=90.0).contains(&lat) && (-180.0..=180.0).contains(&lon) => {
            Geodetic::new(lat, lon, values.get(2).copied().unwrap_or(0.0))
                .map_err(|e| Error::refused(format!("origin {text:?}"), e))
        }
        _ => Err(Error::invalid("expected LAT,LON[,H] with a valid latitude and longitude")),
    }
}

#[cfg(test)]
mod tests {
    use super::parse_origin;

    #[test]
    fn the_height_is_optional_and_kept() {
        let g = parse_origin("60.2711, 24.8572,20").expect("origin");
        assert_eq!((g.lat_deg, g.lon_deg, g.height_m), (60.2711, 24.8572, 20.0));
        assert_eq!(parse_origin("60.2711,24.8572").expect("origin").height_m, 0.0);
        for bad in ["60.2711", "91,0", "a,b", "1,2,3,4", "60,24,nan"] {
            assert!(parse_origin(bad).is_err(), "{bad}");
        }
    }
}
