//! Geodesy on the WGS84 ellipsoid: geodetic ↔ ECEF ↔ local ENU.
//!
//! Everything is `f64`: ECEF coordinates are ~6.4e6 m, so `f32` would leave ~0.5 m steps.
//! The ECEF → geodetic direction uses Heikkinen's closed form (no iteration, so no loop
//! bound to reason about on untrusted input); it is exact to well below a micrometre for
//! any point more than a few kilometres from the Earth's centre.

use nalgebra::{Matrix3, Vector3};

/// WGS84 semi-major axis (m).
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;
/// WGS84 semi-minor axis (m).
pub const WGS84_B: f64 = WGS84_A * (1.0 - WGS84_F);
/// First eccentricity squared.
pub const WGS84_E2: f64 = WGS84_F * (2.0 - WGS84_F);

/// Below this distance from the Earth's axis (m) a point counts as on a pole, where
/// longitude is undefined and is reported as 0.
const POLAR_AXIS_EPS_M: f64 = 1e-9;
/// Points closer than this to the Earth's centre (m) have no meaningful geodetic position.
const MIN_GEOCENTRIC_RADIUS_M: f64 = 100_000.0;

/// A geodetic position: latitude and longitude in degrees, height above the ellipsoid in
/// metres (not above mean sea level — add the geoid separation for that).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Geodetic {
    /// Latitude, degrees north, −90..=90.
    pub lat_deg: f64,
    /// Longitude, degrees east, −180..=180.
    pub lon_deg: f64,
    /// Ellipsoidal height, metres.
    pub height_m: f64,
}

/// Why a position could not be converted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GeoError {
    /// A coordinate is NaN or infinite.
    NonFinite,
    /// Latitude outside ±90° or longitude outside ±180°.
    OutOfRange,
    /// An ECEF point too close to the Earth's centre to have a geodetic position.
    NearGeocentre,
}

impl core::fmt::Display for GeoError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            GeoError::NonFinite => "coordinate is NaN or infinite",
            GeoError::OutOfRange => "latitude or longitude out of range",
            GeoError::NearGeocentre => "ECEF point too close to the Earth's centre",
        })
    }
}

impl core::error::Error for GeoError {}

impl Geodetic {
    /// A checked geodetic position.
    pub fn new(lat_deg: f64, lon_deg: f64, height_m: f64) -> Result<Self, GeoError> {
        if !(lat_deg.is_finite() && lon_deg.is_finite() && height_m.is_finite()) {
            return Err(GeoError::NonFinite);
        }
        if libm::fabs(lat_deg) > 90.0 || libm::fabs(lon_deg) > 180.0 {
            return Err(GeoError::OutOfRange);
        }
        Ok(Geodetic { lat_deg, lon_deg, height_m })
    }

    /// Earth-centred, Earth-fixed coordinates (m).
    pub fn to_ecef(&self) -> Vector3<f64> {
        let lat = self.lat_deg.to_radians();
        let lon = self.lon_deg.to_radians();
        let (slat, clat) = (libm::sin(lat), libm::cos(lat));
        let (slon, clon) = (libm::sin(lon), libm::cos(lon));
        let n = WGS84_A / libm::sqrt(1.0 - WGS84_E2 * slat * slat);
        Vector3::new(
            (n + self.height_m) * clat * clon,
            (n + self.height_m) * clat * slon,
            (n * (1.0 - WGS84_E2) + self.height_m) * slat,
        )
    }

