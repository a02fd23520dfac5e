//! Reprojection between CRSs with the pure-Rust `proj4rs` crate.
//!
//! [`Crs`] only says whether coordinates are degrees or linear units; to move coordinates from
//! one CRS to another a full definition is needed. A [`CrsDefinition`] is a PROJ.4 string plus
//! the [`Crs`] it describes, built from
//!
//! - an EPSG code ([`CrsDefinition::from_epsg`]): the geographic CRSs on the WGS 84 or GRS 80
//!   ellipsoids (4326, 4269, 4258, 4283, 4617, 6318, 4674, 7844, 4167, 4612, 6668, 4490),
//!   WGS 84 / UTM zones N and S (326xx, 327xx), NAD83 / UTM (269xx), ETRS89 / UTM (258xx),
//!   NAD83 / Conus Albers (5070, 6350), ETRS89 / LAEA Europe (3035);
//! - GeoTIFF GeoKeys ([`CrsDefinition::from_geokeys`]), including user-defined CRSs that
//!   describe a geographic CRS or a UTM / Transverse Mercator projection on a given ellipsoid;
//! - a PROJ.4 string given by the user ([`CrsDefinition::from_proj_string`]).
//!
//! Datums whose shift to WGS 84 is below a metre (NAD83, ETRS89, GDA94, …) are taken as WGS 84
//! (`+towgs84=0,0,0`); datums that need grids or large shifts (NAD27, ED50, OSGB36 …) are not
//! supported and give a [`ReprojectError::Unsupported`] naming the code.

use proj4rs::proj::Proj;

use super::crs::Crs;
use super::geotiff::GeoKeyValues;

/// Why a CRS cannot be defined or coordinates cannot be transformed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReprojectError {
    /// The CRS is known to exist but this crate cannot transform it.
    #[error("unsupported CRS {}: {reason}", crate::echo::echo(.crs))]
    Unsupported {
        /// The CRS as text (e.g. `EPSG:27700` or a GeoKey description).
        crs: String,
        /// Why.
        reason: String,
    },
    /// Nothing is known about the CRS (no GeoKeys, no `.prj`, no `crs` given).
    #[error("the data has no coordinate reference system: give one (e.g. crs=EPSG:4326) or assume the scene's")]
    Missing,
    /// `proj4rs` rejected a definition.
    #[error("invalid CRS definition \"{}\": {message}", crate::echo::echo(.definition))]
    Invalid {
        /// The PROJ.4 string.
        definition: String,
        /// What `proj4rs` reported.
        message: String,
    },
}

/// A CRS that can take part in a transformation: the [`Crs`] and its PROJ.4 definition.
#[derive(Debug, Clone, PartialEq)]
pub struct CrsDefinition {
    crs: Crs,
    proj: String,
}

/// WGS 84 as a PROJ.4 string.
const WGS84_LONGLAT: &str = "+proj=longlat +datum=WGS84 +no_defs";
/// PROJ.4 ellipsoid and datum terms for GRS 80 datums treated as WGS 84.
const GRS80_AS_WGS84: &str = "+ellps=GRS80 +towgs84=0,0,0,0,0,0,0";

/// EPSG geographic CRSs on GRS 80 whose datum is within a metre or so of WGS 84.
const GRS80_GEOGRAPHIC: &[u32] = &[4269, 4258, 4283, 4617, 6318, 4674, 7844, 4167, 4612, 6668, 4490];

/// GeoKey ids (GeoTIFF 1.0) read here.
mod key {
    pub const MODEL_TYPE: u16 = 1024;
    pub const GEOGRAPHIC_TYPE: u16 = 2048;
    pub const GEODETIC_DATUM: u16 = 2050;
    pub const ELLIPSOID: u16 = 2056;
    pub const SEMI_MAJOR_AXIS: u16 = 2057;
    pub const SEMI_MINOR_AXIS: u16 = 2058;
    pub const INV_FLATTENING: u16 = 2059;
    pub const TOWGS84: u16 = 2062;
    pub const PROJECTED_CS_TYPE: u16 = 3072;
    pub const PROJECTION: u16 = 3074;
    pub const COORD_TRANS: u16 = 3075;
    pub const LINEAR_UNITS: u16 = 3076;
    pub const LINEAR_UNIT_SIZE: u16 = 3077;
    pub const NAT_ORIGIN_LONG: u16 = 3080;
    pub const NAT_ORIGIN_LAT: u16 = 3081;
    pub const FALSE_EASTING: u16 = 3082;
    pub const FALSE_NORTHING: u16 = 3083;
    pub const CENTER_LONG: u16 = 3088;
    pub const CENTER_LAT: u16 = 3089;
    pub const SCALE_AT_NAT_ORIGIN: u16 = 3092;
    pub const SCALE_AT_CENTER: u16 = 3093;
}

