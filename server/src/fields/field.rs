//! D1 fields: a scalar or label field S : D ⊂ R² → R on the regular grid
//! D = {(x₀ + iΔx, y₀ + jΔy)} of eq. 9.1–9.2, with nodata, possibly over several time steps
//! (eq. 9.3). Each step is a [`Raster`] in the field's CRS; scalars are sampled bilinearly
//! between cell centres, labels at the nearest cell ([`Field::sample`]).

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use chrono::{DateTime, Utc};
use serde::{Deserialize, Serialize};

use super::FieldError;
use crate::gis::{CrsDefinition, Extent, Raster};

/// Most classes a label field may have (label indices must fit the colour look-up table, and
/// more classes cannot be told apart as patterns or colours).
pub const MAX_LABEL_CLASSES: usize = 64;

/// Whether a field holds continuous values or a few discrete labels (thesis 9.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum FieldKind {
    /// Continuous values in [vmin, vmax]; bilinear sampling, linear in time.
    Scalar,
    /// Discrete integer classes; nearest sampling, nearest step in time.
    Label,
}

impl FromStr for FieldKind {
    type Err = FieldError;

    /// `scalar` or `label` (case-insensitive).
    fn from_str(s: &str) -> Result<FieldKind, FieldError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "scalar" => Ok(FieldKind::Scalar),
            "label" => Ok(FieldKind::Label),
            _ => Err(FieldError::Invalid(format!("kind \"{s}\" must be scalar or label"))),
        }
    }
}

impl fmt::Display for FieldKind {
    /// `scalar` or `label`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FieldKind::Scalar => "scalar",
            FieldKind::Label => "label",
        })
    }
}

/// One class of a label field.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct ClassInfo {
    /// The cell value of the class.
    pub value: i64,
    /// Number of valid cells with this value over all time steps.
    pub count: u64,
    /// A display name, if one was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// The colour of the class in the file's palette (8-bit sRGB), if it had one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<[u8; 3]>,
}

/// One time step of a field.
#[derive(Debug, Clone)]
pub struct FieldStep {
    /// The step's time; `None` only for a field with a single step and no time.
    pub time: Option<DateTime<Utc>>,
    /// The grid in the field's CRS (its `crs` member is informational; the field's
    /// [`CrsDefinition`] is authoritative).
    pub raster: Raster,
}

/// A scalar or label field with one or more time steps, in one CRS.
#[derive(Debug, Clone)]
pub struct Field {
    kind: FieldKind,
    crs: CrsDefinition,
    units: Option<String>,
    steps: Vec<FieldStep>,
    classes: Vec<ClassInfo>,
    /// Smallest and largest valid value over all steps, found once: every mapped frame asks.
    range: (f64, f64),
}