    /// The geodetic position of an ECEF point (Heikkinen 1982, closed form).
    pub fn from_ecef(ecef: &Vector3<f64>) -> Result<Self, GeoError> {
        let (x, y, z) = (ecef.x, ecef.y, ecef.z);
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return Err(GeoError::NonFinite);
        }
        if ecef.norm() < MIN_GEOCENTRIC_RADIUS_M {
            return Err(GeoError::NearGeocentre);
        }
        let (a, b, e2) = (WGS84_A, WGS84_B, WGS84_E2);
        let ep2 = (a * a - b * b) / (b * b);
        let p = libm::sqrt(x * x + y * y);
        if p < POLAR_AXIS_EPS_M {
            let lat = if z >= 0.0 { 90.0 } else { -90.0 };
            return Ok(Geodetic { lat_deg: lat, lon_deg: 0.0, height_m: libm::fabs(z) - b });
        }
        let f = 54.0 * b * b * z * z;
        let g = p * p + (1.0 - e2) * z * z - e2 * (a * a - b * b);
        let c = e2 * e2 * f * p * p / (g * g * g);
        let s = libm::cbrt(1.0 + c + libm::sqrt(c * c + 2.0 * c));
        let k = s + 1.0 + 1.0 / s;
        let pp = f / (3.0 * k * k * g * g);
        let q = libm::sqrt(1.0 + 2.0 * e2 * e2 * pp);
        let r0 = -pp * e2 * p / (1.0 + q)
            + libm::sqrt(0.5 * a * a * (1.0 + 1.0 / q) - pp * (1.0 - e2) * z * z / (q * (1.0 + q)) - 0.5 * pp * p * p);
        let pe = p - e2 * r0;
        let u = libm::sqrt(pe * pe + z * z);
        let v = libm::sqrt(pe * pe + (1.0 - e2) * z * z);
        let z0 = b * b * z / (a * v);
        let height_m = u * (1.0 - b * b / (a * v));
        let lat = libm::atan2(z + ep2 * z0, p);
        let lon = libm::atan2(y, x);
        Ok(Geodetic { lat_deg: lat.to_degrees(), lon_deg: lon.to_degrees(), height_m })
    }
}

/// Iteration bound of Vincenty's inverse method (it converges in a handful of
/// iterations except for nearly antipodal points).
const VINCENTY_MAX_ITERATIONS: usize = 200;

/// Distance (m) on the WGS84 ellipsoid between two points and the initial bearing
/// (degrees clockwise from north, 0..360) from the first to the second — Vincenty's
/// inverse method (1975). `None` when it does not converge (nearly antipodal points).
pub fn distance_and_bearing(lat1_deg: f64, lon1_deg: f64, lat2_deg: f64, lon2_deg: f64) -> Option<(f64, f64)> {
    let (a, b, f) = (WGS84_A, WGS84_B, WGS84_F);
    let l = (lon2_deg - lon1_deg).to_radians();
    let u1 = libm::atan((1.0 - f) * libm::tan(lat1_deg.to_radians()));
    let u2 = libm::atan((1.0 - f) * libm::tan(lat2_deg.to_radians()));
    let (su1, cu1) = (libm::sin(u1), libm::cos(u1));
    let (su2, cu2) = (libm::sin(u2), libm::cos(u2));
    let mut lambda = l;
    for _ in 0..VINCENTY_MAX_ITERATIONS {
        let (sl, cl) = (libm::sin(lambda), libm::cos(lambda));
        let sin_sigma =
            libm::sqrt((cu2 * sl) * (cu2 * sl) + (cu1 * su2 - su1 * cu2 * cl) * (cu1 * su2 - su1 * cu2 * cl));
        if sin_sigma == 0.0 {
            return Some((0.0, 0.0));
        }
        let cos_sigma = su1 * su2 + cu1 * cu2 * cl;
        let sigma = libm::atan2(sin_sigma, cos_sigma);
        let sin_alpha = cu1 * cu2 * sl / sin_sigma;
        let cos2_alpha = 1.0 - sin_alpha * sin_alpha;
        let cos_2sm = if cos2_alpha != 0.0 { cos_sigma - 2.0 * su1 * su2 / cos2_alpha } else { 0.0 };
        let c = f / 16.0 * cos2_alpha * (4.0 + f * (4.0 - 3.0 * cos2_alpha));
        let previous = lambda;
        lambda = l
            + (1.0 - c)
                * f
                * sin_alpha
                * (sigma + c * sin_sigma * (cos_2sm + c * cos_sigma * (-1.0 + 2.0 * cos_2sm * cos_2sm)));
        if libm::fabs(lambda - previous) < 1e-12 {
            let u_sq = cos2_alpha * (a * a - b * b) / (b * b);
            let big_a = 1.0 + u_sq / 16384.0 * (4096.0 + u_sq * (-768.0 + u_sq * (320.0 - 175.0 * u_sq)));
            let big_b = u_sq / 1024.0 * (256.0 + u_sq * (-128.0 + u_sq * (74.0 - 47.0 * u_sq)));
            let delta_sigma = big_b
                * sin_sigma
                * (cos_2sm
                    + big_b / 4.0
                        * (cos_sigma * (-1.0 + 2.0 * cos_2sm * cos_2sm)
                            - big_b / 6.0
                                * cos_2sm
                                * (-3.0 + 4.0 * sin_sigma * sin_sigma)
                                * (-3.0 + 4.0 * cos_2sm * cos_2sm)));
            let distance = b * big_a * (sigma - delta_sigma);
            let (sl, cl) = (libm::sin(lambda), libm::cos(lambda));
            let bearing = libm::atan2(cu2 * sl, cu1 * su2 - su1 * cu2 * cl).to_degrees();
            return Some((distance, if bearing < 0.0 { bearing + 360.0 } else { bearing }));
        }
    }
    None
}