/// GeoKey "user-defined" value.
const USER_DEFINED: u16 = 32767;
/// GTModelType values.
const MODEL_PROJECTED: u16 = 1;
const MODEL_GEOGRAPHIC: u16 = 2;
/// ProjCoordTransGeoKey value for Transverse Mercator.
const CT_TRANSVERSE_MERCATOR: u16 = 1;

impl CrsDefinition {
    /// The CRS this definition describes.
    pub fn crs(&self) -> Crs {
        self.crs
    }

    /// The PROJ.4 string.
    pub fn proj_string(&self) -> &str {
        &self.proj
    }

    /// Whether coordinates are lon/lat degrees.
    pub fn is_geographic(&self) -> bool {
        self.crs.is_geographic()
    }

    /// A short label: `EPSG:<code>` where known, else the PROJ.4 string.
    pub fn label(&self) -> String {
        match self.crs.epsg() {
            Some(code) => format!("EPSG:{code}"),
            None => self.proj.clone(),
        }
    }

    /// WGS 84 longitude/latitude (EPSG:4326).
    pub fn wgs84() -> CrsDefinition {
        CrsDefinition { crs: Crs::Geographic { epsg: Some(4326) }, proj: WGS84_LONGLAT.to_string() }
    }

    /// The definition of an EPSG code from the supported families (see the module docs).
    pub fn from_epsg(code: u32) -> Result<CrsDefinition, ReprojectError> {
        let unsupported =
            |reason: &str| ReprojectError::Unsupported { crs: format!("EPSG:{code}"), reason: reason.into() };
        let geographic = |proj: String| CrsDefinition { crs: Crs::Geographic { epsg: Some(code) }, proj };
        let projected =
            |proj: String| CrsDefinition { crs: Crs::Projected { epsg: Some(code), unit_to_metre: 1.0 }, proj };
        let def = match code {
            4326 => geographic(WGS84_LONGLAT.to_string()),
            c if GRS80_GEOGRAPHIC.contains(&c) => geographic(format!("+proj=longlat {GRS80_AS_WGS84} +no_defs")),
            32601..=32660 => projected(format!("+proj=utm +zone={} +datum=WGS84 +units=m +no_defs", code - 32600)),
            32701..=32760 => {
                projected(format!("+proj=utm +zone={} +south +datum=WGS84 +units=m +no_defs", code - 32700))
            }
            26901..=26923 => projected(format!("+proj=utm +zone={} {GRS80_AS_WGS84} +units=m +no_defs", code - 26900)),
            25828..=25838 => projected(format!("+proj=utm +zone={} {GRS80_AS_WGS84} +units=m +no_defs", code - 25800)),
            5070 | 6350 => projected(format!(
                "+proj=aea +lat_0=23 +lon_0=-96 +lat_1=29.5 +lat_2=45.5 +x_0=0 +y_0=0 {GRS80_AS_WGS84} +units=m +no_defs"
            )),
            3035 => projected(format!(
                "+proj=laea +lat_0=52 +lon_0=10 +x_0=4321000 +y_0=3210000 {GRS80_AS_WGS84} +units=m +no_defs"
            )),
            4267 | 4230 | 4277 | 4322 | 26701..=26722 | 23028..=23038 | 27700 => {
                return Err(unsupported("its datum needs a shift to WGS 84 that is not built in"));
            }
            _ => {
                return Err(unsupported(
                    "not in the built-in table (geographic 4326, 4269, 4258, …; WGS 84 UTM 326xx/327xx, \
                     NAD83 UTM 269xx, ETRS89 UTM 258xx, 5070, 3035)",
                ));
            }
        };
        def.validated()
    }

