//! NetCDF-3 (classic and 64-bit offset) fields with the pure-Rust `netcdf3` crate, following
//! the CF conventions as far as gridded data needs them:
//!
//! - the variable: [`LoadOptions::variable`], or the only variable whose last two dimensions
//!   are gridded (y, x) coordinate axes; any leading dimensions must have size 1 except one,
//!   the time axis;
//! - coordinates: 1-D coordinate variables (same name as their dimension), evenly spaced;
//!   latitude/longitude axes (by `units` `degrees_north`/`degrees_east`, `standard_name` or
//!   name) give WGS 84 lon/lat; other x/y axes need a `grid_mapping` of
//!   `latitude_longitude` or `transverse_mercator`, or a CRS in the options. Rows whose
//!   latitude (y) increases with the index (south-up) are flipped so that row 0 is north;
//!   longitudes all ≥ 180° are shifted by −360°;
//! - values: `_FillValue` and `missing_value` (or the NetCDF default fill when neither is set)
//!   and values outside `valid_min`/`valid_max`/`valid_range` are nodata; `scale_factor` and
//!   `add_offset` are applied; `units` becomes the field's units;
//! - time: a coordinate variable with CF units `<days|hours|minutes|seconds> since <date>` and
//!   calendar `standard`, `gregorian` or `proleptic_gregorian` (proleptic Gregorian; standard
//!   dates before 1582-10-15 are rejected). Other calendars (`noleap`, `360_day`, …) are
//!   rejected.

use std::io::Cursor;

use chrono::{DateTime, NaiveDate, NaiveDateTime, TimeDelta, Utc};
use netcdf3::{DataType, DataVector, FileReader, Variable};

use super::FieldError;
use super::field::{Field, FieldStep};
use super::source::LoadOptions;
use crate::gis::{CrsDefinition, GeoTransform, Raster};

/// The grid axis a dimension stands for.
#[derive(Debug, Clone, PartialEq)]
struct Axis {
    /// Cell centre coordinates in file order.
    coords: Vec<f64>,
    /// Whether this is a latitude or longitude axis.
    geographic: bool,
}

