//! Reprojection between CRSs with the pure-Rust `proj4rs` crate.
//!
//! [`Crs`] only says whether coordinates are degrees or linear units; to move coordinates from
//! one CRS to another a full definition is needed. A [`CrsDefinition`] is a PROJ.4 string plus
//! the [`Crs`] it describes, built from
//!
//! - an EPSG code ([`CrsDefinition::from_epsg`]): any geographic or projected CRS of the EPSG
//!   table ([`crate::gis::crs::epsg_entry`]);
//! - WKT ([`CrsDefinition::from_wkt`]) naming an EPSG CRS by authority or by name;
//! - GeoTIFF GeoKeys ([`CrsDefinition::from_geokeys`]): an EPSG code, a citation naming an EPSG
//!   CRS, or user-defined CRSs that describe a geographic CRS or a UTM / Transverse Mercator
//!   projection on a given ellipsoid;
//! - a PROJ.4 string given by the user ([`CrsDefinition::from_proj_string`]).
//!
//! Datum shifts are PROJ's for these definitions: the table's `+towgs84` Helmert parameters
//! (3 or 7), the built-in `+datum` parameters of `proj4rs` (OSGB36, potsdam …), none for datums
//! within a metre of WGS 84 (NAD83, ETRS89, GDA94 …). Helmert parameters are accurate to a few
//! metres at best (a national grid shift such as OSTN15 is better by two orders); definitions
//! that need a grid file (NAD27, NZGD49) give [`ReprojectError::Unsupported`] naming the grid.

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
    /// A raster could not be resampled from one CRS to another.
    #[error("cannot resample from {from} to {to}: {reason}")]
    Resample {
        /// Source CRS label.
        from: String,
        /// Target CRS label.
        to: String,
        /// Why.
        reason: String,
    },
    /// Data that lies entirely outside the scene.
    #[error("{what} does not overlap the scene (in {crs})")]
    NoOverlap {
        /// What does not overlap.
        what: String,
        /// The scene CRS label.
        crs: String,
    },
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

/// GeoKey ids (GeoTIFF 1.0) read here.
mod key {
    pub const MODEL_TYPE: u16 = 1024;
    pub const GT_CITATION: u16 = 1026;
    pub const GEOG_CITATION: u16 = 2049;
    pub const PCS_CITATION: u16 = 3073;
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

    /// A short identifier: `EPSG:<code>` where known, else the PROJ.4 string (metadata keep
    /// it; messages use `Display`, which adds the EPSG name).
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

