//! ESRI ASCII grid (`.asc`) reader, with the CRS from a sibling `.prj` (WKT) if present.
//!
//! ```text
//! ncols        240
//! nrows        144
//! xllcorner    -105.550416666684      (or xllcenter)
//! yllcorner    40.090416666671        (or yllcenter)
//! cellsize     0.000833333333         (or dx / dy)
//! NODATA_value 0                      (optional)
//! 2569 2569 2573 …                    (nrows × ncols values, row 0 = north)
//! ```

use std::path::{Path, PathBuf};

use super::crs::Crs;
use super::error::GisError;
use super::raster::{self, GeoTransform, Raster};
use crate::echo::echo;

/// Header keys, lower case.
const KEYS: &[&str] =
    &["ncols", "nrows", "xllcorner", "xllcenter", "yllcorner", "yllcenter", "cellsize", "dx", "dy", "nodata_value"];

/// A header value with the line it came from.
#[derive(Debug, Clone, Copy)]
struct Entry {
    value: f64,
    line: usize,
}

/// Parsed header values, indexed like [`KEYS`].
#[derive(Debug, Default)]
struct Header {
    entries: [Option<Entry>; KEYS.len()],
}

impl Header {
    fn get(&self, key: &str) -> Option<Entry> {
        let i = KEYS.iter().position(|k| *k == key)?;
        self.entries[i]
    }
}

/// Reads an ESRI ASCII grid. Header keys are case-insensitive; the CRS comes from
/// `<name>.prj` next to the file (WKT), else it is [`Crs::Unspecified`].
pub fn read_ascii_grid(path: &Path) -> Result<Raster, GisError> {
    let bytes = std::fs::read(path).map_err(|source| GisError::Io { path: path.to_path_buf(), source })?;
    let text = String::from_utf8(bytes).map_err(|_| GisError::Format {
        path: path.to_path_buf(),
        message: "not an ASCII grid (the file is not text)".to_string(),
    })?;
    let mut raster = parse_ascii_grid(path, &text)?;
    raster.crs = read_prj(path)?;
    Ok(raster)
}

/// The lines of `text`, numbered from 1.
fn numbered_lines(text: &str) -> std::iter::Peekable<impl Iterator<Item = (usize, &str)>> {
    text.lines().enumerate().map(|(i, l)| (i + 1, l)).peekable()
}

/// Reads the header: `key value` lines (blank lines skipped, a byte-order mark before a key
/// ignored) until the first line that starts with a number. Returns the header and the
/// number of the first value line.
fn parse_header<'a>(
    path: &Path,
    text: &str,
    lines: &mut std::iter::Peekable<impl Iterator<Item = (usize, &'a str)>>,
) -> Result<(Header, usize), GisError> {
    let err = |line: usize, message: String| GisError::AsciiGrid { path: path.to_path_buf(), line, message };
    let mut header = Header::default();
    while let Some(&(line_no, line)) = lines.peek() {
        let mut tokens = line.split_whitespace();
        let Some(key) = tokens.next() else {
            lines.next();
            continue;
        };
        if key.parse::<f64>().is_ok() {
            break;
        }
        lines.next();
        let lower = key.trim_start_matches('\u{feff}').to_ascii_lowercase();
        let shown = echo(key);
        let index = KEYS
            .iter()
            .position(|k| *k == lower)
            .ok_or_else(|| err(line_no, format!("unknown header key \"{shown}\"")))?;
        let value = match (tokens.next(), tokens.next()) {
            (Some(v), None) => v,
            _ => {
                return Err(err(line_no, format!("header key \"{shown}\" needs exactly one value")));
            }
        };
        let value: f64 = value
            .parse()
            .ok()
            .filter(|v: &f64| v.is_finite())
            .ok_or_else(|| err(line_no, format!("\"{}\" is not a number for {shown}", echo(value))))?;
        if header.entries[index].is_some() {
            return Err(err(line_no, format!("header key \"{shown}\" appears twice")));
        }
        header.entries[index] = Some(Entry { value, line: line_no });
    }
    let header_end = lines.peek().map_or(text.lines().count() + 1, |&(n, _)| n);
    Ok((header, header_end))
}

/// The `ncols × nrows` an ASCII grid's header announces, read exactly as
/// [`parse_ascii_grid`] reads it (same keys, blank lines, byte-order marks and errors), so a
/// size limit can be checked before any value is decoded. Not checked against
/// [`raster::MAX_CELLS`].
pub fn ascii_grid_size(path: &Path, text: &str) -> Result<(u64, u64), GisError> {
    let mut lines = numbered_lines(text);
    let (header, header_end) = parse_header(path, text, &mut lines)?;
    Ok((count(path, &header, header_end, "ncols")?, count(path, &header, header_end, "nrows")?))
}

