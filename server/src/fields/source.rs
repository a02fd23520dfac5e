//! Reading fields from files or uploaded bytes: GeoTIFF, ESRI ASCII grid and NetCDF-3, and a
//! series built from several timestamped rasters.
//!
//! GeoTIFF and ASCII grids go through the readers of [`crate::gis`] (GeoTIFF needs a file, so
//! uploaded bytes are written to a scratch file first); NetCDF-3 is read from memory by
//! [`super::netcdf`]. Before any decoding the announced grid size is checked against
//! [`LoadOptions::max_cells`], so a small compressed file cannot expand into gigabytes.

use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use serde::{Deserialize, Serialize};

use super::FieldError;
use super::field::{Field, FieldKind, FieldStep};
use super::series::parse_time;
use crate::gis::{self, CrsDefinition, ReprojectError};

/// The file formats a field can come in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FieldFormat {
    /// GeoTIFF (`.tif`, `.tiff`).
    GeoTiff,
    /// ESRI ASCII grid (`.asc`).
    AsciiGrid,
    /// NetCDF-3 classic or 64-bit offset (`.nc`).
    NetCdf,
    /// GeoJSON polygons with an integer label property, rasterized as a label field.
    GeoJson,
}

impl FieldFormat {
    /// Recognises a format by the first bytes (TIFF and NetCDF signatures, an ASCII grid
    /// header), falling back to the extension of `filename`. NetCDF-4/HDF5 is recognised and
    /// rejected with a message saying so.
    pub fn detect(bytes: &[u8], filename: Option<&str>) -> Result<FieldFormat, FieldError> {
        let head = bytes.get(..4).unwrap_or(bytes);
        if matches!(head, b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+") {
            return Ok(FieldFormat::GeoTiff);
        }
        if matches!(head, b"CDF\x01" | b"CDF\x02" | b"CDF\x05") {
            return Ok(FieldFormat::NetCdf);
        }
        let context = filename.unwrap_or("upload").to_string();
        if bytes.starts_with(b"\x89HDF\r\n\x1a\n") {
            return Err(FieldError::Format {
                context,
                message: "NetCDF-4/HDF5 is not supported; convert to NetCDF-3 (e.g. `nccopy -k classic`)".into(),
            });
        }
        let text_start = String::from_utf8_lossy(&bytes[..bytes.len().min(64)]).trim_start().to_ascii_lowercase();
        if ["ncols", "nrows"].iter().any(|k| text_start.starts_with(k)) {
            return Ok(FieldFormat::AsciiGrid);
        }
        if text_start.trim_start_matches('\u{feff}').starts_with('{') {
            return Ok(FieldFormat::GeoJson);
        }
        let ext = filename.and_then(|f| Path::new(f).extension()).and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        Err(FieldError::Format {
            context,
            message: match ext.as_deref() {
                Some("tif" | "tiff") => "not a TIFF file (bad signature)".into(),
                Some("nc") => "not a NetCDF-3 file (bad signature)".into(),
                Some("asc") => "not an ESRI ASCII grid (no ncols/nrows header)".into(),
                _ => "unknown format: expected GeoTIFF, ESRI ASCII grid (.asc), NetCDF-3 (.nc) or GeoJSON".into(),
            },
        })
    }

    /// The usual file extension.
    pub fn extension(&self) -> &'static str {
        match self {
            FieldFormat::GeoTiff => "tif",
            FieldFormat::AsciiGrid => "asc",
            FieldFormat::NetCdf => "nc",
            FieldFormat::GeoJson => "geojson",
        }
    }
}

/// How to read a field.
#[derive(Debug, Clone)]
pub struct LoadOptions {
    /// Scalar or label.
    pub kind: FieldKind,
    /// CRS to use instead of the file's (e.g. the scene's, for "assume scene CRS", or for an
    /// ASCII grid without `.prj`). `None`: the file's CRS, an error if it has none.
    pub crs: Option<CrsDefinition>,
    /// Time stamp (ISO 8601) of a single-grid file. NetCDF files with a time axis take their
    /// own times and reject this.
    pub time: Option<String>,
    /// NetCDF variable to read; may be left out when the file has one gridded variable.
    pub variable: Option<String>,
    /// Units of the values, overriding the file's (NetCDF `units`).
    pub units: Option<String>,
    /// Largest grid accepted per time step (width × height), checked before decoding.
    pub max_cells: u64,
    /// Most time steps accepted.
    pub max_steps: usize,
}

/// Default of [`LoadOptions::max_cells`]: 4096 × 4096 cells.
pub const DEFAULT_MAX_CELLS: u64 = 1 << 24;
/// Default of [`LoadOptions::max_steps`].
pub const DEFAULT_MAX_STEPS: usize = 1000;

