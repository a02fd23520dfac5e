//! GeoTIFF reading (band 1 of any strip/tiled, little/big-endian, compressed TIFF the `tiff`
//! crate decodes) and writing (strip layout, Deflate, native = little-endian byte order on
//! the platforms we run on).
//!
//! Georeferencing: ModelTiepoint + ModelPixelScale, or ModelTransformation without rotation;
//! GeoKeys GTModelType (1024), GTRasterType (1025, PixelIsPoint shifts by half a cell),
//! GeographicType (2048), ProjectedCSType (3072; 32767 = user-defined → no EPSG code),
//! ProjLinearUnits (3076) and ProjLinearUnitSize (3077); nodata from GDAL_NODATA (42113).
//!
//! Palette (and WhiteIsZero) images: `tiff` 0.11 refuses to decode PhotometricInterpretation
//! RGBPalette at all (its colour-type check runs before any chunk is read), while the samples
//! are plain 8-bit indices. The reader therefore patches the 2-byte PhotometricInterpretation
//! value in an in-memory copy of the file to BlackIsZero and decodes that copy; the ColorMap is
//! read from the original tags first. Nothing else of the TIFF is parsed by hand.

use std::io::Cursor;
use std::path::Path;

use tiff::decoder::{Decoder, DecodingResult, Limits};
use tiff::encoder::colortype::{ColorType, Gray8, Gray32Float, RGB16};
use tiff::encoder::compression::DeflateLevel;
use tiff::encoder::{Compression, TiffEncoder, TiffValue};
use tiff::tags::{PhotometricInterpretation, SampleFormat, Tag};

use super::crs::{Crs, FOOT, US_SURVEY_FOOT};
use super::error::GisError;
use super::raster::{self, Extent, GeoTransform, Raster};

/// GeoKey ids used here.
mod key {
    pub const MODEL_TYPE: u16 = 1024;
    pub const RASTER_TYPE: u16 = 1025;
    pub const GEOGRAPHIC_TYPE: u16 = 2048;
    pub const PROJECTED_CS_TYPE: u16 = 3072;
    pub const PROJ_LINEAR_UNITS: u16 = 3076;
    pub const PROJ_LINEAR_UNIT_SIZE: u16 = 3077;
}

/// GeoKey value for "user-defined".
const USER_DEFINED: u16 = 32767;
/// GTModelType values.
const MODEL_PROJECTED: u16 = 1;
const MODEL_GEOGRAPHIC: u16 = 2;
const MODEL_GEOCENTRIC: u16 = 3;
/// GTRasterType values.
const RASTER_PIXEL_IS_AREA: u16 = 1;
const RASTER_PIXEL_IS_POINT: u16 = 2;
/// EPSG linear unit codes.
const UNIT_METRE: u16 = 9001;
const UNIT_FOOT: u16 = 9002;
const UNIT_US_SURVEY_FOOT: u16 = 9003;
const UNIT_KILOMETRE: u16 = 9036;

/// Sample types this reader converts to `f64`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SampleType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    F32,
    F64,
}

impl SampleType {
    /// From the SampleFormat and BitsPerSample tag values; `Err` describes an unsupported one.
    fn from_tags(format: u16, bits: u16) -> Result<SampleType, String> {
        let kind = match format {
            1 => "unsigned integer",
            2 => "signed integer",
            3 => "float",
            4 => "undefined",
            5 => "complex integer",
            6 => "complex float",
            _ => "unknown format",
        };
        Ok(match (format, bits) {
            (1, 8) => SampleType::U8,
            (2, 8) => SampleType::I8,
            (1, 16) => SampleType::U16,
            (2, 16) => SampleType::I16,
            (1, 32) => SampleType::U32,
            (2, 32) => SampleType::I32,
            (3, 32) => SampleType::F32,
            (3, 64) => SampleType::F64,
            _ => return Err(format!("{bits}-bit {kind} (SampleFormat {format})")),
        })
    }
}

/// A GeoKey value: a SHORT stored in the directory or DOUBLEs from GeoDoubleParams.
#[derive(Debug, Clone, PartialEq)]
enum KeyValue {
    Short(u16),
    Doubles(Vec<f64>),
    /// ASCII or otherwise unused here.
    Other,
}

/// The GeoKeys of a file, in directory order.
#[derive(Debug, Default)]
struct GeoKeys {
    keys: Vec<(u16, KeyValue)>,
}

impl GeoKeys {
    /// Parses GeoKeyDirectory (SHORTs) with GeoDoubleParams.
    fn parse(dir: &[u16], doubles: &[f64]) -> Result<GeoKeys, String> {
        let [_version, _revision, _minor, count, rest @ ..] = dir else {
            return Err("GeoKeyDirectory is shorter than its 4-value header".to_string());
        };
        let count = usize::from(*count);
        if rest.len() < count * 4 {
            return Err(format!("GeoKeyDirectory announces {count} keys but holds {}", rest.len() / 4));
        }
        let keys = rest
            .chunks_exact(4)
            .take(count)
            .map(|e| {
                let (id, location, n, value) = (e[0], e[1], usize::from(e[2]), e[3]);
                let v = match location {
                    0 => KeyValue::Short(value),
                    34735 => dir.get(usize::from(value)).map_or(KeyValue::Other, |&s| KeyValue::Short(s)),
                    34736 => doubles
                        .get(usize::from(value)..usize::from(value) + n)
                        .map_or(KeyValue::Other, |d| KeyValue::Doubles(d.to_vec())),
                    _ => KeyValue::Other,
                };
                (id, v)
            })
            .collect();
        Ok(GeoKeys { keys })
    }

    fn short(&self, id: u16) -> Option<u16> {
        self.keys.iter().find_map(|(k, v)| match v {
            KeyValue::Short(s) if *k == id => Some(*s),
            _ => None,
        })
    }

    fn double(&self, id: u16) -> Option<f64> {
        self.keys.iter().find_map(|(k, v)| match v {
            KeyValue::Doubles(d) if *k == id => d.first().copied(),
            _ => None,
        })
    }

    /// Whether GTRasterType is PixelIsPoint.
    fn pixel_is_point(&self) -> bool {
        self.short(key::RASTER_TYPE) == Some(RASTER_PIXEL_IS_POINT)
    }

    /// The CRS the keys describe.
    fn crs(&self) -> Result<Crs, String> {
        let code = |id| self.short(id).filter(|&c| c != 0 && c != USER_DEFINED).map(u32::from);
        let model = match self.short(key::MODEL_TYPE) {
            Some(m @ (MODEL_PROJECTED | MODEL_GEOGRAPHIC)) => m,
            Some(MODEL_GEOCENTRIC) => {
                return Err("geocentric model type is not supported".to_string());
            }
            _ if self.short(key::PROJECTED_CS_TYPE).is_some() => MODEL_PROJECTED,
            _ if self.short(key::GEOGRAPHIC_TYPE).is_some() => MODEL_GEOGRAPHIC,
            _ => return Ok(Crs::Unspecified),
        };
        if model == MODEL_GEOGRAPHIC {
            return Ok(Crs::Geographic { epsg: code(key::GEOGRAPHIC_TYPE) });
        }
        let unit_to_metre = match self.short(key::PROJ_LINEAR_UNITS) {
            None | Some(UNIT_METRE) => 1.0,
            Some(UNIT_FOOT) => FOOT,
            Some(UNIT_US_SURVEY_FOOT) => US_SURVEY_FOOT,
            Some(UNIT_KILOMETRE) => 1000.0,
            Some(USER_DEFINED) => self
                .double(key::PROJ_LINEAR_UNIT_SIZE)
                .filter(|s| s.is_finite() && *s > 0.0)
                .ok_or("user-defined linear unit without a valid ProjLinearUnitSizeGeoKey")?,
            Some(other) => return Err(format!("unsupported linear unit code {other}")),
        };
        Ok(Crs::Projected { epsg: code(key::PROJECTED_CS_TYPE), unit_to_metre })
    }
}