    /// The definition of a [`Crs`]: from its EPSG code. A CRS without code cannot be
    /// transformed on its own ([`ReprojectError::Unsupported`]; read its GeoKeys or give a
    /// PROJ.4 string instead), an unspecified one gives [`ReprojectError::Missing`].
    pub fn from_crs(crs: &Crs) -> Result<CrsDefinition, ReprojectError> {
        match crs {
            Crs::Unspecified => Err(ReprojectError::Missing),
            c => match c.epsg() {
                Some(code) => CrsDefinition::from_epsg(code),
                None => Err(ReprojectError::Unsupported {
                    crs: c.to_string(),
                    reason: "a CRS without EPSG code needs its full definition (GeoKeys or a PROJ.4 string)".into(),
                }),
            },
        }
    }

    /// A PROJ.4 string such as `+proj=utm +zone=13 +datum=WGS84`. Geographic definitions
    /// (`+proj=longlat`/`latlong`) give [`Crs::Geographic`], others [`Crs::Projected`] with the
    /// string's unit.
    pub fn from_proj_string(text: &str) -> Result<CrsDefinition, ReprojectError> {
        let text = text.trim();
        let proj = parse_proj(text)?;
        let crs = if proj.is_latlong() {
            Crs::Geographic { epsg: None }
        } else {
            Crs::Projected { epsg: None, unit_to_metre: proj.to_meter() }
        };
        Ok(CrsDefinition { crs, proj: text.to_string() })
    }

    /// Parses what a user may give as a CRS: `EPSG:<code>` or a PROJ.4 string starting with `+`.
    pub fn parse(text: &str) -> Result<CrsDefinition, ReprojectError> {
        let trimmed = text.trim();
        if trimmed.starts_with('+') {
            return CrsDefinition::from_proj_string(trimmed);
        }
        let code = trimmed
            .split_once(':')
            .filter(|(auth, _)| auth.trim().eq_ignore_ascii_case("EPSG"))
            .and_then(|(_, code)| code.trim().parse::<u32>().ok())
            .ok_or_else(|| ReprojectError::Unsupported {
                crs: trimmed.to_string(),
                reason: "expected EPSG:<code> or a PROJ.4 string starting with '+'".into(),
            })?;
        CrsDefinition::from_epsg(code)
    }

    /// The CRS described by GeoTIFF GeoKeys: an EPSG code where present, otherwise a
    /// user-defined geographic CRS or UTM / Transverse Mercator projection with its ellipsoid
    /// (EPSG ellipsoid code or semi-major axis with inverse flattening or semi-minor axis),
    /// TOWGS84 if given (else the datum is taken as WGS 84) and linear unit. `Ok(None)` when
    /// the keys describe no CRS.
    pub fn from_geokeys(keys: &GeoKeyValues) -> Result<Option<CrsDefinition>, ReprojectError> {
        let code = |id| keys.short(id).filter(|&c| c != 0 && c != USER_DEFINED).map(u32::from);
        let model = match keys.short(key::MODEL_TYPE) {
            Some(m) => m,
            None if keys.short(key::PROJECTED_CS_TYPE).is_some() => MODEL_PROJECTED,
            None if keys.short(key::GEOGRAPHIC_TYPE).is_some() => MODEL_GEOGRAPHIC,
            None => return Ok(None),
        };
        let unsupported = |reason: String| ReprojectError::Unsupported { crs: "user-defined GeoKeys".into(), reason };
        match model {
            MODEL_GEOGRAPHIC => {
                if let Some(code) = code(key::GEOGRAPHIC_TYPE) {
                    return CrsDefinition::from_epsg(code).map(Some);
                }
                let datum = geokey_datum(keys).map_err(unsupported)?;
                let proj = format!("+proj=longlat {datum} +no_defs");
                Some(CrsDefinition { crs: Crs::Geographic { epsg: None }, proj }.validated()).transpose()
            }
            MODEL_PROJECTED => {
                if let Some(code) = code(key::PROJECTED_CS_TYPE) {
                    return CrsDefinition::from_epsg(code).map(Some);
                }
                let datum = geokey_datum(keys).map_err(unsupported)?;
                let (units, unit_to_metre) = geokey_units(keys).map_err(unsupported)?;
                let projection = match keys.short(key::PROJECTION) {
                    // EPSG conversion codes 16001–16060 / 16101–16160: UTM zone n N / S.
                    Some(c @ 16001..=16060) => format!("+proj=utm +zone={}", c - 16000),
                    Some(c @ 16101..=16160) => format!("+proj=utm +zone={} +south", c - 16100),
                    _ => match keys.short(key::COORD_TRANS) {
                        Some(CT_TRANSVERSE_MERCATOR) => transverse_mercator(keys).map_err(unsupported)?,
                        Some(other) => {
                            return Err(unsupported(format!(
                                "coordinate transformation {other} is not supported (only Transverse Mercator / UTM)"
                            )));
                        }
                        None => {
                            return Err(unsupported(
                                "projected CRS without EPSG code, UTM ProjectionGeoKey or ProjCoordTransGeoKey".into(),
                            ));
                        }
                    },
                };
                let proj = format!("{projection} {datum} {units} +no_defs");
                Some(CrsDefinition { crs: Crs::Projected { epsg: None, unit_to_metre }, proj }.validated()).transpose()
            }
            other => Err(unsupported(format!("model type {other} is not supported"))),
        }
    }

