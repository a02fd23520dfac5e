//! Errors of the GIS layer. Every variant that concerns a file names that file first, so a
//! message shown to a user says which input is wrong and why.

use std::path::PathBuf;

/// Why a raster could not be read, written, cropped or placed in a local frame.
#[derive(Debug, thiserror::Error)]
pub enum GisError {
    /// The file could not be opened or read.
    #[error("{}: cannot read: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The file does not start with a TIFF signature.
    #[error("{}: not a TIFF file", path.display())]
    NotTiff {
        /// The file.
        path: PathBuf,
    },
    /// The TIFF decoder rejected the file (corrupt data, unsupported layout or compression).
    #[error("{}: cannot decode TIFF: {message}", path.display())]
    Tiff {
        /// The file.
        path: PathBuf,
        /// What the decoder reported.
        message: String,
    },
    /// A TIFF without ModelTiepoint/ModelPixelScale or ModelTransformation tags.
    #[error(
        "{}: TIFF has no georeferencing (ModelTiepoint/ModelPixelScale or ModelTransformation)",
        path.display()
    )]
    NoGeoreferencing {
        /// The file.
        path: PathBuf,
    },
    /// Georeferencing that is present but unusable (rotated, south-up, zero or negative cell
    /// size, non-finite coordinates, malformed GeoKey directory …).
    #[error("{}: unsupported georeferencing: {reason}", path.display())]
    BadGeoreferencing {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },
    /// A sample type this crate does not read (complex, 1-bit, 64-bit integer, 16-bit float …).
    #[error(
        "{}: unsupported sample type {detail} (supported: 8/16/32-bit integers, 32/64-bit floats)",
        path.display()
    )]
    UnsupportedSampleType {
        /// The file.
        path: PathBuf,
        /// The sample type found, e.g. "1-bit unsigned integer".
        detail: String,
    },
    /// Every cell of the raster is nodata (or NaN).
    #[error("{}: every cell is nodata", path.display())]
    AllNodata {
        /// The file.
        path: PathBuf,
    },
    /// Width × height above [`crate::gis::raster::MAX_CELLS`].
    #[error(
        "{}: raster of {width} × {height} cells is too large (limit {limit} cells)",
        path.display()
    )]
    TooLarge {
        /// The file.
        path: PathBuf,
        /// Columns.
        width: u64,
        /// Rows.
        height: u64,
        /// The cell limit.
        limit: u64,
    },
    /// A parse error in an ESRI ASCII grid, with its 1-based line number.
    #[error("{}: line {line}: {message}", path.display())]
    AsciiGrid {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong on that line.
        message: String,
    },
    /// A file-level format problem without a single line to blame (e.g. too few values).
    #[error("{}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The file extension names no raster format this crate reads.
    #[error(
        "{}: unknown raster format (expected .tif, .tiff or .asc)",
        path.display()
    )]
    UnknownFormat {
        /// The file.
        path: PathBuf,
    },
    /// Writing a raster failed or the raster cannot be stored in the requested type.
    #[error("{}: cannot write: {message}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A CRS string that is not an `EPSG:<code>` this crate knows.
    #[error("unknown CRS \"{}\": {reason}", crate::echo::echo(.crs))]
    UnknownCrs {
        /// The string as given.
        crs: String,
        /// Why it was rejected.
        reason: String,
    },
    /// A raster whose CRS cannot be brought into the scene's.
    #[error("{}: {source}", path.display())]
    Reproject {
        /// The file.
        path: PathBuf,
        /// Why.
        source: super::reproject::ReprojectError,
    },
    /// A raster without CRS cannot be placed in a metric frame.
    #[error("raster has no coordinate reference system: set the CRS, e.g. `crs = \"EPSG:4326\"` in the scene file")]
    UnspecifiedCrs,
    /// A local frame cannot be built at this origin (e.g. too close to a pole).
    #[error("cannot build a local metric frame: {reason}")]
    BadFrame {
        /// Why.
        reason: String,
    },
    /// A window (a scene's crop extent) that does not meet the raster.
    #[error(
        "{}: the window [{}, {}, {}, {}] does not overlap the raster, which covers [{}, {}, {}, {}] in {crs}",
        path.display(), window.min_x, window.min_y, window.max_x, window.max_y,
        extent.min_x, extent.min_y, extent.max_x, extent.max_y
    )]
    WindowOutside {
        /// The file.
        path: PathBuf,
        /// The window asked for, in the raster's CRS.
        window: super::raster::Extent,
        /// What the raster covers.
        extent: super::raster::Extent,
        /// The raster's CRS.
        crs: super::crs::Crs,
    },
    /// A crop window that is empty or extends past the raster.
    #[error(
        "crop window {width} × {height} at column {col0}, row {row0} does not fit in a {raster_width} × {raster_height} raster"
    )]
    CropOutOfRange {
        /// First column of the window.
        col0: usize,
        /// First row of the window.
        row0: usize,
        /// Window width.
        width: usize,
        /// Window height.
        height: usize,
        /// Raster width.
        raster_width: usize,
        /// Raster height.
        raster_height: usize,
    },
    /// A raster whose `data` length is not `width × height`.
    #[error("raster holds {len} values for {width} × {height} cells")]
    InconsistentRaster {
        /// Length of `data`.
        len: usize,
        /// Columns.
        width: usize,
        /// Rows.
        height: usize,
    },
}