/// The north-up transform from ModelTransformation or ModelTiepoint + ModelPixelScale;
/// `Ok(None)` when the file has neither.
fn transform_from_tags(
    tiepoints: Option<&[f64]>,
    scale: Option<&[f64]>,
    matrix: Option<&[f64]>,
    pixel_is_point: bool,
) -> Result<Option<GeoTransform>, String> {
    let (origin_x, origin_y, cell_width, cell_height) = if let Some(m) = matrix {
        let &[a, b, _, d, e, f, _, h, ..] = m else {
            return Err(format!("ModelTransformation has {} values, not 16", m.len()));
        };
        if b != 0.0 || e != 0.0 {
            return Err("rotated or sheared ModelTransformation is not supported".to_string());
        }
        (d, h, a, -f)
    } else {
        let (Some(t), Some(s)) = (tiepoints, scale) else {
            return match tiepoints {
                Some(t) if t.len() > 6 => {
                    Err("ground control points without ModelPixelScale are not supported".to_string())
                }
                _ => Ok(None),
            };
        };
        let (&[i, j, _, x, y, ..], &[sx, sy, ..]) = (t, s) else {
            return Err("ModelTiepoint or ModelPixelScale has too few values".to_string());
        };
        (x - i * sx, y + j * sy, sx, sy)
    };
    let positive = |v: f64| v > 0.0;
    if !positive(cell_width) || !positive(cell_height) {
        return Err(format!(
            "cell size {cell_width} × {cell_height}: only north-up rasters with positive cell \
             sizes are supported"
        ));
    }
    let mut t = GeoTransform { origin_x, origin_y, cell_width, cell_height };
    if pixel_is_point {
        // The georeferenced point of a pixel is its centre: move to the corner.
        t.origin_x -= 0.5 * cell_width;
        t.origin_y += 0.5 * cell_height;
    }
    Ok(Some(t))
}

/// The bytes of a TIFF file with the first IFD's PhotometricInterpretation set to BlackIsZero,
/// so that `tiff` decodes the raw samples. `None` if the entry cannot be found as a SHORT.
fn with_black_is_zero(bytes: &[u8], ifd_offset: u64) -> Option<Vec<u8>> {
    let big_endian = bytes.get(..2)? == b"MM";
    let u16_at = |pos: usize| -> Option<u16> {
        let b: [u8; 2] = bytes.get(pos..pos.checked_add(2)?)?.try_into().ok()?;
        Some(if big_endian { u16::from_be_bytes(b) } else { u16::from_le_bytes(b) })
    };
    let u64_at = |pos: usize| -> Option<u64> {
        let b: [u8; 8] = bytes.get(pos..pos.checked_add(8)?)?.try_into().ok()?;
        Some(if big_endian { u64::from_be_bytes(b) } else { u64::from_le_bytes(b) })
    };
    let bigtiff = u16_at(2)? == 43;
    let ifd = usize::try_from(ifd_offset).ok()?;
    // Classic: u16 count, 12-byte entries (tag, type, u32 count, 4-byte value).
    // BigTIFF: u64 count, 20-byte entries (tag, type, u64 count, 8-byte value).
    let (count, first, entry_len, value_at) = if bigtiff {
        (usize::try_from(u64_at(ifd)?).ok()?, ifd + 8, 20, 12)
    } else {
        (usize::from(u16_at(ifd)?), ifd + 2, 12, 8)
    };
    const SHORT: u16 = 3;
    let entry = (0..count)
        .map(|i| first + i * entry_len)
        .find(|&e| u16_at(e) == Some(Tag::PhotometricInterpretation.to_u16()))?;
    if u16_at(entry + 2)? != SHORT {
        return None;
    }
    let value = entry + value_at;
    let new = PhotometricInterpretation::BlackIsZero.to_u16();
    let mut patched = bytes.to_vec();
    patched.get_mut(value..value + 2)?.copy_from_slice(&if big_endian { new.to_be_bytes() } else { new.to_le_bytes() });
    Some(patched)
}

/// Parses a GDAL_NODATA string ("-9999", "nan", "-3.4028234663852886e+38").
fn parse_nodata(text: &str) -> Option<f64> {
    text.trim_matches(|c: char| c == '\0' || c.is_whitespace()).parse().ok()
}

/// Scales a TIFF ColorMap (all reds, then greens, then blues, 16 bit) to 8-bit RGB entries.
fn palette_from_colormap(map: &[u16], bits: u16) -> Option<Vec<[u8; 3]>> {
    let n = 1usize.checked_shl(u32::from(bits))?;
    if map.len() != 3 * n {
        return None;
    }
    // Rounded v / 257; at most 255, so the narrowing is exact.
    let to8 = |v: u16| ((u32::from(v) + 128) / 257) as u8;
    Some((0..n).map(|i| [to8(map[i]), to8(map[n + i]), to8(map[2 * n + i])]).collect())
}

/// Converts band `index` (from 0) of decoded samples (`stride` samples per pixel) to `f64`.
fn band(result: &DecodingResult, stride: usize, index: usize) -> Vec<f64> {
    fn pick<T: Copy + Into<f64>>(v: &[T], stride: usize, index: usize) -> Vec<f64> {
        v.iter().skip(index).step_by(stride).map(|&x| x.into()).collect()
    }
    match result {
        DecodingResult::U8(v) => pick(v, stride, index),
        DecodingResult::I8(v) => pick(v, stride, index),
        DecodingResult::U16(v) => pick(v, stride, index),
        DecodingResult::I16(v) => pick(v, stride, index),
        DecodingResult::U32(v) => pick(v, stride, index),
        DecodingResult::I32(v) => pick(v, stride, index),
        DecodingResult::F32(v) => pick(v, stride, index),
        DecodingResult::F64(v) => pick(v, stride, index),
        // Rejected by the sample type check before decoding; precision loss is acceptable for
        // the unlikely case that a decoder ever returns them.
        DecodingResult::U64(v) => v.iter().skip(index).step_by(stride).map(|&x| x as f64).collect(),
        DecodingResult::I64(v) => v.iter().skip(index).step_by(stride).map(|&x| x as f64).collect(),
        DecodingResult::F16(v) => v.iter().skip(index).step_by(stride).map(|&x| f64::from(x)).collect(),
    }
}