    /// Checks that `proj4rs` accepts the definition.
    fn validated(self) -> Result<CrsDefinition, ReprojectError> {
        parse_proj(&self.proj)?;
        Ok(self)
    }
}

/// `proj4rs` parse with its error mapped.
fn parse_proj(text: &str) -> Result<Proj, ReprojectError> {
    Proj::from_proj_string(text)
        .map_err(|e| ReprojectError::Invalid { definition: text.to_string(), message: e.to_string() })
}

/// The `+ellps`/`+a +rf`/`+a +b` and `+towgs84` terms of user-defined GeoKeys.
fn geokey_datum(keys: &GeoKeyValues) -> Result<String, String> {
    let ellipsoid = match keys.short(key::ELLIPSOID) {
        Some(7030) => "+ellps=WGS84".to_string(),
        Some(7019) => "+ellps=GRS80".to_string(),
        Some(7043) => "+ellps=WGS72".to_string(),
        Some(USER_DEFINED) | None => {
            match (
                keys.double(key::SEMI_MAJOR_AXIS),
                keys.double(key::INV_FLATTENING),
                keys.double(key::SEMI_MINOR_AXIS),
            ) {
                (Some(a), Some(rf), _) if a > 0.0 && rf > 0.0 => format!("+a={a} +rf={rf}"),
                (Some(a), _, Some(b)) if a > 0.0 && b > 0.0 => format!("+a={a} +b={b}"),
                _ => match keys.short(key::GEODETIC_DATUM) {
                    Some(6326) | None => "+ellps=WGS84".to_string(),
                    Some(6269 | 6258 | 6283 | 6140 | 6674 | 1116 | 1165) => "+ellps=GRS80".to_string(),
                    Some(other) => return Err(format!("geodetic datum {other} is not supported")),
                },
            }
        }
        Some(other) => {
            return Err(format!("ellipsoid {other} is not supported (WGS 84, GRS 80, WGS 72 or user-defined)"));
        }
    };
    let towgs84 = match keys.doubles(key::TOWGS84) {
        Some(p) if p.len() == 3 || p.len() == 7 => p.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(","),
        Some(p) => return Err(format!("GeogTOWGS84GeoKey has {} values, not 3 or 7", p.len())),
        None => "0,0,0,0,0,0,0".to_string(),
    };
    Ok(format!("{ellipsoid} +towgs84={towgs84}"))
}

/// The `+units`/`+to_meter` term and metres per unit of projected GeoKeys.
fn geokey_units(keys: &GeoKeyValues) -> Result<(String, f64), String> {
    Ok(match keys.short(key::LINEAR_UNITS) {
        None | Some(9001) => ("+units=m".into(), 1.0),
        Some(9002) => ("+units=ft".into(), super::crs::FOOT),
        Some(9003) => ("+units=us-ft".into(), super::crs::US_SURVEY_FOOT),
        Some(9036) => ("+units=km".into(), 1000.0),
        Some(USER_DEFINED) => {
            let size = keys
                .double(key::LINEAR_UNIT_SIZE)
                .filter(|s| s.is_finite() && *s > 0.0)
                .ok_or("user-defined linear unit without a valid ProjLinearUnitSizeGeoKey")?;
            (format!("+to_meter={size}"), size)
        }
        Some(other) => return Err(format!("linear unit {other} is not supported")),
    })
}

