//! From a 4D log's or a map tile's local ENU frame into the projected frame nuPlan's maps
//! use: the UTM zone of the map's origin (WGS 84, EPSG 326zz north / 327zz south), through
//! geodetic coordinates. UTM's Transverse Mercator is Rust Geodesy's (Krüger's series).

use dash2sim_core::geo::{Geodetic, LocalFrame};
use dash2sim_core::nalgebra::Vector3;
use dash2sim_linux::{Error, Result};
use geodesy::prelude::*;

/// ENU of one origin → UTM of one zone.
#[derive(Debug)]
pub struct Projection {
    frame: LocalFrame,
    context: Minimal,
    utm: OpHandle,
    /// UTM zone (1–60).
    pub zone: u8,
    /// Northern hemisphere.
    pub north: bool,
}

impl Projection {
    /// The projection for the local frame at `origin` into its own UTM zone.
    pub fn new(origin: Geodetic) -> Result<Self> {
        let zone = (((origin.lon_deg + 180.0) / 6.0).floor() as i64).rem_euclid(60) as u8 + 1;
        Self::with_zone(origin, zone, origin.lat_deg >= 0.0)
    }

    /// The projection for the local frame at `origin` into UTM zone `zone` (a log whose
    /// origin differs from its map's goes into the map's zone).
    pub fn with_zone(origin: Geodetic, zone: u8, north: bool) -> Result<Self> {
        let mut context = Minimal::default();
        let definition = if north { format!("utm zone={zone}") } else { format!("utm zone={zone} south") };
        let utm = context.op(&definition).map_err(|e| Error::refused(format!("UTM zone {zone}"), e))?;
        Ok(Projection { frame: LocalFrame::new(origin), context, utm, zone, north })
    }

    /// The EPSG code of the zone (WGS 84 / UTM).
    pub fn epsg(&self) -> i32 {
        if self.north {
            32600 + i32::from(self.zone)
        } else {
            32700 + i32::from(self.zone)
        }
    }

    /// Easting, northing of ENU points (NaN where a point has no geodetic position).
    pub fn project(&self, enu: &[(f64, f64, f64)]) -> Vec<(f64, f64)> {
        let mut data: Vec<Coor2D> = enu
            .iter()
            .map(|&(e, n, u)| match self.frame.enu_to_geodetic(&Vector3::new(e, n, u)) {
                Ok(g) => Coor2D::geo(g.lat_deg, g.lon_deg),
                Err(_) => Coor2D::nan(),
            })
            .collect();
        if self.context.apply(self.utm, Fwd, &mut data).is_err() {
            return vec![(f64::NAN, f64::NAN); enu.len()];
        }
        data.iter().map(|c| (c[0], c[1])).collect()
    }

    /// A heading (rad, counter-clockwise from east) at an ENU point, as a grid heading: the
    /// direction of a point 1 m ahead, projected (the meridian convergence of the place).
    pub fn heading(&self, at: (f64, f64, f64), heading: f64) -> f64 {
        let ahead = (at.0 + heading.cos(), at.1 + heading.sin(), at.2);
        let p = self.project(&[at, ahead]);
        (p[1].1 - p[0].1).atan2(p[1].0 - p[0].0)
    }

    /// The zone's WKT (EPSG's definition, as GDAL writes it).
    pub fn wkt(&self) -> String {
        let central = f64::from(self.zone) * 6.0 - 183.0;
        let false_northing = if self.north { 0 } else { 10_000_000 };
        format!(
            r#"PROJCS["WGS 84 / UTM zone {zone}{hemisphere}",GEOGCS["WGS 84",DATUM["WGS_1984",SPHEROID["WGS 84",6378137,298.257223563,AUTHORITY["EPSG","7030"]],AUTHORITY["EPSG","6326"]],PRIMEM["Greenwich",0,AUTHORITY["EPSG","8901"]],UNIT["degree",0.0174532925199433,AUTHORITY["EPSG","9122"]],AUTHORITY["EPSG","4326"]],PROJECTION["Transverse_Mercator"],PARAMETER["latitude_of_origin",0],PARAMETER["central_meridian",{central}],PARAMETER["scale_factor",0.9996],PARAMETER["false_easting",500000],PARAMETER["false_northing",{false_northing}],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AXIS["Northing",NORTH],AUTHORITY["EPSG","{epsg}"]]"#,
            zone = self.zone,
            hemisphere = if self.north { "N" } else { "S" },
            epsg = self.epsg(),
        )
    }

    /// The zone's name as EPSG gives it.
    pub fn name(&self) -> String {
        format!("WGS 84 / UTM zone {}{}", self.zone, if self.north { "N" } else { "S" })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn helsinki_lands_in_zone_35_where_proj_puts_it() {
        // pyproj 3.7.2 (EPSG:4326 → EPSG:32635): 60.17°N 24.94°E → 385 700.421 E, 6 672 126.743 N.
        let p = Projection::new(Geodetic::new(60.17, 24.94, 0.0).expect("origin")).expect("projection");
        assert_eq!((p.zone, p.north, p.epsg()), (35, true, 32635));
        let [(e, n)] = p.project(&[(0.0, 0.0, 0.0)])[..] else { panic!("one point") };
        assert!((e - 385_700.421).abs() < 0.001 && (n - 6_672_126.743).abs() < 0.001, "{e} {n}");
        // True north on the grid, west of the central meridian (27°E): pyproj's projection of
        // a point 1 m north (pyproj.Geod) gives atan2(dN, dE) = 1.539603 rad.
        let h = p.heading((0.0, 0.0, 0.0), std::f64::consts::FRAC_PI_2);
        assert!((h - 1.539_603).abs() < 1e-5, "{h}");
    }
}