/// Number of decoded values of a result.
fn result_len(result: &DecodingResult) -> usize {
    match result {
        DecodingResult::U8(v) => v.len(),
        DecodingResult::I8(v) => v.len(),
        DecodingResult::U16(v) => v.len(),
        DecodingResult::I16(v) => v.len(),
        DecodingResult::U32(v) => v.len(),
        DecodingResult::I32(v) => v.len(),
        DecodingResult::U64(v) => v.len(),
        DecodingResult::I64(v) => v.len(),
        DecodingResult::F16(v) => v.len(),
        DecodingResult::F32(v) => v.len(),
        DecodingResult::F64(v) => v.len(),
    }
}

/// Bytes that decoding the image of `decoder` decompresses, computed from its tags before
/// anything is decoded: whole chunks across (strips, or tiles with their right-hand padding,
/// which the decoder decompresses and discards) × the rows × samples per pixel × bytes per
/// sample. A tiny compressed file can announce gigabytes this way (a decompression bomb:
/// 4096 × 4096 cells of 29 four-byte samples, or tiles 65536 wide); callers compare this
/// against their budget first.
pub fn decoded_bytes<R: std::io::Read + std::io::Seek>(decoder: &mut Decoder<R>) -> tiff::TiffResult<u64> {
    let (width, height) = decoder.dimensions()?;
    let first = |values: Option<Vec<u16>>| values.and_then(|v| v.first().copied());
    let samples = first(decoder.find_tag_unsigned_vec::<u16>(Tag::SamplesPerPixel)?).unwrap_or(1);
    let bits = decoder.find_tag_unsigned_vec::<u16>(Tag::BitsPerSample)?;
    let bits = bits.and_then(|b| b.into_iter().max()).unwrap_or(1);
    let (chunk_width, _) = decoder.chunk_dimensions();
    let chunks_across = u64::from(width).div_ceil(u64::from(chunk_width.max(1)));
    let padded_width = chunks_across.saturating_mul(u64::from(chunk_width));
    Ok(padded_width
        .saturating_mul(u64::from(height))
        .saturating_mul(u64::from(samples.max(1)))
        .saturating_mul(u64::from(bits.div_ceil(8).max(1))))
}

/// Decoding budget of a raster of at most `max_cells` cells: 8 bytes per cell (one f64 band
/// or four u16 bands), so that a raster at the cell limit still decodes.
pub fn decoding_budget(max_cells: u64) -> u64 {
    max_cells.saturating_mul(8)
}

/// Whether a TIFF's first image holds unsigned 16-bit samples (as 16-bit orthophotos do).
pub fn is_uint16(path: &Path) -> Result<bool, GisError> {
    let file = std::fs::File::open(path).map_err(|source| GisError::Io { path: path.to_path_buf(), source })?;
    let tiff_err = |e: tiff::TiffError| GisError::Tiff { path: path.to_path_buf(), message: e.to_string() };
    let mut decoder = Decoder::new(std::io::BufReader::new(file)).map_err(tiff_err)?;
    let mut first = |tag| -> Result<Option<u16>, GisError> {
        let values = decoder.find_tag(tag).map_err(tiff_err)?;
        Ok(values.map(|v| v.into_u16_vec()).transpose().map_err(tiff_err)?.and_then(|v| v.first().copied()))
    };
    let bits = first(Tag::BitsPerSample)?.unwrap_or(1);
    let format = first(Tag::SampleFormat)?.unwrap_or(SampleFormat::Uint.to_u16());
    Ok(bits == 16 && format == SampleFormat::Uint.to_u16())
}

/// Reads band 1 of a GeoTIFF with its georeferencing, CRS, nodata and palette.
pub fn read_geotiff(path: &Path) -> Result<Raster, GisError> {
    let mut bands = read_bands(path, false)?;
    Ok(bands.swap_remove(0))
}

/// Reads every band of a pixel-interleaved GeoTIFF (an RGB orthophoto: three rasters), each
/// with the file's georeferencing, CRS and nodata. A planar (band-sequential) file with more
/// than one band is an error naming the file.
pub fn read_geotiff_bands(path: &Path) -> Result<Vec<Raster>, GisError> {
    read_bands(path, true)
}

/// What the tags of one image (IFD) of a TIFF say about its cells, read before decoding.
struct Layout {
    width: u32,
    height: u32,
    sample_type: SampleType,
    bits: u16,
    photometric: Option<u16>,
    planar: bool,
    samples: u16,
}

impl Layout {
    /// The layout of the decoder's current image.
    fn read<R: std::io::Read + std::io::Seek>(decoder: &mut Decoder<R>, path: &Path) -> Result<Layout, GisError> {
        let tiff_err = |e: tiff::TiffError| GisError::Tiff { path: path.to_path_buf(), message: e.to_string() };
        let (width, height) = decoder.dimensions().map_err(tiff_err)?;
        let mut first = |tag| -> Result<Option<u16>, GisError> {
            let values =
                decoder.find_tag(tag).and_then(|v| v.map(|v| v.into_u16_vec()).transpose()).map_err(tiff_err)?;
            Ok(values.and_then(|v| v.first().copied()))
        };
        // Sample type of band 1 (formats are homogeneous, `tiff` checks that).
        let bits = first(Tag::BitsPerSample)?.unwrap_or(1);
        let format = first(Tag::SampleFormat)?.unwrap_or(SampleFormat::Uint.to_u16());
        let sample_type = SampleType::from_tags(format, bits)
            .map_err(|detail| GisError::UnsupportedSampleType { path: path.to_path_buf(), detail })?;
        let photometric = first(Tag::PhotometricInterpretation)?;
        let planar = first(Tag::PlanarConfiguration)? == Some(2);
        let samples = first(Tag::SamplesPerPixel)?.unwrap_or(1);
        Ok(Layout { width, height, sample_type, bits, photometric, planar, samples })
    }

    /// Whether the image is a palette or WhiteIsZero image, which the decoder reads only with
    /// its PhotometricInterpretation patched (see [`with_black_is_zero`]).
    fn needs_patch(&self) -> bool {
        [PhotometricInterpretation::RGBPalette, PhotometricInterpretation::WhiteIsZero]
            .iter()
            .any(|p| self.photometric == Some(p.to_u16()))
    }
}

/// The georeferencing, CRS and nodata value of a GeoTIFF (its first image's tags).
struct Georeference {
    transform: GeoTransform,
    crs: Crs,
    nodata: Option<f64>,
}