impl Field {
    /// A field from its steps. Steps are sorted by time; either there is exactly one step
    /// without time, or every step has a distinct time. Label fields must hold integer values
    /// with at most [`MAX_LABEL_CLASSES`] classes; class colours come from the first step's
    /// palette, if any. Every step needs at least one valid cell.
    pub fn new(
        kind: FieldKind,
        crs: CrsDefinition,
        units: Option<String>,
        mut steps: Vec<FieldStep>,
    ) -> Result<Field, FieldError> {
        if steps.is_empty() {
            return Err(FieldError::Invalid("a field needs at least one grid".into()));
        }
        let untimed = steps.iter().filter(|s| s.time.is_none()).count();
        if untimed > 0 && steps.len() > 1 {
            return Err(FieldError::Invalid(format!(
                "a series of {} grids needs a time stamp on every grid ({untimed} without)",
                steps.len()
            )));
        }
        steps.sort_by_key(|s| s.time);
        for step in &mut steps {
            // Infinite values are not data (and cannot be stored in JSON statistics).
            step.raster.data.iter_mut().filter(|v| v.is_infinite()).for_each(|v| *v = f64::NAN);
        }
        if let Some(w) = steps.windows(2).find(|w| w[0].time == w[1].time) {
            let t = w[0].time.map(|t| super::format_time(&t)).unwrap_or_default();
            return Err(FieldError::Invalid(format!("time step {t} appears twice")));
        }
        for (i, step) in steps.iter().enumerate() {
            let r = &step.raster;
            if r.width.checked_mul(r.height) != Some(r.data.len()) || r.data.is_empty() {
                return Err(FieldError::Invalid(format!(
                    "grid {i} holds {} values for {} × {} cells",
                    r.data.len(),
                    r.width,
                    r.height
                )));
            }
            if r.valid_count() == 0 {
                return Err(FieldError::Invalid(format!("grid {i} has no valid cell (all nodata)")));
            }
        }
        let classes = match kind {
            FieldKind::Scalar => Vec::new(),
            FieldKind::Label => label_classes(&steps)?,
        };
        let units = units.map(|u| u.trim().to_string()).filter(|u| !u.is_empty());
        let range = steps
            .iter()
            .filter_map(|s| s.raster.valid_range())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |acc, r| (acc.0.min(r.0), acc.1.max(r.1)));
        Ok(Field { kind, crs, units, steps, classes, range })
    }

    /// Scalar or label.
    pub fn kind(&self) -> FieldKind {
        self.kind
    }

    /// The CRS of every step's grid.
    pub fn crs(&self) -> &CrsDefinition {
        &self.crs
    }

    /// Units of the values (e.g. `C`, `mm/m`), if known.
    pub fn units(&self) -> Option<&str> {
        self.units.as_deref()
    }

    /// The time steps, sorted by time.
    pub fn steps(&self) -> &[FieldStep] {
        &self.steps
    }

    /// The times of the steps (empty for a field without time).
    pub fn times(&self) -> Vec<DateTime<Utc>> {
        self.steps.iter().filter_map(|s| s.time).collect()
    }

    /// The classes of a label field sorted by value (empty for scalars); a class's position is
    /// its label index in [`super::FieldGrid`] values and in the colour look-up table.
    pub fn classes(&self) -> &[ClassInfo] {
        &self.classes
    }

    /// Sets display names of label classes by value; unknown values are an error.
    pub fn set_class_names(&mut self, names: &BTreeMap<i64, String>) -> Result<(), FieldError> {
        for (value, name) in names {
            let class = self.classes.iter_mut().find(|c| c.value == *value).ok_or_else(|| {
                FieldError::Invalid(format!("class name given for value {value}, which the field does not contain"))
            })?;
            class.name = Some(name.clone());
        }
        Ok(())
    }

    /// Smallest and largest valid value over all steps.
    pub fn value_range(&self) -> (f64, f64) {
        self.range
    }

    /// The union of the steps' extents in the field's CRS.
    pub fn extent(&self) -> Extent {
        let first = self.steps[0].raster.extent();
        self.steps.iter().map(|s| s.raster.extent()).fold(first, |a, e| Extent {
            min_x: a.min_x.min(e.min_x),
            min_y: a.min_y.min(e.min_y),
            max_x: a.max_x.max(e.max_x),
            max_y: a.max_y.max(e.max_y),
        })
    }

    /// The value of step `step` at a point of the field's CRS: bilinear between cell centres
    /// for scalars, the containing cell for labels. `None` outside the grid, on nodata (a
    /// scalar point next to a nodata cell with non-zero weight is nodata too) or for a step
    /// index out of range.
    pub fn sample(&self, step: usize, x: f64, y: f64) -> Option<f64> {
        let raster = &self.steps.get(step)?.raster;
        match self.kind {
            FieldKind::Scalar => raster.sample_bilinear(x, y),
            FieldKind::Label => raster.sample_nearest(x, y),
        }
    }

    /// The label index (position in [`Field::classes`]) of a class value.
    pub fn label_index(&self, value: f64) -> Option<usize> {
        self.classes.binary_search_by(|c| (c.value as f64).total_cmp(&value)).ok()
    }

    /// Appends the steps of `other` (a further part of the same series: same kind and CRS,
    /// every step timed, no time twice). Units and class names of `self` are kept.
    pub fn append(self, other: Field) -> Result<Field, FieldError> {
        if other.kind != self.kind {
            return Err(FieldError::Invalid(format!("cannot add a {} grid to a {} series", other.kind, self.kind)));
        }
        if other.crs.proj_string() != self.crs.proj_string() {
            return Err(FieldError::Invalid(format!(
                "every step of a series must be in the same CRS ({} vs {})",
                other.crs.label(),
                self.crs.label()
            )));
        }
        let names: BTreeMap<i64, String> =
            self.classes.iter().filter_map(|c| Some((c.value, c.name.clone()?))).collect();
        let mut steps = self.steps;
        steps.extend(other.steps);
        let mut field = Field::new(self.kind, self.crs, self.units.or(other.units), steps)?;
        for class in &mut field.classes {
            class.name = names.get(&class.value).cloned();
        }
        Ok(field)
    }
}