/// A local east-north-up tangent plane at a geodetic origin.
///
/// Anchoring, tracking and the map all work in one such frame per drive; its origin is
/// written in the log header so every local coordinate can be geo-referenced again.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalFrame {
    origin: Geodetic,
    origin_ecef: Vector3<f64>,
    /// Rows are the east, north and up unit vectors in ECEF.
    ecef_to_enu: Matrix3<f64>,
}

impl LocalFrame {
    /// The ENU frame whose origin is `origin`.
    pub fn new(origin: Geodetic) -> Self {
        let lat = origin.lat_deg.to_radians();
        let lon = origin.lon_deg.to_radians();
        let (slat, clat) = (libm::sin(lat), libm::cos(lat));
        let (slon, clon) = (libm::sin(lon), libm::cos(lon));
        #[rustfmt::skip]
        let ecef_to_enu = Matrix3::new(
            -slon,          clon,         0.0,
            -slat * clon,  -slat * slon,  clat,
             clat * clon,   clat * slon,  slat,
        );
        LocalFrame { origin, origin_ecef: origin.to_ecef(), ecef_to_enu }
    }

    /// The geodetic origin.
    pub fn origin(&self) -> Geodetic {
        self.origin
    }

    /// ECEF point → ENU coordinates (m).
    pub fn ecef_to_enu(&self, ecef: &Vector3<f64>) -> Vector3<f64> {
        self.ecef_to_enu * (ecef - self.origin_ecef)
    }

    /// ENU coordinates → ECEF point.
    pub fn enu_to_ecef(&self, enu: &Vector3<f64>) -> Vector3<f64> {
        self.ecef_to_enu.transpose() * enu + self.origin_ecef
    }

    /// Geodetic position → ENU coordinates.
    pub fn geodetic_to_enu(&self, g: &Geodetic) -> Vector3<f64> {
        self.ecef_to_enu(&g.to_ecef())
    }

    /// ENU coordinates → geodetic position.
    pub fn enu_to_geodetic(&self, enu: &Vector3<f64>) -> Result<Geodetic, GeoError> {
        Geodetic::from_ecef(&self.enu_to_ecef(enu))
    }