impl Georeference {
    fn read<R: std::io::Read + std::io::Seek>(
        decoder: &mut Decoder<R>,
        path: &Path,
        sample_type: SampleType,
    ) -> Result<Georeference, GisError> {
        let tiff_err = |e: tiff::TiffError| GisError::Tiff { path: path.to_path_buf(), message: e.to_string() };
        let bad_geo = |reason: String| GisError::BadGeoreferencing { path: path.to_path_buf(), reason };
        let mut doubles = |tag| -> Result<Option<Vec<f64>>, GisError> {
            decoder.find_tag(tag).and_then(|v| v.map(|v| v.into_f64_vec()).transpose()).map_err(tiff_err)
        };
        let tiepoints = doubles(Tag::ModelTiepointTag)?;
        let scale = doubles(Tag::ModelPixelScaleTag)?;
        let matrix = doubles(Tag::ModelTransformationTag)?;
        let params = doubles(Tag::GeoDoubleParamsTag)?.unwrap_or_default();
        let directory = decoder
            .find_tag(Tag::GeoKeyDirectoryTag)
            .and_then(|v| v.map(|v| v.into_u16_vec()).transpose())
            .map_err(tiff_err)?;
        let geokeys = match directory {
            Some(dir) => GeoKeys::parse(&dir, &params).map_err(bad_geo)?,
            None => GeoKeys::default(),
        };
        let transform =
            transform_from_tags(tiepoints.as_deref(), scale.as_deref(), matrix.as_deref(), geokeys.pixel_is_point())
                .map_err(bad_geo)?
                .ok_or_else(|| GisError::NoGeoreferencing { path: path.to_path_buf() })?;
        raster::check_transform(path, &transform)?;
        let crs = geokeys.crs().map_err(bad_geo)?;
        let mut nodata = match decoder.find_tag(Tag::GdalNodata).map_err(tiff_err)? {
            Some(v) => {
                let text = v.into_string().map_err(tiff_err)?;
                Some(parse_nodata(&text).ok_or_else(|| GisError::Tiff {
                    path: path.to_path_buf(),
                    message: format!("GDAL_NODATA value \"{}\" is not a number", text.trim()),
                })?)
            }
            None => None,
        };
        if sample_type == SampleType::F32 {
            // Cells hold f32 values: compare against the nodata value as f32 (like GDAL does).
            nodata = nodata.map(|v| f64::from(v as f32));
        }
        Ok(Georeference { transform, crs, nodata })
    }
}

/// Decoder limits within the decoding budget of [`raster::MAX_CELLS`].
fn limits() -> Limits {
    let mut l = Limits::default();
    l.decoding_buffer_size = usize::try_from(decoding_budget(raster::MAX_CELLS)).unwrap_or(usize::MAX);
    l
}

/// [`read_geotiff`] (band 1 only, `all` false) and [`read_geotiff_bands`] (`all` true).
fn read_bands(path: &Path, all: bool) -> Result<Vec<Raster>, GisError> {
    let bytes = std::fs::read(path).map_err(|source| GisError::Io { path: path.to_path_buf(), source })?;
    let tiff_err = |e: tiff::TiffError| GisError::Tiff { path: path.to_path_buf(), message: e.to_string() };
    check_signature(path, &bytes)?;
    let mut decoder = Decoder::new(Cursor::new(bytes.as_slice())).map_err(tiff_err)?;
    let layout = Layout::read(&mut decoder, path)?;
    let (width, height) = (layout.width, layout.height);
    raster::check_dimensions(path, width.into(), height.into())?;
    if all && layout.planar && layout.samples > 1 {
        return Err(GisError::Tiff {
            path: path.to_path_buf(),
            message: format!(
                "its {} bands are stored plane by plane; write it pixel-interleaved \
                 (gdal_translate -co INTERLEAVE=PIXEL)",
                layout.samples
            ),
        });
    }
    let ycbcr = (all && layout.photometric == Some(PhotometricInterpretation::YCbCr.to_u16()) && layout.bits == 8)
        .then(|| YCbCr::from_tags(&mut decoder))
        .transpose()
        .map_err(tiff_err)?;
    let geo = Georeference::read(&mut decoder, path, layout.sample_type)?;
    let palette = read_palette(&mut decoder, path, &layout)?;

    // Cell counts are capped by MAX_CELLS; the decoded bytes (padding and further samples
    // included) by the same budget, checked before decoding.
    check_budget(path, decoded_bytes(&mut decoder).map_err(tiff_err)?)?;
    let result = if layout.needs_patch() {
        let patched =
            decoder.ifd_pointer().and_then(|ifd| with_black_is_zero(&bytes, ifd.0)).ok_or_else(|| GisError::Tiff {
                path: path.to_path_buf(),
                message: "cannot locate the PhotometricInterpretation entry".to_string(),
            })?;
        let mut d = Decoder::new(Cursor::new(patched.as_slice())).map_err(tiff_err)?.with_limits(limits());
        d.read_image().map_err(tiff_err)?
    } else {
        let mut d = decoder.with_limits(limits());
        d.read_image().map_err(tiff_err)?
    };

    // Chunky images interleave all samples of a pixel; planar ones yield plane 1 only.
    let cells = width as usize * height as usize;
    let len = result_len(&result);
    let stride = if layout.planar { 1 } else { len / cells };
    if stride == 0 || len != stride * cells {
        return Err(GisError::Tiff {
            path: path.to_path_buf(),
            message: format!("decoded {len} samples for {width} × {height} pixels"),
        });
    }
    let raster = |index: usize| Raster {
        width: width as usize,
        height: height as usize,
        data: band(&result, stride, index),
        nodata: geo.nodata,
        transform: geo.transform,
        crs: geo.crs,
        palette: palette.clone(),
    };
    let first = raster(0);
    raster::check_not_all_nodata(path, &first)?;
    let mut bands = vec![first];
    if all {
        bands.extend((1..stride).map(raster));
    }
    if let (Some(ycbcr), [y, cb, cr, ..]) = (ycbcr, bands.as_mut_slice()) {
        ycbcr.to_rgb(y, cb, cr);
    }
    Ok(bands)
}