/// Reads a field from the bytes of a NetCDF-3 file; `name` is used in messages.
pub fn read_netcdf(bytes: &[u8], name: &str, opts: &LoadOptions) -> Result<Field, FieldError> {
    let err = |message: String| FieldError::Format { context: name.to_string(), message };
    check_header(bytes).map_err(|m| err(format!("malformed NetCDF-3 header: {m}")))?;
    let open = || {
        FileReader::open_seek_read(name, Box::new(Cursor::new(bytes.to_vec())))
            .map_err(|e| err(format!("not a readable NetCDF-3 file: {e}")))
    };
    // The header as owned data (the reader's is borrowed while reading values).
    let (data_set, _version) = open()?.close();
    let mut reader = open()?;

    let candidates: Vec<&Variable> = data_set.get_vars().into_iter().filter(|v| is_gridded(&data_set, v)).collect();
    let names = || candidates.iter().map(|v| v.name().to_string()).collect::<Vec<_>>().join(", ");
    let var = match opts.variable.as_deref() {
        Some(wanted) => *candidates.iter().find(|v| v.name() == wanted).ok_or_else(|| {
            FieldError::Invalid(format!(
                "{}: no gridded variable \"{}\" (gridded variables: {})",
                crate::echo::echo(name),
                crate::echo::echo(wanted),
                names()
            ))
        })?,
        None => match candidates.as_slice() {
            [only] => *only,
            [] => return Err(err("no gridded variable (with latitude/longitude or y/x coordinate axes)".into())),
            _ => {
                return Err(FieldError::Invalid(format!(
                    "{name}: several gridded variables, choose one with variable=… ({})",
                    names()
                )));
            }
        },
    };
    let var_name = var.name().to_string();
    let dims = var.get_dims();
    let (leading, grid_dims) = dims.split_at(dims.len() - 2);
    let (ny, nx) = (grid_dims[0].size(), grid_dims[1].size());
    let cells = (ny as u64).saturating_mul(nx as u64);
    if cells > opts.max_cells {
        return Err(FieldError::TooLarge {
            what: format!("{name}: grid of {nx} × {ny} cells"),
            size: cells,
            limit: opts.max_cells,
        });
    }
    let long_axes: Vec<_> = leading.iter().filter(|d| d.size() != 1).collect();
    if long_axes.len() > 1 {
        return Err(err(format!("variable {var_name} has more than one non-grid dimension longer than 1")));
    }
    let time_dim = long_axes.first().map(|d| d.name()).or_else(|| {
        leading.iter().map(|d| d.name()).find(|n| {
            data_set.get_var(n).and_then(|v| v.get_attr_as_string("units")).is_some_and(|u| u.contains(" since "))
        })
    });
    let n_steps = leading.iter().map(|d| d.size()).product::<usize>();
    if n_steps == 0 {
        return Err(err(format!("variable {var_name} has no time steps (a dimension of size 0)")));
    }
    if n_steps > opts.max_steps {
        return Err(FieldError::TooLarge {
            what: format!("{name}: time axis"),
            size: n_steps as u64,
            limit: opts.max_steps as u64,
        });
    }
    let type_size = match var.data_type() {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 => 2,
        DataType::I32 | DataType::F32 => 4,
        DataType::F64 => 8,
    };
    let total_bytes = cells.saturating_mul(n_steps as u64).saturating_mul(type_size);
    if total_bytes > bytes.len() as u64 {
        return Err(err(format!(
            "file is truncated: variable {var_name} needs {total_bytes} bytes, the file has {}",
            bytes.len()
        )));
    }

    // Coordinates and CRS.
    let y = read_axis(&mut reader, &grid_dims[0].name(), name)?;
    let x = read_axis(&mut reader, &grid_dims[1].name(), name)?;
    let (mut x, y) = (x, y);
    let crs = match &opts.crs {
        Some(given) => given.clone(),
        None if x.geographic && y.geographic => CrsDefinition::wgs84(),
        None => grid_mapping(&data_set, var, name)?,
    };
    if crs.is_geographic() && x.coords.iter().all(|&lon| lon >= 180.0) {
        x.coords.iter_mut().for_each(|lon| *lon -= 360.0);
    }
    let (x0, dx) = spacing(&x.coords, &grid_dims[1].name(), name)?;
    let (y0, dy) = spacing(&y.coords, &grid_dims[0].name(), name)?;
    if dx <= 0.0 {
        return Err(err(format!("x axis {} must increase with the index", grid_dims[1].name())));
    }
    let south_up = dy > 0.0;
    let top = if south_up { y0 + (ny as f64 - 0.5) * dy } else { y0 - 0.5 * dy };
    let transform = GeoTransform { origin_x: x0 - 0.5 * dx, origin_y: top, cell_width: dx, cell_height: dy.abs() };

    // Times.
    let times: Vec<Option<DateTime<Utc>>> = match &time_dim {
        Some(dim) => {
            if opts.time.is_some() {
                return Err(FieldError::Invalid(format!(
                    "{name}: the file has its own time axis ({dim}); do not give a time"
                )));
            }
            read_times(&mut reader, dim, name)?.into_iter().map(Some).collect()
        }
        None => vec![opts.time.as_deref().map(super::parse_time).transpose()?],
    };
    if times.len() != n_steps {
        return Err(err(format!("time axis has {} values for {n_steps} steps", times.len())));
    }

    // Values.
    let mask = ValueMask::of(var);
    let slab = ny * nx;
    let whole = if var.is_record_var() {
        None
    } else {
        Some(to_f64(reader.read_var(&var_name).map_err(|e| err(format!("cannot read {var_name}: {e}")))?))
    };
    let mut steps = Vec::with_capacity(n_steps);
    for (k, time) in times.into_iter().enumerate() {
        let raw = match &whole {
            Some(all) => all
                .get(k * slab..(k + 1) * slab)
                .map(<[f64]>::to_vec)
                .ok_or_else(|| err(format!("{var_name} is shorter than its dimensions")))?,
            None => to_f64(
                reader.read_record(&var_name, k).map_err(|e| err(format!("cannot read {var_name} step {k}: {e}")))?,
            ),
        };
        if raw.len() != slab {
            return Err(err(format!("{var_name} step {k} holds {} values for {nx} × {ny} cells", raw.len())));
        }
        let mut data: Vec<f64> = raw.into_iter().map(|v| mask.apply(v)).collect();
        if south_up {
            let flipped: Vec<f64> = data.chunks_exact(nx).rev().flatten().copied().collect();
            data = flipped;
        }
        let raster = Raster { width: nx, height: ny, data, nodata: None, transform, crs: crs.crs(), palette: None };
        if raster.valid_count() == 0 {
            let when = time.map(|t| super::format_time(&t)).unwrap_or_default();
            return Err(err(format!("{var_name} at step {k} {when} has no valid cell (all fill values)")));
        }
        steps.push(FieldStep { time, raster });
    }
    let units =
        opts.units.clone().or_else(|| var.get_attr_as_string("units").map(|u| u.trim_matches('\0').to_string()));
    Field::new(opts.kind, crs, units, steps)
}

