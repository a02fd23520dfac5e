//! Coordinate reference systems, as far as the scene needs them: geographic (lon/lat degrees)
//! or projected (planar, with a linear unit), optionally with an EPSG code.
//!
//! This is not a projection library: a `Crs` only says whether raster coordinates are degrees
//! or linear units (and which unit), which is what the local metric frame
//! ([`crate::gis::LocalFrame`]) needs. Reprojection between CRSs uses the full definitions of
//! [`crate::gis::reproject`].

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;
use std::sync::OnceLock;

use super::error::GisError;

/// The CRS of a raster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Crs {
    /// Longitude/latitude in degrees (x = lon, y = lat).
    Geographic {
        /// EPSG code of the geographic CRS, if known (e.g. 4326 for WGS 84).
        epsg: Option<u32>,
    },
    /// Planar coordinates (e.g. UTM) in a linear unit.
    Projected {
        /// EPSG code, or `None` for user-defined CRSs (GeoKeys or WKT without authority).
        epsg: Option<u32>,
        /// Length of one CRS unit in metres (1 for metres, 0.3048 for feet).
        unit_to_metre: f64,
    },
    /// Nothing is known about the CRS.
    Unspecified,
}

/// International foot in metres (EPSG unit 9002).
pub const FOOT: f64 = 0.3048;
/// US survey foot in metres (EPSG unit 9003).
pub const US_SURVEY_FOOT: f64 = 1200.0 / 3937.0;

/// One EPSG code of the maintained table (the `crs-definitions` crate, generated from the
/// EPSG database via PROJ): the [`Crs`] it is, its PROJ string and its EPSG name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EpsgEntry {
    /// Geographic or projected, with the code and the linear unit.
    pub crs: Crs,
    /// The PROJ.4 definition (datum shift as `+towgs84`, `+datum` or `+nadgrids`).
    pub proj: &'static str,
    /// The EPSG name, e.g. `CH1903+ / LV95`.
    pub name: &'static str,
}

/// The table entry of an EPSG code; `None` for codes the table does not hold and for CRSs
/// that are neither geographic 2D nor projected (geocentric, vertical).
pub fn epsg_entry(code: u32) -> Option<EpsgEntry> {
    let def = crs_definitions::from_code(u16::try_from(code).ok()?)?;
    let proj = def.proj4;
    let term = |key: &str| proj.split_whitespace().find_map(|t| t.strip_prefix(key));
    let crs = match term("+proj=")? {
        "longlat" | "latlong" | "lonlat" | "latlon" => Crs::Geographic { epsg: Some(code) },
        "geocent" => return None,
        _ => {
            let unit_to_metre = match (term("+units="), term("+to_meter=")) {
                (_, Some(f)) => f.parse().ok().filter(|f: &f64| f.is_finite() && *f > 0.0)?,
                (Some("m") | None, None) => 1.0,
                (Some("ft"), None) => FOOT,
                (Some("us-ft"), None) => US_SURVEY_FOOT,
                (Some("km"), None) => 1000.0,
                (Some(_), None) => return None,
            };
            Crs::Projected { epsg: Some(code), unit_to_metre }
        }
    };
    // The WKT starts `PROJCS["name",…` or `GEOGCS["name",…`.
    let name = def.wkt.split('"').nth(1).unwrap_or("");
    Some(EpsgEntry { crs, proj, name })
}

/// Squeezes a CRS name for comparison: lower-case letters and digits only, with 4-digit years
/// `19xx` shortened to `xx`, so that the ESRI `OSGB_1936_British_National_Grid` and the EPSG
/// `OSGB 1936 / British National Grid` compare equal.
fn squeeze_name(name: &str) -> String {
    let mut out = String::new();
    for part in name.split(|c: char| !c.is_ascii_alphanumeric()).filter(|p| !p.is_empty()) {
        let part = part.to_ascii_lowercase();
        match part.strip_prefix("19") {
            Some(yy) if yy.len() == 2 && yy.bytes().all(|b| b.is_ascii_digit()) => out.push_str(yy),
            _ => out.push_str(&part),
        }
    }
    out
}