impl LoadOptions {
    /// Options for a field of `kind` with the file's CRS and default limits.
    pub fn new(kind: FieldKind) -> LoadOptions {
        LoadOptions {
            kind,
            crs: None,
            time: None,
            variable: None,
            units: None,
            max_cells: DEFAULT_MAX_CELLS.min(gis::MAX_CELLS),
            max_steps: DEFAULT_MAX_STEPS,
        }
    }
}

/// Reads a field from a file (format by content, `.prj` side-cars of ASCII grids honoured).
pub fn load_file(path: &Path, opts: &LoadOptions) -> Result<Field, FieldError> {
    let bytes = std::fs::read(path)
        .map_err(|source| FieldError::Gis(gis::GisError::Io { path: path.to_path_buf(), source }))?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("field");
    let format = FieldFormat::detect(&bytes, Some(name))?;
    match format {
        FieldFormat::NetCdf => super::netcdf::read_netcdf(&bytes, name, opts),
        FieldFormat::GeoJson => geojson_labels(&bytes, name, opts),
        FieldFormat::GeoTiff | FieldFormat::AsciiGrid => {
            check_raster_header(&bytes, format, name, opts.max_cells)?;
            let (raster, file_crs) = match format {
                FieldFormat::GeoTiff => (gis::read_geotiff(path)?, geotiff_definition(path)),
                _ => {
                    let raster = gis::read_ascii_grid(path)?;
                    let crs = prj_definition(&raster.crs);
                    (raster, crs)
                }
            };
            single_step(raster, file_crs, opts)
        }
    }
}

/// Reads a field from uploaded bytes. GeoTIFFs are written to a uniquely named file in
/// `scratch_dir` (removed afterwards); ASCII grids have no `.prj`, so they need
/// [`LoadOptions::crs`].
pub fn load_bytes(
    bytes: &[u8],
    filename: Option<&str>,
    opts: &LoadOptions,
    scratch_dir: &Path,
) -> Result<Field, FieldError> {
    let format = FieldFormat::detect(bytes, filename)?;
    let name = filename.unwrap_or("upload");
    match format {
        FieldFormat::NetCdf => super::netcdf::read_netcdf(bytes, name, opts),
        FieldFormat::GeoJson => geojson_labels(bytes, name, opts),
        FieldFormat::AsciiGrid => {
            check_raster_header(bytes, format, name, opts.max_cells)?;
            let text = std::str::from_utf8(bytes).map_err(|_| FieldError::Format {
                context: name.to_string(),
                message: "not an ASCII grid (the file is not text)".into(),
            })?;
            let raster = gis::ascii_grid::parse_ascii_grid(Path::new(name), text)?;
            gis::raster::check_not_all_nodata(Path::new(name), &raster)?;
            single_step(raster, Ok(None), opts)
        }
        FieldFormat::GeoTiff => {
            check_raster_header(bytes, format, name, opts.max_cells)?;
            let scratch = ScratchFile::write(scratch_dir, bytes, format)?;
            let raster = gis::read_geotiff(&scratch.0).map_err(|e| rename_error(e, &scratch.0, name))?;
            let crs = geotiff_definition(&scratch.0);
            single_step(raster, crs, opts)
        }
    }
}

/// Builds one series from several raster files, each with its ISO 8601 time stamp (e.g. a
/// set of GeoTIFFs). All files must be in the same CRS; `opts.time` is ignored.
pub fn load_series(files: &[(PathBuf, String)], opts: &LoadOptions) -> Result<Field, FieldError> {
    if files.len() > opts.max_steps {
        return Err(FieldError::TooLarge {
            what: "series".into(),
            size: files.len() as u64,
            limit: opts.max_steps as u64,
        });
    }
    let mut field: Option<Field> = None;
    for (path, time) in files {
        let step_opts = LoadOptions { time: Some(time.clone()), ..opts.clone() };
        let next = load_file(path, &step_opts)?;
        field = Some(match field {
            None => next,
            Some(f) => f.append(next)?,
        });
    }
    field.ok_or_else(|| FieldError::Invalid("a series needs at least one file".into()))
}

/// The field of a single raster: CRS by override or file, time from the options.
fn single_step(
    mut raster: gis::Raster,
    file_crs: Result<Option<CrsDefinition>, ReprojectError>,
    opts: &LoadOptions,
) -> Result<Field, FieldError> {
    let crs = match &opts.crs {
        Some(given) => given.clone(),
        None => file_crs?.ok_or(ReprojectError::Missing)?,
    };
    raster.crs = crs.crs();
    let time = opts.time.as_deref().map(parse_time).transpose()?;
    Field::new(opts.kind, crs, opts.units.clone(), vec![FieldStep { time, raster }])
}

/// Cells along the longer side of a label field rasterized from GeoJSON polygons.
pub const GEOJSON_GRID_SIDE: usize = 1024;