/// Walks the NetCDF-3 header (classic or 64-bit offset) and checks every count against the
/// bytes that remain, so that a corrupt or hostile header cannot make the `netcdf3` parser
/// reserve gigabytes before it notices the file is too short.
fn check_header(bytes: &[u8]) -> Result<(), String> {
    struct Cursor<'a> {
        b: &'a [u8],
        pos: usize,
    }
    impl Cursor<'_> {
        fn u32(&mut self) -> Result<u32, String> {
            let v = self.b.get(self.pos..self.pos + 4).ok_or("header is truncated")?;
            self.pos += 4;
            Ok(u32::from_be_bytes([v[0], v[1], v[2], v[3]]))
        }
        fn remaining(&self) -> u64 {
            self.b.len().saturating_sub(self.pos) as u64
        }
        /// Skips `n` items of `size` bytes, padded to 4 bytes.
        fn skip(&mut self, n: u64, size: u64) -> Result<(), String> {
            let len = n.checked_mul(size).ok_or("count overflows")?.div_ceil(4) * 4;
            if len > self.remaining() {
                return Err(format!("{n} values of {size} bytes do not fit in the file"));
            }
            // len ≤ remaining, which fits in usize.
            self.pos += len as usize;
            Ok(())
        }
        /// A list header: ABSENT (two zeros) or `tag` followed by a count that fits the file
        /// at `min_item` bytes per item.
        fn list(&mut self, tag: u32, min_item: u64) -> Result<u64, String> {
            let (t, n) = (self.u32()?, u64::from(self.u32()?));
            if t == 0 && n == 0 {
                return Ok(0);
            }
            if t != tag {
                return Err(format!("expected list tag {tag:#x}, found {t:#x}"));
            }
            if n.saturating_mul(min_item) > self.remaining() {
                return Err(format!("list of {n} entries does not fit in the file"));
            }
            Ok(n)
        }
        fn name(&mut self) -> Result<(), String> {
            let n = u64::from(self.u32()?);
            self.skip(n, 1)
        }
        fn attributes(&mut self) -> Result<(), String> {
            for _ in 0..self.list(0x0C, 12)? {
                self.name()?;
                let size = match self.u32()? {
                    1 | 2 => 1,
                    3 => 2,
                    4 | 5 => 4,
                    6 => 8,
                    t => return Err(format!("unknown attribute type {t}")),
                };
                let n = u64::from(self.u32()?);
                self.skip(n, size)?;
            }
            Ok(())
        }
    }
    let version = match bytes.get(..4) {
        Some(b"CDF\x01") => 1,
        Some(b"CDF\x02") => 2,
        Some(b"CDF\x05") => {
            return Err("CDF-5 (64-bit data) files are not supported; use classic or 64-bit offset".into());
        }
        _ => return Err("not a NetCDF-3 file".into()),
    };
    let mut c = Cursor { b: bytes, pos: 4 };
    c.u32()?; // numrecs (or STREAMING)
    for _ in 0..c.list(0x0A, 8)? {
        c.name()?;
        c.u32()?;
    }
    c.attributes()?;
    for _ in 0..c.list(0x0B, 24)? {
        c.name()?;
        let dims = u64::from(c.u32()?);
        c.skip(dims, 4)?;
        c.attributes()?;
        c.u32()?; // nc_type
        c.u32()?; // vsize
        c.skip(1, if version == 1 { 4 } else { 8 })?; // begin
    }
    Ok(())
}