    /// The definition of an EPSG code from the EPSG table ([`crate::gis::crs::epsg_entry`]),
    /// with its datum shift to WGS 84 as PROJ gives it (`+towgs84`, a `+datum` with built-in
    /// parameters or none). Codes whose shift needs a grid file (NAD27, NZGD49's NTv2 grid …)
    /// are refused: without the grid the error would be up to hundreds of metres.
    pub fn from_epsg(code: u32) -> Result<CrsDefinition, ReprojectError> {
        let label = || Crs::from_epsg(code).map_or_else(|| format!("EPSG:{code}"), |c| c.to_string());
        let unsupported = |reason: String| ReprojectError::Unsupported { crs: label(), reason };
        let entry = super::crs::epsg_entry(code).ok_or_else(|| {
            unsupported(
                "no geographic or projected CRS of that code in the EPSG table; give a PROJ string \
                 (+proj=…) instead"
                    .into(),
            )
        })?;
        if let Some(grids) = needs_grid(entry.proj) {
            return Err(unsupported(format!(
                "its shift to WGS 84 needs the grid file(s) {grids}, which are not available; give a PROJ \
                 string with +towgs84=… (accurate to metres) instead"
            )));
        }
        CrsDefinition { crs: entry.crs, proj: entry.proj.to_string() }.validated()
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

    /// Parses what a user may give as a CRS: an EPSG code as
    /// [`crate::gis::crs::parse_epsg_code`] reads it, a PROJ.4 string starting with `+`, or
    /// WKT (as in a `.prj` file) that names an EPSG CRS.
    ///
    /// WKT without an EPSG authority is matched by its name against the EPSG table.
    pub fn parse(text: &str) -> Result<CrsDefinition, ReprojectError> {
        let trimmed = text.trim();
        if trimmed.starts_with('+') {
            return CrsDefinition::from_proj_string(trimmed);
        }
        if trimmed.contains('[') {
            return CrsDefinition::from_wkt(trimmed);
        }
        let code = super::crs::parse_epsg_code(trimmed).map_err(|reason| ReprojectError::Unsupported {
            crs: trimmed.to_string(),
            reason: format!("{reason}, or a PROJ string starting with '+'"),
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
                if let Some(code) = code(key::GEOGRAPHIC_TYPE).or_else(|| cited_epsg(keys, true)) {
                    return CrsDefinition::from_epsg(code).map(Some);
                }
                let datum = geokey_datum(keys).map_err(unsupported)?;
                let proj = format!("+proj=longlat {datum} +no_defs");
                Some(CrsDefinition { crs: Crs::Geographic { epsg: None }, proj }.validated()).transpose()
            }
            MODEL_PROJECTED => {
                if let Some(code) = code(key::PROJECTED_CS_TYPE).or_else(|| cited_epsg(keys, false)) {
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

    /// The definition of WKT (WKT1, ESRI or WKT2, e.g. a `.prj` file): the EPSG CRS it names
    /// by authority or, lacking one, by name ([`Crs::from_wkt`]).
    pub fn from_wkt(text: &str) -> Result<CrsDefinition, ReprojectError> {
        let crs = Crs::from_wkt(text).ok_or_else(|| ReprojectError::Unsupported {
            crs: text.chars().take(60).collect(),
            reason: "not WKT of a geographic or projected CRS".into(),
        })?;
        CrsDefinition::from_crs(&crs)
    }

    /// Checks that `proj4rs` accepts the definition.
    fn validated(self) -> Result<CrsDefinition, ReprojectError> {
        parse_proj(&self.proj)?;
        Ok(self)
    }
}

/// The grid files a PROJ string's datum shift needs, `None` if it needs none (`@null` and
/// Helmert parameters need none; NAD27 stands for the NADCON/NTv2 grids).
fn needs_grid(proj: &str) -> Option<String> {
    proj.split_whitespace().find_map(|t| match t {
        "+datum=NAD27" => Some("NADCON/NTv2 (NAD27)".to_string()),
        t => t.strip_prefix("+nadgrids=").filter(|g| *g != "@null").map(str::to_string),
    })
}

impl std::fmt::Display for CrsDefinition {
    /// `EPSG:<code> (<name>)` where known, else the PROJ.4 string.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.crs.epsg() {
            Some(_) => write!(f, "{}", self.crs),
            None => f.write_str(&self.proj),
        }
    }
}

/// `proj4rs` parse with its error mapped.
fn parse_proj(text: &str) -> Result<Proj, ReprojectError> {
    Proj::from_proj_string(text)
        .map_err(|e| ReprojectError::Invalid { definition: text.to_string(), message: e.to_string() })
}

/// The EPSG code a user-defined CRS's citation names: WKT in it (GDAL writes
/// `ESRI PE String = PROJCS[…]`) or the plain name of an EPSG CRS (`PCSCitationGeoKey`,
/// `GeogCitationGeoKey`, else `GTCitationGeoKey`).
fn cited_epsg(keys: &GeoKeyValues, geographic: bool) -> Option<u32> {
    let own = if geographic { key::GEOG_CITATION } else { key::PCS_CITATION };
    [own, key::GT_CITATION].into_iter().filter_map(|id| keys.ascii(id)).find_map(|citation| match citation.find('[') {
        Some(_) => {
            let wkt = citation.find(|c: char| c.is_ascii_uppercase()).map_or(citation, |i| &citation[i..]);
            let wkt = wkt.split_once(" = ").map_or(wkt, |(_, w)| w);
            Crs::from_wkt(wkt).filter(|c| c.is_geographic() == geographic)?.epsg()
        }
        None => super::crs::epsg_by_name(citation, geographic),
    })
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
        GeoKeyValues {
            shorts: shorts.to_vec(),
            doubles: doubles.iter().map(|(k, v)| (*k, v.to_vec())).collect(),
            ascii: Vec::new(),
        }
    }

    #[test]
    fn epsg_families() {
        assert!(CrsDefinition::from_epsg(4326).unwrap().is_geographic());
        assert!(CrsDefinition::from_epsg(4269).unwrap().proj_string().contains("+datum=NAD83"));
        assert!(CrsDefinition::from_epsg(2056).unwrap().proj_string().contains("+towgs84=674.374"));
        assert!(CrsDefinition::from_epsg(32613).unwrap().proj_string().contains("+zone=13 "));
        assert!(CrsDefinition::from_epsg(32733).unwrap().proj_string().contains("+south"));
        assert!(CrsDefinition::from_epsg(26912).unwrap().proj_string().contains("+zone=12 "));
        assert_eq!(CrsDefinition::from_epsg(32612).unwrap().label(), "EPSG:32612");
        assert_eq!(CrsDefinition::from_epsg(32612).unwrap().to_string(), "EPSG:32612 (WGS 84 / UTM zone 12N)");
        assert!(needs_grid("+proj=utm +zone=12 +datum=NAD27").is_some());
        assert_eq!(needs_grid("+proj=merc +nadgrids=@null +no_defs"), None);
        assert_eq!(needs_grid("+proj=tmerc +nadgrids=nzgd2kgrid0005.gsb").as_deref(), Some("nzgd2kgrid0005.gsb"));
        for bad in [4267, 26712, 4978, 0, 70000] {
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
        // User-defined keys whose citation names an EPSG CRS, or holds its (ESRI) WKT.
        let mut cited = keys(&[(1024, 1), (3072, 32767)], &[]);
        cited.ascii = vec![(3073, "CH1903+ / LV95".into())];
        assert_eq!(CrsDefinition::from_geokeys(&cited).unwrap().unwrap().crs().epsg(), Some(2056));
        cited.ascii = vec![(1026, r#"ESRI PE String = PROJCS["OSGB_1936_British_National_Grid",GEOGCS["GCS_OSGB_1936",DATUM["D_OSGB_1936",SPHEROID["Airy_1830",6377563.396,299.3249646]],PRIMEM["Greenwich",0],UNIT["Degree",0.0174532925199433]],PROJECTION["Transverse_Mercator"],UNIT["Meter",1]]"#.into())];
        assert_eq!(CrsDefinition::from_geokeys(&cited).unwrap().unwrap().crs().epsg(), Some(27700));
    }
}