/// A positive integral header value (`ncols`, `nrows`); values past `u64::MAX` saturate.
fn count(path: &Path, header: &Header, header_end: usize, key: &str) -> Result<u64, GisError> {
    let err = |line: usize, message: String| GisError::AsciiGrid { path: path.to_path_buf(), line, message };
    let e = header.get(key).ok_or_else(|| err(header_end, format!("missing header key \"{key}\"")))?;
    if e.value < 1.0 || e.value.fract() != 0.0 {
        return Err(err(e.line, format!("{key} must be a positive integer, not {}", e.value)));
    }
    // A positive integral f64; values past u64::MAX saturate and fail the size check.
    Ok(e.value as u64)
}

/// Parses the text of an ASCII grid; the CRS is left [`Crs::Unspecified`].
pub fn parse_ascii_grid(path: &Path, text: &str) -> Result<Raster, GisError> {
    let err = |line: usize, message: String| GisError::AsciiGrid { path: path.to_path_buf(), line, message };
    let mut lines = numbered_lines(text);
    let (header, header_end) = parse_header(path, text, &mut lines)?;
    let (width, height, transform, nodata) = interpret_header(path, &header, header_end)?;

    // Values: whitespace-separated, any number per line.
    let expected = width * height;
    let mut data = Vec::with_capacity(expected);
    let mut last_line = header_end;
    for (line_no, line) in lines {
        last_line = line_no;
        for token in line.split_whitespace() {
            if data.len() == expected {
                return Err(err(line_no, format!("more than ncols × nrows = {width} × {height} = {expected} values")));
            }
            let v: f64 = token.parse().map_err(|_| err(line_no, format!("\"{}\" is not a number", echo(token))))?;
            if v.is_infinite() {
                return Err(err(line_no, format!("value \"{}\" is infinite", echo(token))));
            }
            data.push(v);
        }
    }
    if data.len() < expected {
        return Err(err(
            last_line,
            format!("file ends after {} of ncols × nrows = {width} × {height} = {expected} values", data.len()),
        ));
    }

    let raster = Raster { width, height, data, nodata, transform, crs: Crs::Unspecified, palette: None };
    raster::check_not_all_nodata(path, &raster)?;
    Ok(raster)
}

/// Checks the header and derives size, transform and nodata.
fn interpret_header(
    path: &Path,
    header: &Header,
    header_end: usize,
) -> Result<(usize, usize, GeoTransform, Option<f64>), GisError> {
    let err = |line: usize, message: String| GisError::AsciiGrid { path: path.to_path_buf(), line, message };
    // The entry of `a` or `b` (exactly one must be given), and whether it is `b`.
    let one_of = |a: &str, b: &str| match (header.get(a), header.get(b)) {
        (Some(e), None) => Ok((e, false)),
        (None, Some(e)) => Ok((e, true)),
        (Some(_), Some(e)) => Err(err(e.line, format!("both \"{a}\" and \"{b}\" given"))),
        (None, None) => Err(err(header_end, format!("missing header key \"{a}\" (or \"{b}\")"))),
    };
    let ncols = count(path, header, header_end, "ncols")?;
    let nrows = count(path, header, header_end, "nrows")?;
    raster::check_dimensions(path, ncols, nrows)?;
    // Both fit in MAX_CELLS, so they fit in usize.
    let (width, height) = (ncols as usize, nrows as usize);

    let (cell_width, cell_height) = match (header.get("cellsize"), header.get("dx"), header.get("dy")) {
        (Some(c), None, None) => ((c.value, c.line), (c.value, c.line)),
        (None, Some(dx), Some(dy)) => ((dx.value, dx.line), (dy.value, dy.line)),
        (Some(c), _, _) => {
            return Err(err(c.line, "both cellsize and dx/dy given".to_string()));
        }
        _ => {
            return Err(err(header_end, "missing header key \"cellsize\" (or \"dx\" and \"dy\")".to_string()));
        }
    };
    for (size, line) in [cell_width, cell_height] {
        if size <= 0.0 {
            return Err(err(line, format!("cell size must be positive, not {size}")));
        }
    }
    let (cell_width, cell_height) = (cell_width.0, cell_height.0);

    let (x, x_center) = one_of("xllcorner", "xllcenter")?;
    let (y, y_center) = one_of("yllcorner", "yllcenter")?;
    let left = if x_center { x.value - 0.5 * cell_width } else { x.value };
    let bottom = if y_center { y.value - 0.5 * cell_height } else { y.value };
    let transform =
        GeoTransform { origin_x: left, origin_y: bottom + height as f64 * cell_height, cell_width, cell_height };
    raster::check_transform(path, &transform)?;
    let nodata = header.get("nodata_value").map(|e| e.value);
    Ok((width, height, transform, nodata))
}