/// Whether a variable is a numeric grid: at least 2 dimensions, the last two with coordinate
/// variables, and not itself a coordinate or bounds variable.
fn is_gridded(ds: &netcdf3::DataSet, v: &Variable) -> bool {
    let dims = v.dim_names();
    if dims.len() < 2 || v.data_type() == DataType::U8 || dims.contains(&v.name().to_string()) {
        return false;
    }
    dims[dims.len() - 2..].iter().all(|d| ds.get_var(d).is_some_and(|c| c.num_dims() == 1 && c.dim_names()[0] == *d))
}

/// Reads a 1-D coordinate variable and decides whether it is latitude/longitude.
fn read_axis(reader: &mut FileReader, dim: &str, name: &str) -> Result<Axis, FieldError> {
    let var = reader.data_set().get_var(dim).cloned().ok_or_else(|| FieldError::Format {
        context: name.to_string(),
        message: format!("dimension {dim} has no coordinate variable"),
    })?;
    let coords = to_f64(reader.read_var(dim).map_err(|e| FieldError::Format {
        context: name.to_string(),
        message: format!("cannot read coordinate {dim}: {e}"),
    })?);
    let attr =
        |a: &str| var.get_attr_as_string(a).map(|s| s.trim_matches('\0').to_ascii_lowercase()).unwrap_or_default();
    let units = attr("units");
    let standard = attr("standard_name");
    let lower = dim.to_ascii_lowercase();
    let geographic = units.starts_with("degree")
        || matches!(standard.as_str(), "latitude" | "longitude")
        || matches!(lower.as_str(), "lat" | "latitude" | "lon" | "long" | "longitude");
    Ok(Axis { coords, geographic })
}

/// First centre and signed spacing of an evenly spaced axis.
fn spacing(coords: &[f64], dim: &str, name: &str) -> Result<(f64, f64), FieldError> {
    let err = |message: String| FieldError::Format { context: name.to_string(), message };
    let (&first, &last) = coords.first().zip(coords.last()).ok_or_else(|| err(format!("axis {dim} is empty")))?;
    if coords.len() < 2 {
        return Err(err(format!("axis {dim} has a single value; its cell size is unknown")));
    }
    let step = (last - first) / (coords.len() - 1) as f64;
    let tolerance = 1e-3 * step.abs();
    let even = coords.windows(2).all(|w| ((w[1] - w[0]) - step).abs() <= tolerance);
    if !step.is_finite() || step == 0.0 || !even {
        return Err(err(format!("axis {dim} is not evenly spaced (only regular grids are supported)")));
    }
    Ok((first, step))
}