/// Refuses bytes that do not start with a TIFF or BigTIFF signature.
fn check_signature(path: &Path, bytes: &[u8]) -> Result<(), GisError> {
    if matches!(bytes.get(..4), Some(b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+")) {
        Ok(())
    } else {
        Err(GisError::NotTiff { path: path.to_path_buf() })
    }
}

/// Refuses decoding `decoded` bytes beyond the budget of [`raster::MAX_CELLS`].
fn check_budget(path: &Path, decoded: u64) -> Result<(), GisError> {
    let budget = decoding_budget(raster::MAX_CELLS);
    if decoded > budget {
        return Err(GisError::Tiff {
            path: path.to_path_buf(),
            message: format!("decoding would produce {decoded} bytes, more than the limit of {budget}"),
        });
    }
    Ok(())
}

/// The 8-bit palette of a palette image (`None` for others).
fn read_palette<R: std::io::Read + std::io::Seek>(
    decoder: &mut Decoder<R>,
    path: &Path,
    layout: &Layout,
) -> Result<Option<Vec<[u8; 3]>>, GisError> {
    if layout.photometric != Some(PhotometricInterpretation::RGBPalette.to_u16()) {
        return Ok(None);
    }
    let map = decoder
        .find_tag(Tag::ColorMap)
        .and_then(|v| v.map(|v| v.into_u16_vec()).transpose())
        .map_err(|e| GisError::Tiff { path: path.to_path_buf(), message: e.to_string() })?;
    Ok(Some(map.and_then(|m| palette_from_colormap(&m, layout.bits)).ok_or_else(|| GisError::Tiff {
        path: path.to_path_buf(),
        message: "palette image without a valid ColorMap".to_string(),
    })?))
}

/// Reads band 1 of a GeoTIFF's cells meeting `window` (CRS coordinates; all cells without
/// one), decoding only the strips or tiles that hold them, from the coarsest of its
/// reduced-resolution images (a Cloud-Optimized GeoTIFF's overviews) that still has at least
/// the resolution `max_cells` cells over the window allow ([`raster::fit_factor`]). The file
/// is read through a buffered reader: strips and tiles outside the window, and levels not
/// chosen, are never read from disk. Palette and WhiteIsZero images (land covers, not DEMs)
/// are read whole and cropped.
pub fn read_geotiff_window(path: &Path, window: Option<&Extent>, max_cells: u64) -> Result<Raster, GisError> {
    let tiff_err = |e: tiff::TiffError| GisError::Tiff { path: path.to_path_buf(), message: e.to_string() };
    let file = std::fs::File::open(path).map_err(|source| GisError::Io { path: path.to_path_buf(), source })?;
    let mut reader = std::io::BufReader::new(file);
    let mut signature = [0u8; 4];
    std::io::Read::read_exact(&mut reader, &mut signature)
        .map_err(|_| GisError::NotTiff { path: path.to_path_buf() })?;
    check_signature(path, &signature)?;
    std::io::Seek::rewind(&mut reader).map_err(|source| GisError::Io { path: path.to_path_buf(), source })?;
    let mut decoder = Decoder::new(reader).map_err(tiff_err)?.with_limits(limits());
    let full = Layout::read(&mut decoder, path)?;
    raster::check_dimensions(path, full.width.into(), full.height.into())?;
    let geo = Georeference::read(&mut decoder, path, full.sample_type)?;
    let (full_w, full_h) = (full.width as usize, full.height as usize);
    let (col0, row0, width, height) = match window {
        None => (0, 0, full_w, full_h),
        Some(w) => raster::window(&geo.transform, full_w, full_h, w).ok_or_else(|| GisError::WindowOutside {
            path: path.to_path_buf(),
            window: *w,
            extent: raster::extent_of(&geo.transform, full_w, full_h),
            crs: geo.crs,
        })?,
    };
    if full.needs_patch() {
        return read_geotiff(path)?.crop(col0, row0, width, height);
    }
    // The coarsest overview at most `max_factor` coarser (image 0: the full resolution).
    let max_factor = raster::fit_factor(width, height, max_cells);
    let (mut level, mut factor) = (0usize, 1usize);
    let mut index = 0usize;
    while decoder.more_images() {
        decoder.next_image().map_err(tiff_err)?;
        index += 1;
        let subfile = decoder.find_tag_unsigned::<u32>(Tag::NewSubfileType).map_err(tiff_err)?.unwrap_or(0);
        let layout = Layout::read(&mut decoder, path)?;
        if subfile & 1 == 0 || layout.width == 0 || layout.sample_type != full.sample_type {
            continue;
        }
        let f = full_w.div_ceil(layout.width as usize);
        // An overview of a whole factor of the full grid (GDAL's: ceil(width / f) cells).
        if f > factor
            && f <= max_factor
            && (layout.height as usize) == full_h.div_ceil(f)
            && (layout.width as usize) == full_w.div_ceil(f)
        {
            (level, factor) = (index, f);
        }
    }
    decoder.seek_to_image(level).map_err(tiff_err)?;
    let layout = Layout::read(&mut decoder, path)?;
    // The window on the chosen level's grid.
    let (c0, r0) = (col0 / factor, row0 / factor);
    let (c1, r1) = (
        (col0 + width).div_ceil(factor).min(layout.width as usize),
        (row0 + height).div_ceil(factor).min(layout.height as usize),
    );
    let (w, h) = (c1 - c0, r1 - r0);
    let (chunk_w, chunk_h) = decoder.chunk_dimensions();
    let (chunk_w, chunk_h) = (chunk_w.max(1) as usize, chunk_h.max(1) as usize);
    let across = (layout.width as usize).div_ceil(chunk_w);
    let (cc0, cc1) = (c0 / chunk_w, (c1 - 1) / chunk_w);
    let (cr0, cr1) = (r0 / chunk_h, (r1 - 1) / chunk_h);
    let chunks = ((cc1 - cc0 + 1) * (cr1 - cr0 + 1)) as u64;
    let per_chunk =
        (chunk_w * chunk_h) as u64 * u64::from(layout.samples.max(1)) * u64::from(layout.bits.div_ceil(8).max(1));
    check_budget(path, chunks.saturating_mul(per_chunk))?;
    let fill = geo.nodata.unwrap_or(f64::NAN);
    let mut data = vec![fill; w * h];
    for cr in cr0..=cr1 {
        for cc in cc0..=cc1 {
            // Chunk indices of the first plane (planar images store plane 1's chunks first).
            let chunk = u32::try_from(cr * across + cc)
                .map_err(|_| GisError::Tiff { path: path.to_path_buf(), message: "too many strips or tiles".into() })?;
            let result = decoder.read_chunk(chunk).map_err(tiff_err)?;
            let (dw, dh) = decoder.chunk_data_dimensions(chunk);
            let (dw, dh) = (dw as usize, dh as usize);
            let len = result_len(&result);
            let stride = if layout.planar { 1 } else { usize::from(layout.samples.max(1)) };
            if len != dw * dh * stride {
                return Err(GisError::Tiff {
                    path: path.to_path_buf(),
                    message: format!("decoded {len} samples for a chunk of {dw} × {dh} pixels"),
                });
            }
            let values = band(&result, stride, 0);
            let (x0, y0) = (cc * chunk_w, cr * chunk_h);
            for y in y0.max(r0)..(y0 + dh).min(r1) {
                for x in x0.max(c0)..(x0 + dw).min(c1) {
                    data[(y - r0) * w + (x - c0)] = values[(y - y0) * dw + (x - x0)];
                }
            }
        }
    }
    // The level's cells span the full extent (GDAL's overviews: ceil(width / f) cells).
    let t = geo.transform;
    let cell_width = t.cell_width * full_w as f64 / f64::from(layout.width);
    let cell_height = t.cell_height * full_h as f64 / f64::from(layout.height);
    let out = Raster {
        width: w,
        height: h,
        data,
        nodata: geo.nodata,
        transform: GeoTransform {
            origin_x: t.origin_x + c0 as f64 * cell_width,
            origin_y: t.origin_y - r0 as f64 * cell_height,
            cell_width,
            cell_height,
        },
        crs: geo.crs,
        palette: None,
    };
    raster::check_not_all_nodata(path, &out)?;
    Ok(out)
}

/// The YCbCr → RGB conversion of a YCbCr GeoTIFF (TIFF 6.0 section 21; what JPEG-compressed
/// orthophotos hold: the decoder returns the JPEG stream's samples as they are).
#[derive(Debug, Clone, Copy)]
struct YCbCr {
    /// YCbCrCoefficients: the luma weights of red, green and blue (default BT.601).
    luma: [f64; 3],
    /// ReferenceBlackWhite: black and white codes of Y, Cb and Cr (default full range).
    reference: [f64; 6],
}

impl YCbCr {
    /// Reads YCbCrCoefficients (529) and ReferenceBlackWhite (532), defaults where absent.
    fn from_tags<R: std::io::Read + std::io::Seek>(decoder: &mut Decoder<R>) -> tiff::TiffResult<YCbCr> {
        let mut rationals = |tag: u16| -> tiff::TiffResult<Option<Vec<f64>>> {
            use tiff::decoder::ifd::Value;
            let Some(value) = decoder.find_tag(Tag::Unknown(tag))? else { return Ok(None) };
            let items = match value {
                Value::List(items) => items,
                one => vec![one],
            };
            Ok(items
                .into_iter()
                .map(|v| match v {
                    Value::Rational(n, d) if d != 0 => Some(f64::from(n) / f64::from(d)),
                    Value::Double(x) => Some(x),
                    Value::Float(x) => Some(f64::from(x)),
                    _ => None,
                })
                .collect())
        };
        let luma = match rationals(529)?.as_deref() {
            Some(&[r, g, b]) if r > 0.0 && g > 0.0 && b > 0.0 => [r, g, b],
            _ => [0.299, 0.587, 0.114],
        };
        let reference = match rationals(532)?.as_deref() {
            Some(&[a, b, c, d, e, f]) if b > a && d > c && f > e => [a, b, c, d, e, f],
            _ => [0.0, 255.0, 128.0, 255.0, 128.0, 255.0],
        };
        Ok(YCbCr { luma, reference })
    }

    /// Turns the bands `y`, `cb`, `cr` into red, green and blue in place (0..=255).
    fn to_rgb(self, y: &mut Raster, cb: &mut Raster, cr: &mut Raster) {
        let [lr, lg, lb] = self.luma;
        let [y0, y1, cb0, cb1, cr0, cr1] = self.reference;
        for ((y, cb), cr) in y.data.iter_mut().zip(cb.data.iter_mut()).zip(cr.data.iter_mut()) {
            let luma = (*y - y0) * 255.0 / (y1 - y0);
            let blue_diff = (*cb - cb0) * 127.0 / (cb1 - cb0);
            let red_diff = (*cr - cr0) * 127.0 / (cr1 - cr0);
            let red = red_diff * (2.0 - 2.0 * lr) + luma;
            let blue = blue_diff * (2.0 - 2.0 * lb) + luma;
            let green = (luma - lb * blue - lr * red) / lg;
            (*y, *cb, *cr) = (red.clamp(0.0, 255.0), green.clamp(0.0, 255.0), blue.clamp(0.0, 255.0));
        }
    }
}

/// The GeoKeys of a GeoTIFF as plain values (SHORT keys and DOUBLE keys), for interpreting
/// CRS parameters that [`Crs`] does not keep (see [`crate::gis::reproject`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GeoKeyValues {
    /// Keys stored as a SHORT (in the directory or GeoKeyDirectory-referenced), in file order.
    pub shorts: Vec<(u16, u16)>,
    /// Keys stored in GeoDoubleParams, in file order.
    pub doubles: Vec<(u16, Vec<f64>)>,
    /// Keys stored in GeoAsciiParams (citations), without the `|` terminator, in file order.
    pub ascii: Vec<(u16, String)>,
}