/// The EPSG code whose name matches `name` (after [`squeeze_name`]; ESRI prefixes `GCS_` and
/// `D_` ignored); `None` when no or more than one code matches. Used for WKT without an
/// authority, as ESRI `.prj` files and many GeoTIFF citations are.
pub fn epsg_by_name(name: &str, geographic: bool) -> Option<u32> {
    let wanted = squeeze_name(name.trim_start_matches("GCS_"));
    if wanted.is_empty() {
        return None;
    }
    epsg_names().get(&(wanted, geographic)).copied().flatten()
}

/// Every EPSG code of the table by its squeezed name and whether it is geographic; `None` for
/// a name more than one code has. Built once (reading the whole table takes a fifth of a
/// second, too long for every upload whose CRS is named without an authority).
fn epsg_names() -> &'static HashMap<(String, bool), Option<u32>> {
    static NAMES: OnceLock<HashMap<(String, bool), Option<u32>>> = OnceLock::new();
    NAMES.get_or_init(|| {
        let mut names = HashMap::new();
        for code in 2000..=u32::from(u16::MAX) {
            let Some(entry) = epsg_entry(code) else { continue };
            names
                .entry((squeeze_name(entry.name), entry.crs.is_geographic()))
                .and_modify(|found| *found = None)
                .or_insert(Some(code));
        }
        names
    })
}

impl Crs {
    /// Whether coordinates are lon/lat degrees.
    pub fn is_geographic(&self) -> bool {
        matches!(self, Crs::Geographic { .. })
    }

    /// The EPSG code, if any.
    pub fn epsg(&self) -> Option<u32> {
        match self {
            Crs::Geographic { epsg } | Crs::Projected { epsg, .. } => *epsg,
            Crs::Unspecified => None,
        }
    }

    /// The CRS of an EPSG code from the table ([`epsg_entry`]), `None` if the code is unknown.
    pub fn from_epsg(code: u32) -> Option<Crs> {
        epsg_entry(code).map(|e| e.crs)
    }

    /// The EPSG name of the CRS (e.g. `CH1903+ / LV95`), if it has a code in the table.
    pub fn name(&self) -> Option<&'static str> {
        self.epsg().and_then(epsg_entry).map(|e| e.name).filter(|n| !n.is_empty())
    }

    /// Interprets OGC WKT (WKT1, ESRI WKT or WKT2), as found in a `.prj` file. Returns `None`
    /// for text that is not WKT of a geographic or projected CRS.
    pub fn from_wkt(text: &str) -> Option<Crs> {
        let root = wkt::parse(text)?;
        crs_of_wkt_node(&root)
    }
}

/// The CRS described by a WKT node (recursing into compound and bound CRSs).
fn crs_of_wkt_node(node: &wkt::Node) -> Option<Crs> {
    match node.keyword.to_ascii_uppercase().as_str() {
        "GEOGCS" | "GEOGCRS" | "GEOGRAPHICCRS" => {
            let epsg = wkt_epsg(node)
                .or_else(|| is_wgs84(node).then_some(4326))
                .or_else(|| node.arg(0).and_then(|name| epsg_by_name(name, true)));
            Some(Crs::Geographic { epsg })
        }
        "PROJCS" | "PROJCRS" | "PROJECTEDCRS" => {
            let unit_to_metre = wkt_length_unit(node).unwrap_or(1.0);
            // Without an authority, the EPSG CRS of the same name and unit.
            let by_name = || {
                let code = epsg_by_name(node.arg(0)?, false)?;
                let same_unit = matches!(Crs::from_epsg(code), Some(Crs::Projected { unit_to_metre: u, .. })
                    if (u - unit_to_metre).abs() < 1e-9 * u);
                same_unit.then_some(code)
            };
            Some(Crs::Projected { epsg: wkt_epsg(node).or_else(by_name), unit_to_metre })
        }
        "COMPD_CS" | "COMPOUNDCRS" | "BOUNDCRS" | "SOURCECRS" => node.nodes().find_map(crs_of_wkt_node),
        _ => None,
    }
}