    /// Rotation taking ECEF-frame vectors to ENU (rows: east, north, up).
    pub fn rotation_ecef_to_enu(&self) -> &Matrix3<f64> {
        &self.ecef_to_enu
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn equator_prime_meridian_is_on_the_x_axis() {
        let e = Geodetic::new(0.0, 0.0, 0.0).expect("valid").to_ecef();
        assert!((e.x - WGS84_A).abs() < 1e-9 && e.y.abs() < 1e-9 && e.z.abs() < 1e-9);
    }

    #[test]
    fn poles_and_geocentre() {
        let north = Geodetic::from_ecef(&Vector3::new(0.0, 0.0, WGS84_B + 10.0)).expect("pole");
        assert_eq!(north.lat_deg, 90.0);
        assert!((north.height_m - 10.0).abs() < 1e-9);
        assert_eq!(Geodetic::from_ecef(&Vector3::new(1.0, 2.0, 3.0)), Err(GeoError::NearGeocentre));
        assert_eq!(Geodetic::from_ecef(&Vector3::new(f64::NAN, 0.0, 0.0)), Err(GeoError::NonFinite));
        assert_eq!(Geodetic::new(91.0, 0.0, 0.0), Err(GeoError::OutOfRange));
    }

    #[test]
    fn enu_axes_point_east_north_up() {
        let frame = LocalFrame::new(Geodetic::new(37.721, -122.4723, 31.6).expect("valid"));
        let north = frame.geodetic_to_enu(&Geodetic::new(37.722, -122.4723, 31.6).expect("valid"));
        assert!(north.y > 110.0 && north.y < 112.0 && north.x.abs() < 1e-6, "{north:?}");
        let east = frame.geodetic_to_enu(&Geodetic::new(37.721, -122.4713, 31.6).expect("valid"));
        assert!(east.x > 87.0 && east.x < 89.0 && east.y.abs() < 1e-3, "{east:?}");
    }

    #[test]
    fn vincenty_distance_and_bearing() {
        // Flinders Peak → Buninyong, Vincenty's own test line: 54 972.271 m, 306° 52′ 05.37″.
        let (d, b) = distance_and_bearing(-37.951_033_417, 144.424_867_889, -37.652_821_139, 143.926_495_528)
            .expect("converges");
        assert!((d - 54_972.271).abs() < 1e-3, "{d}");
        assert!((b - (306.0 + 52.0 / 60.0 + 5.37 / 3600.0)).abs() < 1e-5, "{b}");
        assert_eq!(distance_and_bearing(10.0, 20.0, 10.0, 20.0), Some((0.0, 0.0)));
        let (east, bearing) = distance_and_bearing(0.0, 0.0, 0.0, 1.0).expect("converges");
        assert!((east - 111_319.491).abs() < 1e-3 && (bearing - 90.0).abs() < 1e-9);
    }

    proptest! {
        #[test]
        fn geodetic_ecef_round_trip_below_a_micrometre(
            lat in -89.9f64..89.9, lon in -180.0f64..180.0, h in -500.0f64..20_000.0
        ) {
            let g = Geodetic::new(lat, lon, h).expect("valid");
            let ecef = g.to_ecef();
            let back = Geodetic::from_ecef(&ecef).expect("finite");
            prop_assert!((back.to_ecef() - ecef).norm() < 1e-6);
            prop_assert!((back.height_m - h).abs() < 1e-6);
        }

        #[test]
        fn enu_round_trip_below_a_micrometre(
            lat in -80.0f64..80.0, lon in -180.0f64..180.0,
            e in -50_000.0f64..50_000.0, n in -50_000.0f64..50_000.0, u in -200.0f64..2000.0
        ) {
            let frame = LocalFrame::new(Geodetic::new(lat, lon, 10.0).expect("valid"));
            let enu = Vector3::new(e, n, u);
            let g = frame.enu_to_geodetic(&enu).expect("finite");
            prop_assert!((frame.geodetic_to_enu(&g) - enu).norm() < 1e-6);
        }
    }
}