/// The CRS of a variable's CF `grid_mapping` (latitude_longitude or transverse_mercator).
fn grid_mapping(ds: &netcdf3::DataSet, var: &Variable, name: &str) -> Result<CrsDefinition, FieldError> {
    let missing = || {
        FieldError::Crs(crate::gis::ReprojectError::Unsupported {
            crs: format!("{name}: x/y axes"),
            reason: "the grid is not lat/lon and has no supported grid_mapping; give a CRS".into(),
        })
    };
    let mapping_name = var.get_attr_as_string("grid_mapping").ok_or_else(missing)?;
    let mapping = ds.get_var(mapping_name.trim_matches('\0').trim()).ok_or_else(missing)?;
    let num = |a: &str| mapping.get_attr(a).and_then(|attr| attr_f64(attr).first().copied());
    let kind = mapping.get_attr_as_string("grid_mapping_name").unwrap_or_default();
    let ellipsoid = match (num("semi_major_axis"), num("inverse_flattening")) {
        (Some(a), Some(rf)) if a > 0.0 && rf > 0.0 => format!("+a={a} +rf={rf} +towgs84=0,0,0"),
        _ => "+datum=WGS84".to_string(),
    };
    let proj = match kind.trim_matches('\0') {
        "latitude_longitude" => format!("+proj=longlat {ellipsoid} +no_defs"),
        "transverse_mercator" => format!(
            "+proj=tmerc +lat_0={} +lon_0={} +k={} +x_0={} +y_0={} {ellipsoid} +units=m +no_defs",
            num("latitude_of_projection_origin").unwrap_or(0.0),
            num("longitude_of_central_meridian").ok_or_else(missing)?,
            num("scale_factor_at_central_meridian").unwrap_or(1.0),
            num("false_easting").unwrap_or(0.0),
            num("false_northing").unwrap_or(0.0),
        ),
        _ => return Err(missing()),
    };
    Ok(CrsDefinition::from_proj_string(&proj)?)
}

/// Reads a CF time coordinate as UTC times.
fn read_times(reader: &mut FileReader, dim: &str, name: &str) -> Result<Vec<DateTime<Utc>>, FieldError> {
    let var = reader.data_set().get_var(dim).cloned().ok_or_else(|| FieldError::Format {
        context: name.to_string(),
        message: format!("time dimension {dim} has no coordinate variable with CF units"),
    })?;
    let units = var.get_attr_as_string("units").unwrap_or_default();
    let units = units.trim_matches('\0');
    let calendar =
        var.get_attr_as_string("calendar").unwrap_or_else(|| "standard".into()).trim_matches('\0').to_ascii_lowercase();
    let values = to_f64(reader.read_var(dim).map_err(|e| FieldError::Format {
        context: name.to_string(),
        message: format!("cannot read time coordinate {dim}: {e}"),
    })?);
    values.iter().map(|&v| cf_time(v, units, &calendar)).collect()
}

/// One CF time value: `value` `unit`s after the reference date of `units`.
pub fn cf_time(value: f64, units: &str, calendar: &str) -> Result<DateTime<Utc>, FieldError> {
    let err = |reason: String| FieldError::Time { text: format!("{value} {units}"), reason };
    if !matches!(calendar, "standard" | "gregorian" | "proleptic_gregorian") {
        return Err(err(format!(
            "calendar \"{calendar}\" is not supported (standard, gregorian, proleptic_gregorian)"
        )));
    }
    let (unit, reference) =
        units.split_once(" since ").ok_or_else(|| err("time units must read \"<unit> since <date>\"".into()))?;
    let seconds = match unit.trim().to_ascii_lowercase().as_str() {
        "days" | "day" | "d" => 86_400.0,
        "hours" | "hour" | "hr" | "h" => 3_600.0,
        "minutes" | "minute" | "min" => 60.0,
        "seconds" | "second" | "sec" | "s" => 1.0,
        other => return Err(err(format!("time unit \"{other}\" is not supported (days, hours, minutes, seconds)"))),
    };
    let base = cf_reference(reference.trim())
        .ok_or_else(|| err(format!("reference date \"{reference}\" is not understood")))?;
    let millis = value * seconds * 1000.0;
    if !millis.is_finite() || millis.abs() > 1.0e16 {
        return Err(err("time value is out of range".into()));
    }
    // |millis| ≤ 1e16 fits in i64.
    let t = base
        .checked_add_signed(TimeDelta::milliseconds(millis.round() as i64))
        .ok_or_else(|| err("time value is out of range".into()))?;
    let gregorian_start =
        NaiveDate::from_ymd_opt(1582, 10, 15).and_then(|d| d.and_hms_opt(0, 0, 0)).map(|d| d.and_utc());
    if calendar != "proleptic_gregorian" && gregorian_start.is_some_and(|g| t < g) {
        return Err(err("dates before 1582-10-15 in the mixed Julian/Gregorian calendar are not supported".into()));
    }
    Ok(t)
}