/// A label field from GeoJSON polygons: the integer property `opts.variable` (default
/// `class`) rasterized in the file's CRS (or `opts.crs`) over the polygons' extent, the longer
/// side in [`GEOJSON_GRID_SIDE`] cells.
fn geojson_labels(bytes: &[u8], name: &str, opts: &LoadOptions) -> Result<Field, FieldError> {
    let format = |message: String| FieldError::Format { context: name.to_string(), message };
    if opts.kind != FieldKind::Label {
        return Err(format("GeoJSON polygons make label layers: give kind=label".into()));
    }
    let text = std::str::from_utf8(bytes).map_err(|_| format("not GeoJSON (the file is not UTF-8 text)".into()))?;
    let path = Path::new(name);
    let vector = |e: gis::VectorError| {
        let message = e.to_string();
        format(message.strip_prefix(&format!("{name}: ")).unwrap_or(&message).to_string())
    };
    let crs = match &opts.crs {
        Some(c) => c.clone(),
        None => gis::vector::geojson_crs(path, text).map_err(vector)?,
    };
    // Read once about (0, 0) for the extent, then in a frame about its centre.
    let probe = gis::LocalFrame::new(crs.crs(), 0.0, 0.0)?;
    let features = gis::vector::read_geojson(path, text, Some(&crs), gis::SceneTarget { crs: &crs, frame: &probe })
        .map_err(vector)?;
    let (lo, hi) = gis::vector::bounds(&features).ok_or_else(|| format("has no polygons".into()))?;
    let (a, b) = (probe.to_crs(lo[0], lo[1]), probe.to_crs(hi[0], hi[1]));
    let frame = gis::LocalFrame::new(crs.crs(), 0.5 * (a.0 + b.0), 0.5 * (a.1 + b.1))?;
    let features = gis::vector::read_geojson(path, text, Some(&crs), gis::SceneTarget { crs: &crs, frame: &frame })
        .map_err(vector)?;
    let (lo, hi) = gis::vector::bounds(&features).ok_or_else(|| format("has no polygons".into()))?;
    let cell = (hi[0] - lo[0]).max(hi[1] - lo[1]) / GEOJSON_GRID_SIDE as f64;
    let property = opts.variable.as_deref().unwrap_or("class");
    let raster = gis::vector::rasterize_labels(&features, property, cell, lo, hi, &frame, path).map_err(vector)?;
    single_step(raster, Ok(Some(crs)), opts)
}

/// The full CRS definition of a GeoTIFF from its GeoKeys.
fn geotiff_definition(path: &Path) -> Result<Option<CrsDefinition>, ReprojectError> {
    match gis::read_geokeys(path) {
        Ok(keys) => CrsDefinition::from_geokeys(&keys),
        Err(e) => Err(ReprojectError::Unsupported { crs: "GeoKeys".into(), reason: e.to_string() }),
    }
}

/// The definition of the CRS an ASCII grid's `.prj` gave (by its EPSG code).
fn prj_definition(crs: &gis::Crs) -> Result<Option<CrsDefinition>, ReprojectError> {
    match crs {
        gis::Crs::Unspecified => Ok(None),
        c => CrsDefinition::from_crs(c).map(Some),
    }
}

/// Replaces the scratch path in an error message by the upload's name.
fn rename_error(e: gis::GisError, scratch: &Path, name: &str) -> FieldError {
    if let gis::GisError::TooLarge { width, height, limit, .. } = e {
        return FieldError::TooLarge {
            what: format!("{name}: raster of {width} × {height} cells"),
            size: width.saturating_mul(height),
            limit,
        };
    }
    let message = e.to_string().replace(&scratch.display().to_string(), name);
    let message = message.strip_prefix(&format!("{name}: ")).unwrap_or(&message).to_string();
    FieldError::Format { context: name.to_string(), message }
}