impl GeoKeyValues {
    /// The SHORT value of a key.
    pub fn short(&self, id: u16) -> Option<u16> {
        self.shorts.iter().find(|(k, _)| *k == id).map(|&(_, v)| v)
    }

    /// The first DOUBLE value of a key.
    pub fn double(&self, id: u16) -> Option<f64> {
        self.doubles(id).and_then(|d| d.first().copied())
    }

    /// All DOUBLE values of a key.
    pub fn doubles(&self, id: u16) -> Option<&[f64]> {
        self.doubles.iter().find(|(k, _)| *k == id).map(|(_, v)| v.as_slice())
    }

    /// The ASCII value of a key (e.g. a citation).
    pub fn ascii(&self, id: u16) -> Option<&str> {
        self.ascii.iter().find(|(k, _)| *k == id).map(|(_, v)| v.as_str())
    }
}

/// The GeoKeys stored in GeoAsciiParams: entries of location 34737 point at `count` bytes
/// from `offset`, ended by `|`. Entries out of range are skipped.
fn ascii_keys(dir: &[u16], ascii: &str) -> Vec<(u16, String)> {
    let count = dir.get(3).map_or(0, |&c| usize::from(c));
    dir.get(4..)
        .unwrap_or_default()
        .chunks_exact(4)
        .take(count)
        .filter(|e| e[1] == 34737)
        .filter_map(|e| {
            let (start, len) = (usize::from(e[3]), usize::from(e[2]));
            let text = ascii.get(start..start.checked_add(len)?)?;
            Some((e[0], text.trim_end_matches(['|', '\0']).to_string()))
        })
        .collect()
}

/// Reads only the GeoKeys of a GeoTIFF (empty when the file has no GeoKeyDirectory).
pub fn read_geokeys(path: &Path) -> Result<GeoKeyValues, GisError> {
    let bytes = std::fs::read(path).map_err(|source| GisError::Io { path: path.to_path_buf(), source })?;
    if !matches!(bytes.get(..4), Some(b"II*\0" | b"MM\0*" | b"II+\0" | b"MM\0+")) {
        return Err(GisError::NotTiff { path: path.to_path_buf() });
    }
    let tiff_err = |e: tiff::TiffError| GisError::Tiff { path: path.to_path_buf(), message: e.to_string() };
    let mut decoder = Decoder::new(Cursor::new(bytes.as_slice())).map_err(tiff_err)?;
    let Some(dir) = decoder.find_tag(Tag::GeoKeyDirectoryTag).map_err(tiff_err)? else {
        return Ok(GeoKeyValues::default());
    };
    let dir = dir.into_u16_vec().map_err(tiff_err)?;
    let params = match decoder.find_tag(Tag::GeoDoubleParamsTag).map_err(tiff_err)? {
        Some(v) => v.into_f64_vec().map_err(tiff_err)?,
        None => Vec::new(),
    };
    let keys = GeoKeys::parse(&dir, &params)
        .map_err(|reason| GisError::BadGeoreferencing { path: path.to_path_buf(), reason })?;
    let ascii = match decoder.find_tag(Tag::GeoAsciiParamsTag).map_err(tiff_err)? {
        Some(v) => v.into_string().map_err(tiff_err)?,
        None => String::new(),
    };
    let mut values = GeoKeyValues { ascii: ascii_keys(&dir, &ascii), ..GeoKeyValues::default() };
    for (id, v) in keys.keys {
        match v {
            KeyValue::Short(s) => values.shorts.push((id, s)),
            KeyValue::Doubles(d) => values.doubles.push((id, d)),
            KeyValue::Other => {}
        }
    }
    Ok(values)
}

/// 8-bit palette colour type for the encoder (PhotometricInterpretation RGBPalette).
struct Palette8;

impl ColorType for Palette8 {
    type Inner = u8;
    const TIFF_VALUE: PhotometricInterpretation = PhotometricInterpretation::RGBPalette;
    const BITS_PER_SAMPLE: &'static [u16] = &[8];
    const SAMPLE_FORMAT: &'static [SampleFormat] = &[SampleFormat::Uint];