/// The classes of label steps, with counts and palette colours; checks integer values and the
/// class limit.
fn label_classes(steps: &[FieldStep]) -> Result<Vec<ClassInfo>, FieldError> {
    let mut counts: BTreeMap<i64, u64> = BTreeMap::new();
    for step in steps {
        let r = &step.raster;
        for &v in r.data.iter().filter(|&&v| r.is_valid(v)) {
            if v.fract() != 0.0 || v.abs() > 9.0e15 {
                return Err(FieldError::Invalid(format!(
                    "a label field needs integer class values, found {v} (upload it as a scalar field)"
                )));
            }
            // Integral and within ±2^53, so the conversion is exact.
            *counts.entry(v as i64).or_default() += 1;
            if counts.len() > MAX_LABEL_CLASSES {
                return Err(FieldError::Invalid(format!(
                    "a label field may have at most {MAX_LABEL_CLASSES} classes (found more); upload it as a scalar field"
                )));
            }
        }
    }
    let palette = steps[0].raster.palette.as_deref();
    Ok(counts
        .into_iter()
        .map(|(value, count)| ClassInfo {
            value,
            count,
            name: None,
            color: palette.and_then(|p| usize::try_from(value).ok().and_then(|i| p.get(i)).copied()),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gis::{Crs, GeoTransform};

    fn raster(data: Vec<f64>, w: usize) -> Raster {
        Raster {
            width: w,
            height: data.len() / w,
            data,
            nodata: Some(-1.0),
            transform: GeoTransform { origin_x: 0.0, origin_y: 20.0, cell_width: 10.0, cell_height: 10.0 },
            crs: Crs::Projected { epsg: Some(32613), unit_to_metre: 1.0 },
            palette: None,
        }
    }

    fn utm() -> CrsDefinition {
        CrsDefinition::from_epsg(32613).unwrap()
    }

    #[test]
    fn scalar_bilinear_label_nearest() {
        let steps = vec![FieldStep { time: None, raster: raster(vec![0.0, 10.0, 20.0, 30.0], 2) }];
        let s = Field::new(FieldKind::Scalar, utm(), Some(" K ".into()), steps.clone()).unwrap();
        assert_eq!(s.sample(0, 10.0, 10.0), Some(15.0));
        assert_eq!(s.sample(0, 7.5, 15.0), Some(2.5));
        assert_eq!(s.sample(1, 7.5, 15.0), None);
        assert_eq!(s.units(), Some("K"));
        assert_eq!(s.value_range(), (0.0, 30.0));
        let l = Field::new(FieldKind::Label, utm(), None, steps).unwrap();
        assert_eq!(l.sample(0, 9.0, 11.0), Some(0.0));
        assert_eq!(l.sample(0, 11.0, 9.0), Some(30.0));
        assert_eq!(
            l.classes().iter().map(|c| (c.value, c.count)).collect::<Vec<_>>(),
            [(0, 1), (10, 1), (20, 1), (30, 1)]
        );
        assert_eq!(l.label_index(20.0), Some(2));
        assert_eq!(l.label_index(5.0), None);
    }

    #[test]
    fn label_checks() {
        let frac = vec![FieldStep { time: None, raster: raster(vec![0.5, 1.0], 2) }];
        assert!(Field::new(FieldKind::Label, utm(), None, frac).unwrap_err().to_string().contains("integer"));
        let many = vec![FieldStep { time: None, raster: raster((0..100).map(f64::from).collect(), 10) }];
        assert!(Field::new(FieldKind::Label, utm(), None, many).unwrap_err().to_string().contains("at most 64"));
    }

    #[test]
    fn series_rules() {
        let t = |s: &str| Some(crate::fields::parse_time(s).unwrap());
        let step = |time| FieldStep { time, raster: raster(vec![1.0, 2.0], 2) };
        let f = Field::new(FieldKind::Scalar, utm(), None, vec![step(t("2000-02-01")), step(t("2000-01-01"))]).unwrap();
        assert_eq!(f.times(), vec![t("2000-01-01").unwrap(), t("2000-02-01").unwrap()]);
        assert!(Field::new(FieldKind::Scalar, utm(), None, vec![step(None), step(t("2000-01-01"))]).is_err());
        let dup = Field::new(FieldKind::Scalar, utm(), None, vec![step(t("2000-01-01"))]).unwrap();
        assert!(f.clone().append(dup).unwrap_err().to_string().contains("appears twice"));
        let more = Field::new(FieldKind::Scalar, utm(), None, vec![step(t("2000-03-01"))]).unwrap();
        assert_eq!(f.clone().append(more).unwrap().steps().len(), 3);
        let label = Field::new(FieldKind::Label, utm(), None, vec![step(t("2000-03-01"))]).unwrap();
        assert!(f.append(label).is_err());
    }
}