/// `+proj=tmerc …` from the Transverse Mercator GeoKeys (angles in degrees, offsets in the
/// CRS's linear unit as GeoTIFF stores them, converted to metres as PROJ expects).
fn transverse_mercator(keys: &GeoKeyValues) -> Result<String, String> {
    let lon0 = keys.double(key::NAT_ORIGIN_LONG).or_else(|| keys.double(key::CENTER_LONG)).unwrap_or(0.0);
    let lat0 = keys.double(key::NAT_ORIGIN_LAT).or_else(|| keys.double(key::CENTER_LAT)).unwrap_or(0.0);
    let k0 = keys.double(key::SCALE_AT_NAT_ORIGIN).or_else(|| keys.double(key::SCALE_AT_CENTER)).unwrap_or(1.0);
    let (_, unit) = geokey_units(keys)?;
    let x0 = keys.double(key::FALSE_EASTING).unwrap_or(0.0) * unit;
    let y0 = keys.double(key::FALSE_NORTHING).unwrap_or(0.0) * unit;
    if ![lon0, lat0, k0, x0, y0].iter().all(|v| v.is_finite()) || k0 <= 0.0 {
        return Err("Transverse Mercator parameters are not finite".into());
    }
    Ok(format!("+proj=tmerc +lat_0={lat0} +lon_0={lon0} +k={k0} +x_0={x0} +y_0={y0}"))
}

/// Transforms points from one CRS to another (degrees for geographic CRSs, CRS units for
/// projected ones). Between equal definitions it is the identity and never fails.
#[derive(Debug)]
pub struct Transformer {
    /// `None` for the identity.
    projs: Option<(Proj, Proj)>,
    src_geographic: bool,
    dst_geographic: bool,
}

impl Transformer {
    /// A transformer from `src` to `dst`.
    pub fn new(src: &CrsDefinition, dst: &CrsDefinition) -> Result<Transformer, ReprojectError> {
        let projs = if src.proj == dst.proj { None } else { Some((parse_proj(&src.proj)?, parse_proj(&dst.proj)?)) };
        Ok(Transformer { projs, src_geographic: src.is_geographic(), dst_geographic: dst.is_geographic() })
    }

    /// Whether the transformation is the identity.
    pub fn is_identity(&self) -> bool {
        self.projs.is_none()
    }