    fn horizontal_predict(row: &[u8], result: &mut Vec<u8>) {
        result.extend(row.first());
        result.extend(row.windows(2).map(|w| w[1].wrapping_sub(w[0])));
    }
}

/// The GeoKeyDirectory (and GeoDoubleParams) describing a CRS; `None` for unspecified.
fn geokeys_for(crs: &Crs) -> Option<(Vec<u16>, Vec<f64>)> {
    let mut keys: Vec<[u16; 4]> = Vec::new();
    let mut doubles = Vec::new();
    let short = |id: u16, v: u16| [id, 0, 1, v];
    let epsg16 = |code: Option<u32>| code.and_then(|c| u16::try_from(c).ok());
    match *crs {
        Crs::Unspecified => return None,
        Crs::Geographic { epsg } => {
            keys.push(short(key::MODEL_TYPE, MODEL_GEOGRAPHIC));
            keys.push(short(key::RASTER_TYPE, RASTER_PIXEL_IS_AREA));
            if let Some(code) = epsg16(epsg) {
                keys.push(short(key::GEOGRAPHIC_TYPE, code));
            }
        }
        Crs::Projected { epsg, unit_to_metre } => {
            keys.push(short(key::MODEL_TYPE, MODEL_PROJECTED));
            keys.push(short(key::RASTER_TYPE, RASTER_PIXEL_IS_AREA));
            if let Some(code) = epsg16(epsg) {
                keys.push(short(key::PROJECTED_CS_TYPE, code));
            }
            let unit =
                [(1.0, UNIT_METRE), (FOOT, UNIT_FOOT), (US_SURVEY_FOOT, UNIT_US_SURVEY_FOOT), (1000.0, UNIT_KILOMETRE)]
                    .iter()
                    .find(|(m, _)| (m - unit_to_metre).abs() <= 1e-12 * m)
                    .map(|&(_, code)| code);
            match unit {
                Some(code) => keys.push(short(key::PROJ_LINEAR_UNITS, code)),
                None => {
                    keys.push(short(key::PROJ_LINEAR_UNITS, USER_DEFINED));
                    keys.push([key::PROJ_LINEAR_UNIT_SIZE, 34736, 1, 0]);
                    doubles.push(unit_to_metre);
                }
            }
        }
    }
    // A handful of keys, so the count fits in u16.
    let mut dir = vec![1, 1, 0, keys.len() as u16];
    dir.extend(keys.iter().flatten());
    Some((dir, doubles))
}

/// Encodes `data` as a single-band strip GeoTIFF of colour type `C` into memory.
fn encode<C: ColorType>(
    raster: &Raster,
    data: &[C::Inner],
    nodata: Option<String>,
    colormap: Option<Vec<u16>>,
) -> tiff::TiffResult<Vec<u8>>
where
    [C::Inner]: TiffValue,
{
    let width = u32::try_from(raster.width)?;
    let height = u32::try_from(raster.height)?;
    let mut buffer = Cursor::new(Vec::new());
    {
        let mut tiff = TiffEncoder::new(&mut buffer)?.with_compression(Compression::Deflate(DeflateLevel::Balanced));
        let mut image = tiff.new_image::<C>(width, height)?;
        let dir = image.encoder();
        let t = &raster.transform;
        dir.write_tag(Tag::ModelPixelScaleTag, &[t.cell_width, t.cell_height, 0.0][..])?;
        dir.write_tag(Tag::ModelTiepointTag, &[0.0, 0.0, 0.0, t.origin_x, t.origin_y, 0.0][..])?;
        if let Some((keys, doubles)) = geokeys_for(&raster.crs) {
            dir.write_tag(Tag::GeoKeyDirectoryTag, &keys[..])?;
            if !doubles.is_empty() {
                dir.write_tag(Tag::GeoDoubleParamsTag, &doubles[..])?;
            }
        }
        if let Some(text) = &nodata {
            dir.write_tag(Tag::GdalNodata, text.as_str())?;
        }
        if let Some(map) = &colormap {
            dir.write_tag(Tag::ColorMap, &map[..])?;
        }
        image.write_data(data)?;
    }
    Ok(buffer.into_inner())
}

/// Checks the data length and writes encoded bytes to `path`.
fn finish_write(path: &Path, encoded: tiff::TiffResult<Vec<u8>>) -> Result<(), GisError> {
    let write_err = |message: String| GisError::Write { path: path.to_path_buf(), message };
    let bytes = encoded.map_err(|e| write_err(e.to_string()))?;
    std::fs::write(path, bytes).map_err(|e| write_err(e.to_string()))
}

/// Checks that `raster.data` holds `width × height` values.
fn check_data_len(path: &Path, raster: &Raster) -> Result<(), GisError> {
    let expected = raster.width.checked_mul(raster.height);
    if expected != Some(raster.data.len()) || raster.data.is_empty() {
        return Err(GisError::Write {
            path: path.to_path_buf(),
            message: format!(
                "raster holds {} values for {} × {} cells",
                raster.data.len(),
                raster.width,
                raster.height
            ),
        });
    }
    Ok(())
}

/// Writes an 8-bit GeoTIFF. Valid cells must be integers in 0..=255; nodata (and NaN) cells
/// are written as the raster's nodata value, which must then be such an integer too. With a
/// palette (at most 256 entries) the file is a palette image with that ColorMap.
pub fn write_geotiff_u8(path: &Path, raster: &Raster, palette: Option<&[[u8; 3]]>) -> Result<(), GisError> {
    check_data_len(path, raster)?;
    let write_err = |message: String| GisError::Write { path: path.to_path_buf(), message };
    let as_u8 = |v: f64| (v.fract() == 0.0 && (0.0..=255.0).contains(&v)).then_some(v as u8);
    let nodata = match raster.nodata {
        Some(v) if !v.is_nan() => {
            Some(as_u8(v).ok_or_else(|| write_err(format!("nodata value {v} does not fit an 8-bit unsigned cell")))?)
        }
        _ => None,
    };
    let mut data = Vec::with_capacity(raster.data.len());
    for (i, &v) in raster.data.iter().enumerate() {
        let cell = if raster.is_valid(v) { as_u8(v) } else { nodata };
        data.push(cell.ok_or_else(|| {
            write_err(format!(
                "cell (column {}, row {}) value {v} does not fit an 8-bit unsigned cell",
                i % raster.width,
                i / raster.width
            ))
        })?);
    }
    let nodata_text = nodata.map(|n| n.to_string());
    let encoded = match palette {
        Some(p) => {
            if p.is_empty() || p.len() > 256 {
                return Err(write_err(format!("palette has {} entries (1 to 256 allowed)", p.len())));
            }
            let mut map = vec![0u16; 3 * 256];
            for (i, rgb) in p.iter().enumerate() {
                for (channel, &c) in rgb.iter().enumerate() {
                    map[channel * 256 + i] = u16::from(c) * 257;
                }
            }
            encode::<Palette8>(raster, &data, nodata_text, Some(map))
        }
        None => encode::<Gray8>(raster, &data, nodata_text, None),
    };
    finish_write(path, encoded)
}