/// A CF reference date: `1950-01-01`, `1950-1-1 00:00:00`, `1950-01-01T00:00:00Z`,
/// `1950-01-01 00:00:00.0 UTC`, optionally with a `+hh:mm` offset.
fn cf_reference(text: &str) -> Option<DateTime<Utc>> {
    let text = text.trim_end_matches(" UTC").trim_end_matches('Z').trim();
    let (date, rest) = text.split_once([' ', 'T']).unwrap_or((text, ""));
    let mut ymd = date.splitn(3, '-');
    let (y, m, d) = (ymd.next()?.parse().ok()?, ymd.next()?.parse().ok()?, ymd.next().unwrap_or("1").parse().ok()?);
    let day = NaiveDate::from_ymd_opt(y, m, d)?;
    let rest = rest.trim();
    let (clock, offset_minutes) = match rest.find(['+', '-']) {
        Some(i) => {
            let (clock, off) = rest.split_at(i);
            let sign = if off.starts_with('-') { -1 } else { 1 };
            let mut hm = off[1..].split(':');
            let h: i64 = hm.next()?.trim().parse().ok()?;
            let mi: i64 = hm.next().map_or(Some(0), |s| s.trim().parse().ok())?;
            (clock.trim(), sign * (h * 60 + mi))
        }
        None => (rest, 0),
    };
    let mut hms = clock.split(':').filter(|s| !s.is_empty());
    let h: u32 = hms.next().map_or(Some(0), |s| s.parse().ok())?;
    let mi: u32 = hms.next().map_or(Some(0), |s| s.parse().ok())?;
    let s: f64 = hms.next().map_or(Some(0.0), |s| s.parse().ok())?;
    if !(0.0..61.0).contains(&s) {
        return None;
    }
    // 0 ≤ s < 61, so the casts are exact enough and in range.
    let naive: NaiveDateTime = day.and_hms_milli_opt(h, mi, s.trunc() as u32, (s.fract() * 1000.0).round() as u32)?;
    naive.and_utc().checked_sub_signed(TimeDelta::minutes(offset_minutes))
}

/// Fill, missing and valid-range handling plus unpacking of one variable.
#[derive(Debug, Clone)]
struct ValueMask {
    /// Raw values that mean nodata.
    fill: Vec<f64>,
    /// Valid raw range, inclusive.
    valid: (f64, f64),
    scale: f64,
    offset: f64,
}

impl ValueMask {
    fn of(var: &Variable) -> ValueMask {
        let values = |a: &str| var.get_attr(a).map(attr_f64).unwrap_or_default();
        let mut fill = values("_FillValue");
        fill.extend(values("missing_value"));
        if fill.is_empty() {
            fill.push(match var.data_type() {
                DataType::I8 => f64::from(netcdf3::NC_FILL_I8),
                DataType::U8 => f64::from(netcdf3::NC_FILL_U8),
                DataType::I16 => f64::from(netcdf3::NC_FILL_I16),
                DataType::I32 => f64::from(netcdf3::NC_FILL_I32),
                DataType::F32 => f64::from(netcdf3::NC_FILL_F32),
                DataType::F64 => netcdf3::NC_FILL_F64,
            });
        }
        let range = values("valid_range");
        let lo = range.first().copied().or_else(|| values("valid_min").first().copied()).unwrap_or(f64::NEG_INFINITY);
        let hi = range.get(1).copied().or_else(|| values("valid_max").first().copied()).unwrap_or(f64::INFINITY);
        let scale = values("scale_factor").first().copied().unwrap_or(1.0);
        let offset = values("add_offset").first().copied().unwrap_or(0.0);
        ValueMask { fill, valid: (lo, hi), scale, offset }
    }