/// Checks the grid size a GeoTIFF or ASCII grid announces in its header against `max_cells`
/// before anything is decoded, and what a GeoTIFF's chunks decode to against 8 bytes a cell
/// of it. An ASCII grid's header is parsed by the reader's own header
/// parser, so what is checked is what would be allocated.
fn check_raster_header(bytes: &[u8], format: FieldFormat, name: &str, max_cells: u64) -> Result<(), FieldError> {
    let (w, h, decoded) = match format {
        FieldFormat::GeoTiff => {
            let mut decoder = tiff::decoder::Decoder::new(Cursor::new(bytes)).map_err(|e| FieldError::Format {
                context: name.to_string(),
                message: format!("cannot decode TIFF: {e}"),
            })?;
            let tiff_error = |e: tiff::TiffError| FieldError::Format {
                context: name.to_string(),
                message: format!("cannot decode TIFF: {e}"),
            };
            let (w, h) = decoder.dimensions().map_err(tiff_error)?;
            // Strips or tiles × samples × bytes, before any decompression (D4).
            let decoded = gis::geotiff::decoded_bytes(&mut decoder).map_err(tiff_error)?;
            (u64::from(w), u64::from(h), Some(decoded))
        }
        FieldFormat::AsciiGrid => {
            // The header as the reader reads it (byte-order marks, any number of blank lines);
            // the reader refuses anything that is not UTF-8 text before allocating.
            let Ok(text) = std::str::from_utf8(bytes) else {
                return Err(FieldError::Format {
                    context: name.to_string(),
                    message: "not an ASCII grid (the file is not text)".into(),
                });
            };
            let (w, h) = gis::ascii_grid::ascii_grid_size(Path::new(name), text)?;
            (w, h, None)
        }
        FieldFormat::NetCdf | FieldFormat::GeoJson => return Ok(()),
    };
    let cells = w.saturating_mul(h);
    if cells > max_cells {
        return Err(FieldError::TooLarge {
            what: format!("{name}: raster of {w} × {h} cells"),
            size: cells,
            limit: max_cells,
        });
    }
    let budget = gis::geotiff::decoding_budget(max_cells);
    if let Some(decoded) = decoded.filter(|d| *d > budget) {
        return Err(FieldError::TooLarge {
            what: format!(
                "{name}: decoded TIFF data in bytes (strips or tiles × samples per pixel × bytes per sample)"
            ),
            size: decoded,
            limit: budget,
        });
    }
    Ok(())
}

/// A file removed when dropped.
struct ScratchFile(PathBuf);

impl ScratchFile {
    /// Writes `bytes` to a new uniquely named file in `dir`.
    fn write(dir: &Path, bytes: &[u8], format: FieldFormat) -> Result<ScratchFile, FieldError> {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path = dir.join(format!("upload-{}-{n}.{}", std::process::id(), format.extension()));
        std::fs::write(&path, bytes)
            .map_err(|source| FieldError::Gis(gis::GisError::Io { path: path.clone(), source }))?;
        Ok(ScratchFile(path))
    }
}

impl Drop for ScratchFile {
    fn drop(&mut self) {
        // Best effort: a leftover scratch file is removed when the store is next opened.
        let _ = std::fs::remove_file(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detects_formats() {
        assert_eq!(FieldFormat::detect(b"II*\0rest", None).unwrap(), FieldFormat::GeoTiff);
        assert_eq!(FieldFormat::detect(b"MM\0*rest", Some("x.bin")).unwrap(), FieldFormat::GeoTiff);
        assert_eq!(FieldFormat::detect(b"CDF\x01....", None).unwrap(), FieldFormat::NetCdf);
        assert_eq!(FieldFormat::detect(b"  NCOLS 3\nnrows 2\n", None).unwrap(), FieldFormat::AsciiGrid);
        let hdf = FieldFormat::detect(b"\x89HDF\r\n\x1a\n...", Some("a.nc")).unwrap_err().to_string();
        assert!(hdf.contains("NetCDF-4"), "{hdf}");
        let garbage = FieldFormat::detect(b"hello", Some("a.tif")).unwrap_err().to_string();
        assert!(garbage.contains("a.tif") && garbage.contains("not a TIFF"), "{garbage}");
        assert!(FieldFormat::detect(b"", None).is_err());
    }

    #[test]
    fn ascii_header_limit() {
        let big = b"ncols 100000\nnrows 100000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n";
        let err = check_raster_header(big, FieldFormat::AsciiGrid, "big.asc", 1 << 24).unwrap_err();
        assert!(err.is_too_large(), "{err}");
        assert!(check_raster_header(b"ncols 3\nnrows 2\n", FieldFormat::AsciiGrid, "a.asc", 6).is_ok());
    }

    /// The header check reads the header as the reader does: a byte-order mark before a key
    /// or any number of blank lines do not hide a size over the limit.
    #[test]
    fn ascii_header_limit_sees_what_the_reader_sees() {
        let tail = "xllcorner 0\nyllcorner 0\ncellsize 1\n1 2 3\n";
        let bom = format!("ncols 4200\n\u{feff}nrows 4200\n{tail}");
        let blank = format!("ncols 4200\n{}nrows 4200\n{tail}", "\n".repeat(4096));
        let spaced = format!("ncols 4200\n{}NROWS 4200\n{tail}", "   \r\n".repeat(1000));
        for text in [bom, blank, spaced] {
            let err = check_raster_header(text.as_bytes(), FieldFormat::AsciiGrid, "big.asc", 1 << 24).unwrap_err();
            assert!(err.is_too_large(), "{err}");
            assert!(err.to_string().contains("big.asc"), "{err}");
        }
    }
}