/// The EPSG code of a node's own `AUTHORITY["EPSG","n"]` / `ID["EPSG",n]` (not a nested one).
fn wkt_epsg(node: &wkt::Node) -> Option<u32> {
    node.nodes()
        .filter(|n| n.keyword.eq_ignore_ascii_case("AUTHORITY") || n.keyword.eq_ignore_ascii_case("ID"))
        .find(|n| n.arg(0).is_some_and(|a| a.eq_ignore_ascii_case("EPSG")))
        .and_then(|n| n.arg(1))
        .and_then(|code| code.trim().parse().ok())
}

/// Whether a geographic CRS node is WGS 84 by name or datum name.
fn is_wgs84(node: &wkt::Node) -> bool {
    let wgs84 = |name: &str| {
        let squeezed: String =
            name.chars().filter(|c| c.is_ascii_alphanumeric()).collect::<String>().to_ascii_uppercase();
        squeezed.contains("WGS84") || squeezed.contains("WGS1984")
    };
    node.arg(0).is_some_and(wgs84)
        || node.nodes().filter(|n| n.keyword.eq_ignore_ascii_case("DATUM")).any(|n| n.arg(0).is_some_and(wgs84))
}

/// The linear unit of a projected CRS node in metres: WKT1 `UNIT[name, factor]` directly in
/// the node, or WKT2 `LENGTHUNIT` directly in it or in its `CS`/`AXIS` entries.
fn wkt_length_unit(node: &wkt::Node) -> Option<f64> {
    let factor = |n: &wkt::Node| n.arg(1).and_then(|f| f.trim().parse::<f64>().ok());
    let is_unit =
        |n: &&wkt::Node| n.keyword.eq_ignore_ascii_case("UNIT") || n.keyword.eq_ignore_ascii_case("LENGTHUNIT");
    node.nodes()
        .filter(is_unit)
        .find_map(factor)
        .or_else(|| {
            node.nodes()
                .filter(|n| n.keyword.eq_ignore_ascii_case("AXIS"))
                .flat_map(|axis| axis.nodes())
                .filter(is_unit)
                .find_map(factor)
        })
        .filter(|f| f.is_finite() && *f > 0.0)
}

/// The EPSG code of a CRS name as users and files write it: `EPSG:2056` (also with the name
/// in brackets after it, as [`Crs`]'s `Display` writes it), the OGC URNs
/// `urn:ogc:def:crs:EPSG::2056` and `urn:ogc:def:crs:OGC:1.3:CRS84` (WGS 84, as GeoJSON's
/// `crs` member uses them). `Err` says what was expected.
pub fn parse_epsg_code(text: &str) -> Result<u32, &'static str> {
    let text = text.trim();
    let text = text.split_once('(').map_or(text, |(code, _)| code).trim();
    let lower = text.to_ascii_lowercase();
    if matches!(lower.as_str(), "crs84" | "ogc:crs84" | "urn:ogc:def:crs:ogc:1.3:crs84" | "urn:ogc:def:crs:ogc::crs84")
    {
        return Ok(4326);
    }
    let code = if let Some(rest) = lower.strip_prefix("urn:ogc:def:crs:epsg:") {
        // `urn:ogc:def:crs:EPSG::n` or with a version: `urn:ogc:def:crs:EPSG:9.8:n`.
        rest.rsplit(':').next().unwrap_or("")
    } else {
        match lower.split_once(':') {
            Some(("epsg", code)) => code,
            Some(_) => return Err("only EPSG codes are supported, e.g. EPSG:4326"),
            None => return Err("expected EPSG:<code>, e.g. EPSG:4326"),
        }
    };
    code.trim().parse().map_err(|_| "the EPSG code is not a number")
}