    /// The unpacked value, NaN for nodata.
    fn apply(&self, raw: f64) -> f64 {
        if raw.is_nan() || self.fill.contains(&raw) || raw < self.valid.0 || raw > self.valid.1 {
            return f64::NAN;
        }
        let v = raw * self.scale + self.offset;
        if v.is_finite() { v } else { f64::NAN }
    }
}

/// Numeric attribute values as `f64` (empty for text).
fn attr_f64(attr: &netcdf3::Attribute) -> Vec<f64> {
    if let Some(v) = attr.get_f64() {
        v.to_vec()
    } else if let Some(v) = attr.get_f32() {
        v.iter().map(|&x| f64::from(x)).collect()
    } else if let Some(v) = attr.get_i32() {
        v.iter().map(|&x| f64::from(x)).collect()
    } else if let Some(v) = attr.get_i16() {
        v.iter().map(|&x| f64::from(x)).collect()
    } else if let Some(v) = attr.get_i8() {
        v.iter().map(|&x| f64::from(x)).collect()
    } else {
        Vec::new()
    }
}

/// Any numeric data vector as `f64` (text bytes as their codes).
fn to_f64(v: DataVector) -> Vec<f64> {
    match v {
        DataVector::I8(d) => d.into_iter().map(f64::from).collect(),
        DataVector::U8(d) => d.into_iter().map(f64::from).collect(),
        DataVector::I16(d) => d.into_iter().map(f64::from).collect(),
        DataVector::I32(d) => d.into_iter().map(f64::from).collect(),
        DataVector::F32(d) => d.into_iter().map(f64::from).collect(),
        DataVector::F64(d) => d,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cf_times() {
        let t = |v, u| super::super::format_time(&cf_time(v, u, "standard").unwrap());
        assert_eq!(t(17927.0, "days since 1950-01-01 00:00:00"), "1999-01-31T00:00:00Z");
        assert_eq!(t(36.0, "hours since 2000-1-1"), "2000-01-02T12:00:00Z");
        assert_eq!(t(90.0, "minutes since 2000-01-01T00:00:00Z"), "2000-01-01T01:30:00Z");
        assert_eq!(t(0.0, "seconds since 2000-01-01 12:00:00 +02:00"), "2000-01-01T10:00:00Z");
        assert_eq!(t(0.5, "days since 2000-01-01 00:00:00.0 UTC"), "2000-01-01T12:00:00Z");
        assert!(cf_time(0.0, "days since 2000-01-01", "noleap").unwrap_err().to_string().contains("noleap"));
        assert!(cf_time(0.0, "fortnights since 2000-01-01", "standard").is_err());
        assert!(cf_time(0.0, "days after 2000-01-01", "standard").is_err());
        assert!(cf_time(0.0, "days since 1500-01-01", "standard").is_err());
        assert!(cf_time(0.0, "days since 1500-01-01", "proleptic_gregorian").is_ok());
        assert!(cf_time(f64::NAN, "days since 2000-01-01", "standard").is_err());
    }

    #[test]
    fn spacing_checks() {
        assert_eq!(spacing(&[1.0, 1.5, 2.0], "x", "f").unwrap(), (1.0, 0.5));
        assert_eq!(spacing(&[2.0, 1.5, 1.0], "y", "f").unwrap(), (2.0, -0.5));
        assert!(spacing(&[1.0, 1.5, 3.0], "x", "f").is_err());
        assert!(spacing(&[1.0], "x", "f").is_err());
        assert!(spacing(&[1.0, 1.0], "x", "f").is_err());
    }

    #[test]
    fn mask_and_unpack() {
        let m = ValueMask { fill: vec![-999.0], valid: (-100.0, 100.0), scale: 0.5, offset: 10.0 };
        assert_eq!(m.apply(4.0), 12.0);
        assert!(m.apply(-999.0).is_nan());
        assert!(m.apply(101.0).is_nan());
        assert!(m.apply(f64::NAN).is_nan());
    }
}
