//! The scene's local metric frame: x east, y north in metres about an origin, z up unchanged.
//!
//! Geographic CRSs use a local equirectangular projection on the WGS 84 ellipsoid (the datum of
//! other geographic CRSs such as NAD83 differs by far less than a DEM cell for this purpose):
//! `x = (lon − lon0)·N(lat0)·cos(lat0)·π/180`, `y = (lat − lat0)·M(lat0)·π/180`, with `N` and
//! `M` the prime-vertical and meridional radii of curvature at `lat0`. Projected CRSs are only
//! translated to the origin and scaled to metres, so `f32` world coordinates stay precise.

use super::crs::Crs;
use super::error::GisError;
use super::raster::Raster;

/// WGS 84 semi-major axis in metres.
pub const WGS84_A: f64 = 6_378_137.0;
/// WGS 84 flattening.
pub const WGS84_F: f64 = 1.0 / 298.257_223_563;

/// Largest |latitude| of a geographic frame origin; the equirectangular approximation
/// degenerates towards the poles.
pub const MAX_ORIGIN_LATITUDE: f64 = 85.0;

/// Maps CRS coordinates to local metres about an origin and back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalFrame {
    crs: Crs,
    origin_x: f64,
    origin_y: f64,
    /// Metres per CRS unit along x.
    scale_x: f64,
    /// Metres per CRS unit along y.
    scale_y: f64,
}

/// Meridional (M) and prime-vertical (N) radii of curvature of WGS 84 at a latitude in
/// degrees, in metres.
pub fn wgs84_radii(lat_deg: f64) -> (f64, f64) {
    let e2 = WGS84_F * (2.0 - WGS84_F);
    let s = lat_deg.to_radians().sin();
    let w2 = 1.0 - e2 * s * s;
    let n = WGS84_A / w2.sqrt();
    let m = WGS84_A * (1.0 - e2) / (w2 * w2.sqrt());
    (m, n)
}

impl LocalFrame {
    /// A frame for `crs` with its origin at the CRS point (`x0`, `y0`).
    pub fn new(crs: Crs, x0: f64, y0: f64) -> Result<LocalFrame, GisError> {
        if !x0.is_finite() || !y0.is_finite() {
            return Err(GisError::BadFrame { reason: format!("origin ({x0}, {y0}) is not finite") });
        }
        let (scale_x, scale_y) = match crs {
            Crs::Unspecified => return Err(GisError::UnspecifiedCrs),
            Crs::Geographic { .. } => {
                if y0.abs() > MAX_ORIGIN_LATITUDE {
                    return Err(GisError::BadFrame {
                        reason: format!(
                            "latitude {y0}° of the origin is beyond ±{MAX_ORIGIN_LATITUDE}°; \
                             use a projected CRS near the poles"
                        ),
                    });
                }
                let (m, n) = wgs84_radii(y0);
                let deg = std::f64::consts::PI / 180.0;
                (n * y0.to_radians().cos() * deg, m * deg)
            }
            Crs::Projected { unit_to_metre, .. } => {
                if !(unit_to_metre.is_finite() && unit_to_metre > 0.0) {
                    return Err(GisError::BadFrame {
                        reason: format!("CRS unit of {unit_to_metre} m is not positive"),
                    });
                }
                (unit_to_metre, unit_to_metre)
            }
        };
        Ok(LocalFrame { crs, origin_x: x0, origin_y: y0, scale_x, scale_y })
    }

    /// The frame of a raster, with its origin at the centre of the raster's extent. Errors if
    /// the raster's CRS is [`Crs::Unspecified`].
    pub fn for_raster(r: &Raster) -> Result<LocalFrame, GisError> {
        let (x0, y0) = r.extent().center();
        LocalFrame::new(r.crs, x0, y0)
    }

    /// CRS coordinates → local metres (x east, y north).
    pub fn to_local(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.origin_x) * self.scale_x, (y - self.origin_y) * self.scale_y)
    }

    /// Local metres → CRS coordinates (exact inverse of [`LocalFrame::to_local`]).
    pub fn to_crs(&self, x: f64, y: f64) -> (f64, f64) {
        (x / self.scale_x + self.origin_x, y / self.scale_y + self.origin_y)
    }

    /// The origin in CRS coordinates.
    pub fn origin_crs(&self) -> (f64, f64) {
        (self.origin_x, self.origin_y)
    }

    /// The CRS the frame converts from.
    pub fn crs(&self) -> &Crs {
        &self.crs
    }

    /// Metres per CRS unit along x and y (e.g. to convert cell sizes).
    pub fn scale(&self) -> (f64, f64) {
        (self.scale_x, self.scale_y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radii_match_reference_values() {
        // Equator: M = a(1−e²), N = a.
        let (m0, n0) = wgs84_radii(0.0);
        assert!((n0 - WGS84_A).abs() < 1e-6);
        assert!((m0 - 6_335_439.327).abs() < 1e-3);
        // Pole: M = N = a / sqrt(1−e²).
        let (m90, n90) = wgs84_radii(90.0);
        assert!((m90 - 6_399_593.626).abs() < 1e-3);
        assert!((n90 - 6_399_593.626).abs() < 1e-3);
    }

    #[test]
    fn geographic_round_trip_and_scale() {
        let f = LocalFrame::new(Crs::Geographic { epsg: Some(4326) }, -105.45, 40.15).unwrap();
        assert_eq!(f.to_local(-105.45, 40.15), (0.0, 0.0));
        for &(x, y) in &[(-105.55, 40.09), (-105.35, 40.21), (-105.0, 39.0)] {
            let (lx, ly) = f.to_local(x, y);
            let (bx, by) = f.to_crs(lx, ly);
            assert!((bx - x).abs() < 1e-12 && (by - y).abs() < 1e-12);
        }
        let (sx, sy) = f.scale();
        assert!(sx < sy, "a degree of longitude is shorter than one of latitude at 40°N");
    }

    #[test]
    fn projected_is_translation_and_unit_scale() {
        let crs = Crs::Projected { epsg: None, unit_to_metre: crate::gis::crs::FOOT };
        let f = LocalFrame::new(crs, 1000.0, 2000.0).unwrap();
        assert_eq!(f.to_local(1010.0, 1990.0), (10.0 * 0.3048, -10.0 * 0.3048));
        assert_eq!(f.origin_crs(), (1000.0, 2000.0));
        assert_eq!(f.crs(), &crs);
    }

    #[test]
    fn rejects_bad_frames() {
        assert!(matches!(LocalFrame::new(Crs::Unspecified, 0.0, 0.0), Err(GisError::UnspecifiedCrs)));
        assert!(matches!(LocalFrame::new(Crs::Geographic { epsg: None }, 0.0, 89.0), Err(GisError::BadFrame { .. })));
        assert!(matches!(
            LocalFrame::new(Crs::Geographic { epsg: None }, f64::NAN, 0.0),
            Err(GisError::BadFrame { .. })
        ));
        let zero_unit = Crs::Projected { epsg: None, unit_to_metre: 0.0 };
        assert!(matches!(LocalFrame::new(zero_unit, 0.0, 0.0), Err(GisError::BadFrame { .. })));
        let msg = GisError::UnspecifiedCrs.to_string();
        assert!(msg.contains("crs = \"EPSG:4326\""), "{msg}");
    }
}