/// The CRS from `<name>.prj` (or `.PRJ`) next to `path`, [`Crs::Unspecified`] if there is
/// none or it is not recognisable WKT (then a warning is logged).
fn read_prj(path: &Path) -> Result<Crs, GisError> {
    let candidates: [PathBuf; 2] = [path.with_extension("prj"), path.with_extension("PRJ")];
    for prj in candidates {
        match std::fs::read(&prj) {
            Ok(bytes) => {
                let text = String::from_utf8_lossy(&bytes);
                return Ok(Crs::from_wkt(&text).unwrap_or_else(|| {
                    tracing::warn!("{}: not WKT of a geographic or projected CRS; CRS left unspecified", prj.display());
                    Crs::Unspecified
                }));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => continue,
            Err(source) => return Err(GisError::Io { path: prj, source }),
        }
    }
    Ok(Crs::Unspecified)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Raster, GisError> {
        parse_ascii_grid(Path::new("t.asc"), text)
    }

    #[test]
    fn corner_header() {
        let r = parse(
            "NCOLS 3\nNROWS 2\nXLLCORNER 10\nYLLCORNER 20\nCELLSIZE 5\nNODATA_VALUE -9999\n\
             1 2 3\n4 5 -9999\n",
        )
        .unwrap();
        assert_eq!((r.width, r.height), (3, 2));
        assert_eq!(r.transform, GeoTransform { origin_x: 10.0, origin_y: 30.0, cell_width: 5.0, cell_height: 5.0 });
        assert_eq!(r.get(2, 0), Some(3.0));
        assert_eq!(r.get(2, 1), None);
        assert_eq!(r.crs, Crs::Unspecified);
    }

    #[test]
    fn center_header_dx_dy_and_free_layout() {
        let r =
            parse("ncols 2\r\nnrows 2\r\nxllcenter 0.5\r\nyllcenter 1\r\ndx 1\r\ndy 2\r\n1 2 3\r\n\r\n4\r\n").unwrap();
        assert_eq!(r.transform, GeoTransform { origin_x: 0.0, origin_y: 4.0, cell_width: 1.0, cell_height: 2.0 });
        assert_eq!(r.data, vec![1.0, 2.0, 3.0, 4.0]);
        assert_eq!(r.nodata, None);
    }

    fn line_error(text: &str) -> (usize, String) {
        match parse(text) {
            Err(GisError::AsciiGrid { line, message, .. }) => (line, message),
            other => panic!("expected a line error, got {other:?}"),
        }
    }

    const HEAD: &str = "ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n";

    #[test]
    fn reports_lines() {
        assert_eq!(line_error(&format!("{HEAD}1 2\n3 x\n")).0, 7);
        assert_eq!(line_error(&format!("{HEAD}1 2\n3\n")).0, 7);
        assert_eq!(line_error(&format!("{HEAD}1 2\n3 4\n5\n")).0, 8);
        assert_eq!(line_error(&format!("{HEAD}1 2\n3 inf\n")).0, 7);
        assert_eq!(line_error("ncols 2\nfoo 3\n").0, 2);
        assert_eq!(line_error("ncols 2\nncols 3\n").0, 2);
        assert_eq!(line_error("ncols 2 3\n").0, 1);
        assert_eq!(line_error("ncols two\n").0, 1);
        let (line, msg) = line_error("ncols 2\nnrows 2\nxllcorner 0\ncellsize 1\n1 2 3 4\n");
        assert_eq!(line, 5);
        assert!(msg.contains("yllcorner"), "{msg}");
        assert_eq!(line_error("ncols 0\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n").0, 1);
        assert_eq!(line_error("ncols 2.5\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n").0, 1);
        assert_eq!(line_error("ncols 1\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize -1\n1\n").0, 5);
        assert_eq!(line_error("ncols 1\nnrows 1\nxllcorner 0\nxllcenter 0\nyllcorner 0\ncellsize 1\n1\n").0, 4);
    }

    #[test]
    fn too_large_and_all_nodata() {
        assert!(matches!(
            parse("ncols 100000\nnrows 100000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1\n"),
            Err(GisError::TooLarge { .. })
        ));
        assert!(matches!(parse(&format!("{HEAD}nodata_value 7\n7 7\n7 nan\n")), Err(GisError::AllNodata { .. })));
    }
}