/// Writes an RGB GeoTIFF of 16-bit samples (pixel-interleaved; an orthophoto as survey
/// agencies deliver it) from three bands on `bands[0]`'s grid; values are clamped to
/// 0..65535 and nodata cells written as 0.
pub fn write_geotiff_rgb16(path: &Path, bands: &[Raster; 3]) -> Result<(), GisError> {
    for band in bands {
        check_data_len(path, band)?;
    }
    let sample = |band: &Raster, i: usize| {
        let v = band.data.get(i).copied().filter(|&v| band.is_valid(v)).unwrap_or(0.0);
        v.clamp(0.0, 65535.0).round() as u16
    };
    let data: Vec<u16> = (0..bands[0].data.len()).flat_map(|i| bands.iter().map(move |b| sample(b, i))).collect();
    finish_write(path, encode::<RGB16>(&bands[0], &data, None, None))
}

/// Writes a 32-bit float GeoTIFF. Nodata cells are written as the nodata value (as `f32`), or
/// NaN if the raster has none.
pub fn write_geotiff_f32(path: &Path, raster: &Raster) -> Result<(), GisError> {
    check_data_len(path, raster)?;
    let fill = raster.nodata.map_or(f32::NAN, |v| v as f32);
    let data: Vec<f32> = raster.data.iter().map(|&v| if raster.is_valid(v) { v as f32 } else { fill }).collect();
    let nodata_text = raster.nodata.map(|v| {
        let v = v as f32;
        if v.is_nan() { "nan".to_string() } else { v.to_string() }
    });
    finish_write(path, encode::<Gray32Float>(raster, &data, nodata_text, None))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_types() {
        assert_eq!(SampleType::from_tags(1, 8), Ok(SampleType::U8));
        assert_eq!(SampleType::from_tags(2, 16), Ok(SampleType::I16));
        assert_eq!(SampleType::from_tags(3, 64), Ok(SampleType::F64));
        let err = SampleType::from_tags(6, 64).unwrap_err();
        assert!(err.contains("complex float"), "{err}");
        assert!(SampleType::from_tags(1, 1).unwrap_err().contains("1-bit"));
        assert!(SampleType::from_tags(3, 16).is_err());
        assert!(SampleType::from_tags(1, 64).is_err());
    }

    #[test]
    fn geokeys_user_defined_projection_and_units() {
        let dir = [
            1, 1, 0, 4, //
            1024, 0, 1, 1, //
            1025, 0, 1, 2, //
            3072, 0, 1, 32767, //
            3076, 0, 1, 9003,
        ];
        let keys = GeoKeys::parse(&dir, &[]).unwrap();
        assert!(keys.pixel_is_point());
        assert_eq!(keys.crs().unwrap(), Crs::Projected { epsg: None, unit_to_metre: US_SURVEY_FOOT });
        let dir = [1, 1, 0, 2, 1024, 0, 1, 1, 3076, 0, 1, 32767];
        assert!(GeoKeys::parse(&dir, &[]).unwrap().crs().is_err());
        let dir = [1, 1, 0, 3, 1024, 0, 1, 1, 3076, 0, 1, 32767, 3077, 34736, 1, 1];
        assert_eq!(
            GeoKeys::parse(&dir, &[0.0, 2.5]).unwrap().crs().unwrap(),
            Crs::Projected { epsg: None, unit_to_metre: 2.5 }
        );
        assert!(GeoKeys::parse(&[1, 1, 0, 2, 1024, 0, 1, 1], &[]).is_err());
        assert!(GeoKeys::parse(&[1, 1], &[]).is_err());
        assert_eq!(GeoKeys::parse(&[1, 1, 0, 0], &[]).unwrap().crs().unwrap(), Crs::Unspecified);
    }

    #[test]
    fn geokeys_written_are_read_back() {
        for crs in [
            Crs::Geographic { epsg: Some(4326) },
            Crs::Geographic { epsg: None },
            Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
            Crs::Projected { epsg: None, unit_to_metre: FOOT },
            Crs::Projected { epsg: None, unit_to_metre: 1.7 },
        ] {
            let (dir, doubles) = geokeys_for(&crs).unwrap();
            assert_eq!(GeoKeys::parse(&dir, &doubles).unwrap().crs().unwrap(), crs);
        }
        assert!(geokeys_for(&Crs::Unspecified).is_none());
    }

    #[test]
    fn transforms() {
        let t = transform_from_tags(Some(&[0.0, 0.0, 0.0, 10.0, 20.0, 0.0]), Some(&[2.0, 3.0, 0.0]), None, false)
            .unwrap()
            .unwrap();
        assert_eq!((t.origin_x, t.origin_y, t.cell_width, t.cell_height), (10.0, 20.0, 2.0, 3.0));
        // Tiepoint at pixel (1, 2), PixelIsPoint.
        let t = transform_from_tags(Some(&[1.0, 2.0, 0.0, 10.0, 20.0, 0.0]), Some(&[2.0, 3.0, 0.0]), None, true)
            .unwrap()
            .unwrap();
        assert_eq!((t.origin_x, t.origin_y), (10.0 - 2.0 - 1.0, 20.0 + 6.0 + 1.5));
        let m = [
            2.0, 0.0, 0.0, 10.0, //
            0.0, -3.0, 0.0, 20.0, //
            0.0, 0.0, 0.0, 0.0, //
            0.0, 0.0, 0.0, 1.0,
        ];
        let t = transform_from_tags(None, None, Some(&m), false).unwrap().unwrap();
        assert_eq!((t.origin_x, t.origin_y, t.cell_width, t.cell_height), (10.0, 20.0, 2.0, 3.0));
        let mut rotated = m;
        rotated[1] = 0.1;
        assert!(transform_from_tags(None, None, Some(&rotated), false).is_err());
        let mut south_up = m;
        south_up[5] = 3.0;
        assert!(transform_from_tags(None, None, Some(&south_up), false).is_err());
        assert_eq!(transform_from_tags(None, Some(&[1.0, 1.0, 0.0]), None, false), Ok(None));
        assert!(transform_from_tags(Some(&[0.0; 12]), None, None, false).is_err());
    }

    #[test]
    fn palette_scaling_and_nodata_text() {
        let mut map = vec![0u16; 6];
        map[0] = 65535;
        map[3] = 71 * 257;
        map[5] = 128;
        assert_eq!(palette_from_colormap(&map, 1), Some(vec![[255, 0, 0], [0, 71, 0]]));
        assert_eq!(palette_from_colormap(&map, 2), None);
        assert_eq!(parse_nodata("-9999\0"), Some(-9999.0));
        assert!(parse_nodata(" nan ").is_some_and(f64::is_nan));
        assert_eq!(parse_nodata("none"), None);
    }

    #[test]
    fn patching_rejects_garbage() {
        assert_eq!(with_black_is_zero(b"II*\0", 8), None);
        assert_eq!(with_black_is_zero(b"", 0), None);
        assert_eq!(with_black_is_zero(b"II*\0\x08\0\0\0\xff\xff", 8), None);
    }
}