    /// The point `(x, y)` of the source CRS in the target CRS; `None` if it cannot be
    /// transformed (outside the projection's domain, non-finite input).
    pub fn transform(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        if !x.is_finite() || !y.is_finite() {
            return None;
        }
        let Some((src, dst)) = &self.projs else {
            return Some((x, y));
        };
        let mut p = if self.src_geographic { (x.to_radians(), y.to_radians(), 0.0) } else { (x, y, 0.0) };
        proj4rs::transform::transform(src, dst, &mut p).ok()?;
        let (ox, oy) = if self.dst_geographic { (p.0.to_degrees(), p.1.to_degrees()) } else { (p.0, p.1) };
        (ox.is_finite() && oy.is_finite()).then_some((ox, oy))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(shorts: &[(u16, u16)], doubles: &[(u16, &[f64])]) -> GeoKeyValues {
        GeoKeyValues { shorts: shorts.to_vec(), doubles: doubles.iter().map(|(k, v)| (*k, v.to_vec())).collect() }
    }

    #[test]
    fn epsg_families() {
        assert!(CrsDefinition::from_epsg(4326).unwrap().is_geographic());
        assert!(CrsDefinition::from_epsg(4269).unwrap().proj_string().contains("GRS80"));
        assert!(CrsDefinition::from_epsg(32613).unwrap().proj_string().contains("+zone=13 "));
        assert!(CrsDefinition::from_epsg(32733).unwrap().proj_string().contains("+south"));
        assert!(CrsDefinition::from_epsg(26912).unwrap().proj_string().contains("+zone=12 "));
        assert_eq!(CrsDefinition::from_epsg(32612).unwrap().label(), "EPSG:32612");
        for bad in [4267, 27700, 3857, 0] {
            assert!(matches!(CrsDefinition::from_epsg(bad), Err(ReprojectError::Unsupported { .. })), "{bad}");
        }
        assert_eq!(CrsDefinition::from_crs(&Crs::Unspecified), Err(ReprojectError::Missing));
        assert!(CrsDefinition::from_crs(&Crs::Projected { epsg: None, unit_to_metre: 1.0 }).is_err());
    }

    #[test]
    fn parse_user_strings() {
        assert_eq!(CrsDefinition::parse(" epsg:32613 ").unwrap().crs().epsg(), Some(32613));
        let d = CrsDefinition::parse("+proj=utm +zone=13 +datum=WGS84 +units=us-ft").unwrap();
        assert!(
            matches!(d.crs(), Crs::Projected { epsg: None, unit_to_metre } if (unit_to_metre - 0.3048006).abs() < 1e-6)
        );
        assert!(CrsDefinition::parse("+proj=longlat +datum=WGS84").unwrap().is_geographic());
        assert!(matches!(CrsDefinition::parse("+proj=nonsense"), Err(ReprojectError::Invalid { .. })));
        assert!(matches!(CrsDefinition::parse("WGS84"), Err(ReprojectError::Unsupported { .. })));
    }

    #[test]
    fn identity_and_round_trip() {
        let wgs = CrsDefinition::wgs84();
        let utm = CrsDefinition::from_epsg(32613).unwrap();
        assert!(Transformer::new(&wgs, &wgs).unwrap().is_identity());
        let fwd = Transformer::new(&wgs, &utm).unwrap();
        let back = Transformer::new(&utm, &wgs).unwrap();
        let (x, y) = fwd.transform(-105.45, 40.15).unwrap();
        let (lon, lat) = back.transform(x, y).unwrap();
        assert!((lon + 105.45).abs() < 1e-9 && (lat - 40.15).abs() < 1e-9);
        assert_eq!(fwd.transform(f64::NAN, 0.0), None);
    }

    #[test]
    fn user_defined_utm_geokeys() {
        // As in NLCD files: UTM zone 12N by ProjectionGeoKey, GRS 80 given by its axes.
        let k = keys(
            &[(1024, 1), (2048, 32767), (2050, 32767), (2056, 32767), (3072, 32767), (3074, 16012), (3076, 9001)],
            &[(2057, &[6378137.0]), (2059, &[298.257222101]), (2062, &[0.0, 0.0, 0.0])],
        );
        let d = CrsDefinition::from_geokeys(&k).unwrap().unwrap();
        assert_eq!(d.crs(), Crs::Projected { epsg: None, unit_to_metre: 1.0 });
        assert!(d.proj_string().starts_with("+proj=utm +zone=12 +a=6378137 +rf=298.257222101"), "{}", d.proj_string());
        // Explicit Transverse Mercator parameters equal to UTM 12N give the same coordinates.
        let tm = keys(
            &[(1024, 1), (3072, 32767), (3074, 32767), (3075, 1), (2056, 7019)],
            &[(3080, &[-111.0]), (3081, &[0.0]), (3082, &[500000.0]), (3083, &[0.0]), (3092, &[0.9996])],
        );
        let t = CrsDefinition::from_geokeys(&tm).unwrap().unwrap();
        let wgs = CrsDefinition::wgs84();
        let a = Transformer::new(&d, &wgs).unwrap().transform(320000.0, 4130000.0).unwrap();
        let b = Transformer::new(&t, &wgs).unwrap().transform(320000.0, 4130000.0).unwrap();
        assert!((a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9, "{a:?} {b:?}");
        let lcc = keys(&[(1024, 1), (3072, 32767), (3075, 8)], &[]);
        assert!(matches!(CrsDefinition::from_geokeys(&lcc), Err(ReprojectError::Unsupported { .. })));
        assert_eq!(CrsDefinition::from_geokeys(&keys(&[], &[])), Ok(None));
        let geo = keys(&[(1024, 2), (2048, 4326)], &[]);
        assert_eq!(CrsDefinition::from_geokeys(&geo).unwrap(), Some(CrsDefinition::wgs84()));
    }
}
