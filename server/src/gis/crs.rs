//! Coordinate reference systems, as far as the scene needs them: geographic (lon/lat degrees)
//! or projected (planar, with a linear unit), optionally with an EPSG code.
//!
//! This is not a projection library: a `Crs` only says whether raster coordinates are degrees
//! or linear units (and which unit), which is what the local metric frame
//! ([`crate::gis::LocalFrame`]) needs. Reprojection between CRSs uses the full definitions of
//! [`crate::gis::reproject`].

use std::fmt;
use std::str::FromStr;

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

/// EPSG codes of geographic 2D CRSs the crate knows (datum differences are irrelevant for a
/// local frame, which always uses the WGS 84 ellipsoid).
const GEOGRAPHIC_EPSG: &[u32] = &[
    4326, // WGS 84
    4269, // NAD83
    4258, // ETRS89
    4267, // NAD27
    4283, // GDA94
    7844, // GDA2020
    4617, // NAD83(CSRS)
    6318, // NAD83(2011)
    4674, // SIRGAS 2000
    4322, // WGS 72
    4277, // OSGB36
    4230, // ED50
    4612, // JGD2000
    6668, // JGD2011
    4490, // CGCS2000
    4167, // NZGD2000
];

/// Ranges of EPSG codes of projected CRSs in metres the crate knows.
const PROJECTED_METRE_EPSG: &[(u32, u32)] = &[
    (32601, 32660), // WGS 84 / UTM zones 1N–60N
    (32701, 32760), // WGS 84 / UTM zones 1S–60S
    (26901, 26923), // NAD83 / UTM zones 1N–23N
    (26701, 26722), // NAD27 / UTM zones 1N–22N
    (25828, 25838), // ETRS89 / UTM zones 28N–38N
    (23028, 23038), // ED50 / UTM zones 28N–38N
    (28348, 28358), // GDA94 / MGA zones 48–58
    (7846, 7859),   // GDA2020 / MGA zones 46–59
    (5070, 5070),   // NAD83 / Conus Albers
    (6350, 6350),   // NAD83(2011) / Conus Albers
    (3035, 3035),   // ETRS89-extended / LAEA Europe
    (3034, 3034),   // ETRS89-extended / LCC Europe
    (27700, 27700), // OSGB36 / British National Grid
    (2056, 2056),   // CH1903+ / LV95
    (21781, 21781), // CH1903 / LV03
    (28992, 28992), // Amersfoort / RD New
    (2154, 2154),   // RGF93 / Lambert-93
    (31467, 31467), // DHDN / 3-degree Gauss-Kruger zone 3
    (3006, 3006),   // SWEREF99 TM
    (3067, 3067),   // ETRS89 / TM35FIN
    (2193, 2193),   // NZGD2000 / New Zealand Transverse Mercator
    (3577, 3577),   // GDA94 / Australian Albers
];

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

    /// The CRS of an EPSG code from the built-in table, `None` if the code is unknown.
    pub fn from_epsg(code: u32) -> Option<Crs> {
        if GEOGRAPHIC_EPSG.contains(&code) {
            Some(Crs::Geographic { epsg: Some(code) })
        } else if PROJECTED_METRE_EPSG.iter().any(|&(lo, hi)| (lo..=hi).contains(&code)) {
            Some(Crs::Projected { epsg: Some(code), unit_to_metre: 1.0 })
        } else {
            None
        }
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
            let epsg = wkt_epsg(node).or_else(|| is_wgs84(node).then_some(4326));
            Some(Crs::Geographic { epsg })
        }
        "PROJCS" | "PROJCRS" | "PROJECTEDCRS" => {
            Some(Crs::Projected { epsg: wkt_epsg(node), unit_to_metre: wkt_length_unit(node).unwrap_or(1.0) })
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

impl FromStr for Crs {
    type Err = GisError;

    /// Parses `EPSG:<code>` (case-insensitive) for the codes in the built-in table.
    fn from_str(s: &str) -> Result<Crs, GisError> {
        let unknown = |reason: &str| GisError::UnknownCrs { crs: s.to_string(), reason: reason.to_string() };
        let trimmed = s.trim();
        let (authority, code) =
            trimmed.split_once(':').ok_or_else(|| unknown("expected EPSG:<code>, e.g. EPSG:4326"))?;
        if !authority.trim().eq_ignore_ascii_case("EPSG") {
            return Err(unknown("only EPSG codes are supported, e.g. EPSG:4326"));
        }
        let code: u32 = code.trim().parse().map_err(|_| unknown("the EPSG code is not a number"))?;
        Crs::from_epsg(code).ok_or_else(|| {
            unknown(
                "EPSG code not in the built-in table (geographic: 4326, 4269, 4258, …; projected \
                 in metres: UTM 326xx/327xx, NAD83 UTM 269xx, ETRS89 UTM 258xx, 5070, 3035, …)",
            )
        })
    }
}

impl fmt::Display for Crs {
    /// `EPSG:<code>` where known, otherwise a short description.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Crs::Geographic { epsg: Some(code) } | Crs::Projected { epsg: Some(code), .. } => {
                write!(f, "EPSG:{code}")
            }
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
        for bad in ["EPSG:3857", "EPSG:abc", "4326", "ESRI:102003", ""] {
            let err = bad.parse::<Crs>().unwrap_err();
            assert!(matches!(err, GisError::UnknownCrs { .. }), "{bad}: {err}");
        }
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
        assert_eq!(Crs::from_wkt(nad83), Some(Crs::Geographic { epsg: None }));
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