impl FromStr for Crs {
    type Err = GisError;

    /// Parses an EPSG code as [`parse_epsg_code`] reads it, for the codes of the EPSG table.
    fn from_str(s: &str) -> Result<Crs, GisError> {
        let unknown = |reason: &str| GisError::UnknownCrs { crs: s.to_string(), reason: reason.to_string() };
        let code = parse_epsg_code(s).map_err(unknown)?;
        Crs::from_epsg(code).ok_or_else(|| {
            unknown("no geographic or projected CRS of that code in the EPSG table; give a PROJ string instead")
        })
    }
}

impl fmt::Display for Crs {
    /// `EPSG:<code> (<name>)` where known, otherwise a short description.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Crs::Geographic { epsg: Some(code) } | Crs::Projected { epsg: Some(code), .. } => match self.name() {
                Some(name) => write!(f, "EPSG:{code} ({name})"),
                None => write!(f, "EPSG:{code}"),
            },
            Crs::Geographic { epsg: None } => write!(f, "geographic (no EPSG code)"),
            Crs::Projected { epsg: None, unit_to_metre } => {
                write!(f, "projected (no EPSG code, unit {unit_to_metre} m)")
            }
            Crs::Unspecified => write!(f, "unspecified"),
        }
    }
}

/// A minimal reader of the bracket structure of WKT: `KEYWORD[arg, "text", NODE[…], …]`.
mod wkt {
    /// One `KEYWORD[…]` element.
    #[derive(Debug, PartialEq)]
    pub struct Node {
        /// The keyword before the bracket.
        pub keyword: String,
        /// The bracketed items in order.
        pub items: Vec<Item>,
    }

    /// An item inside brackets.
    #[derive(Debug, PartialEq)]
    pub enum Item {
        /// A nested element.
        Node(Node),
        /// A quoted string, number or bare word.
        Value(String),
    }

    impl Node {
        /// The nested elements.
        pub fn nodes(&self) -> impl Iterator<Item = &Node> {
            self.items.iter().filter_map(|i| match i {
                Item::Node(n) => Some(n),
                Item::Value(_) => None,
            })
        }

        /// The `i`-th item if it is a value.
        pub fn arg(&self, i: usize) -> Option<&str> {
            match self.items.get(i)? {
                Item::Value(v) => Some(v),
                Item::Node(_) => None,
            }
        }
    }

    /// Parses the first WKT element of `text`; `None` if it is not well-formed.
    pub fn parse(text: &str) -> Option<Node> {
        let chars: Vec<char> = text.trim_start_matches('\u{feff}').chars().collect();
        let mut pos = 0;
        skip_ws(&chars, &mut pos);
        let node = parse_node(&chars, &mut pos, 0)?;
        Some(node)
    }

    /// Nesting limit, so hostile input cannot overflow the stack.
    const MAX_DEPTH: usize = 64;

    fn skip_ws(chars: &[char], pos: &mut usize) {
        while chars.get(*pos).is_some_and(|c| c.is_whitespace()) {
            *pos += 1;
        }
    }

    fn parse_word(chars: &[char], pos: &mut usize) -> String {
        let start = *pos;
        while chars.get(*pos).is_some_and(|&c| !matches!(c, '[' | ']' | '(' | ')' | ',' | '"') && !c.is_whitespace()) {
            *pos += 1;
        }
        chars[start..*pos].iter().collect()
    }

    fn parse_node(chars: &[char], pos: &mut usize, depth: usize) -> Option<Node> {
        if depth > MAX_DEPTH {
            return None;
        }
        let keyword = parse_word(chars, pos);
        if keyword.is_empty() || !keyword.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return None;
        }
        skip_ws(chars, pos);
        if !matches!(chars.get(*pos), Some('[' | '(')) {
            return None;
        }
        *pos += 1;
        let mut items = Vec::new();
        loop {
            skip_ws(chars, pos);
            match chars.get(*pos)? {
                ']' | ')' if items.is_empty() => {
                    *pos += 1;
                    break;
                }
                '"' => items.push(Item::Value(parse_quoted(chars, pos)?)),
                _ => {
                    let start = *pos;
                    let word = parse_word(chars, pos);
                    skip_ws(chars, pos);
                    if matches!(chars.get(*pos), Some('[' | '(')) {
                        *pos = start;
                        items.push(Item::Node(parse_node(chars, pos, depth + 1)?));
                    } else if word.is_empty() {
                        return None;
                    } else {
                        items.push(Item::Value(word));
                    }
                }
            }
            skip_ws(chars, pos);
            match chars.get(*pos)? {
                ',' => *pos += 1,
                ']' | ')' => {
                    *pos += 1;
                    break;
                }
                _ => return None,
            }
        }
        Some(Node { keyword, items })
    }

    /// A `"…"` string; `""` inside stands for one quote.
    fn parse_quoted(chars: &[char], pos: &mut usize) -> Option<String> {
        *pos += 1;
        let mut out = String::new();
        loop {
            match chars.get(*pos)? {
                '"' if chars.get(*pos + 1) == Some(&'"') => {
                    out.push('"');
                    *pos += 2;
                }
                '"' => {
                    *pos += 1;
                    return Some(out);
                }
                &c => {
                    out.push(c);
                    *pos += 1;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_epsg_strings() {
        assert_eq!("EPSG:4326".parse::<Crs>().unwrap(), Crs::Geographic { epsg: Some(4326) });
        assert_eq!(" epsg:26912 ".parse::<Crs>().unwrap(), Crs::Projected { epsg: Some(26912), unit_to_metre: 1.0 });
        assert_eq!("EPSG:32613".parse::<Crs>().unwrap(), Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 });
        assert!("EPSG:4269".parse::<Crs>().unwrap().is_geographic());
        assert!("EPSG:4258".parse::<Crs>().unwrap().is_geographic());
        assert_eq!("EPSG:3857".parse::<Crs>().unwrap(), Crs::Projected { epsg: Some(3857), unit_to_metre: 1.0 });
        assert_eq!("urn:ogc:def:crs:EPSG:9.8.15:2056".parse::<Crs>().unwrap().epsg(), Some(2056));
        for bad in ["EPSG:99999", "EPSG:4978", "EPSG:abc", "4326", "ESRI:102003", ""] {
            let err = bad.parse::<Crs>().unwrap_err();
            assert!(matches!(err, GisError::UnknownCrs { .. }), "{bad}: {err}");
        }
    }

    #[test]
    fn table_units_and_names() {
        let e = epsg_entry(2227).unwrap();
        assert_eq!(e.crs, Crs::Projected { epsg: Some(2227), unit_to_metre: US_SURVEY_FOOT });
        assert_eq!(epsg_entry(2056).unwrap().name, "CH1903+ / LV95");
        assert_eq!(Crs::from_epsg(4326).unwrap().name(), Some("WGS 84"));
        assert_eq!(squeeze_name("RGF_1993_Lambert_93"), squeeze_name("RGF93 / Lambert-93"));
        assert_eq!(epsg_by_name("CH1903+_LV95", false), Some(2056));
        assert_eq!(epsg_by_name("GCS_OSGB_1936", true), Some(4277));
        assert_eq!(epsg_by_name("no such CRS", false), None);
    }

    #[test]
    fn display_round_trips_epsg() {
        let crs: Crs = "EPSG:32613".parse().unwrap();
        assert_eq!(crs.to_string().parse::<Crs>().unwrap(), crs);
        assert_eq!(crs.epsg(), Some(32613));
        assert_eq!(Crs::Unspecified.epsg(), None);
    }

    #[test]
    fn esri_wkt_wgs84_without_authority_is_4326() {
        let wkt = r#"GEOGCS["GCS_WGS_1984",DATUM["D_WGS_1984",SPHEROID["WGS_1984",6378137.0,298.257223563]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]]"#;
        assert_eq!(Crs::from_wkt(wkt), Some(Crs::Geographic { epsg: Some(4326) }));
    }

    #[test]
    fn wkt1_with_authorities_uses_the_outermost() {
        let wkt = r#"PROJCS["NAD83 / UTM zone 12N",GEOGCS["NAD83",DATUM["North_American_Datum_1983",SPHEROID["GRS 1980",6378137,298.257222101,AUTHORITY["EPSG","7019"]],AUTHORITY["EPSG","6269"]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433],AUTHORITY["EPSG","4269"]],PROJECTION["Transverse_Mercator"],PARAMETER["central_meridian",-111],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AXIS["Easting",EAST],AUTHORITY["EPSG","26912"]]"#;
        assert_eq!(Crs::from_wkt(wkt), Some(Crs::Projected { epsg: Some(26912), unit_to_metre: 1.0 }));
        let nad83 = r#"GEOGCS["NAD83",DATUM["North_American_Datum_1983",SPHEROID["GRS 1980",6378137,298.257222101]],PRIMEM["Greenwich",0],UNIT["degree",0.0174532925199433]]"#;
        // Without an authority the EPSG name "NAD83" identifies EPSG:4269.
        assert_eq!(Crs::from_wkt(nad83), Some(Crs::Geographic { epsg: Some(4269) }));
    }

    #[test]
    fn esri_wkt_in_feet() {
        let wkt = r#"PROJCS["NAD_1983_StatePlane_California_III_FIPS_0403_Feet",GEOGCS["GCS_North_American_1983",DATUM["D_North_American_1983",SPHEROID["GRS_1980",6378137.0,298.257222101]],PRIMEM["Greenwich",0.0],UNIT["Degree",0.0174532925199433]],PROJECTION["Lambert_Conformal_Conic"],UNIT["Foot_US",0.3048006096012192]]"#;
        match Crs::from_wkt(wkt) {
            Some(Crs::Projected { epsg: None, unit_to_metre }) => {
                assert!((unit_to_metre - US_SURVEY_FOOT).abs() < 1e-12)
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn wkt2_projected_with_axis_units() {
        let wkt = r#"PROJCRS["NAD83 / UTM zone 12N",
            BASEGEOGCRS["NAD83",DATUM["North American Datum 1983",
                ELLIPSOID["GRS 1980",6378137,298.257222101,LENGTHUNIT["metre",1]]],
                ID["EPSG",4269]],
            CONVERSION["UTM zone 12N",METHOD["Transverse Mercator",ID["EPSG",9807]]],
            CS[Cartesian,2],
                AXIS["(E)",east,ORDER[1],LENGTHUNIT["foot",0.3048]],
                AXIS["(N)",north,ORDER[2],LENGTHUNIT["foot",0.3048]],
            USAGE[SCOPE["x"],BBOX[31.33,-114,84,-108]],
            ID["EPSG",26912]]"#;
        assert_eq!(Crs::from_wkt(wkt), Some(Crs::Projected { epsg: Some(26912), unit_to_metre: FOOT }));
    }

    #[test]
    fn non_wkt_is_none() {
        assert_eq!(Crs::from_wkt("Projection UTM\nZone 13\nUnits METERS"), None);
        assert_eq!(Crs::from_wkt(""), None);
        assert_eq!(Crs::from_wkt("GEOGCS[\"x\""), None);
        assert_eq!(Crs::from_wkt(&"A[".repeat(200)), None);
        assert_eq!(Crs::from_wkt(r#"VERT_CS["x",VERT_DATUM["y",2005]]"#), None);
    }
}
