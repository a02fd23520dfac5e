//! D5 time: ISO 8601 time stamps and the value of a series at time t.
//!
//! Scalars use eq. 9.4 of the thesis, linear interpolation between the bracketing steps:
//! `S(t) = (1 − uₜ)·S(tᵢ) + uₜ·S(tᵢ₊₁)` with `uₜ = (t − tᵢ)/(tᵢ₊₁ − tᵢ)` for `tᵢ ≤ t < tᵢ₊₁`.
//! Labels take the nearest step (they switch at the midpoint between two steps). A time before
//! the first or after the last step clamps to that step and says so ([`Clamp`]).
//!
//! Time stamps are UTC. Accepted input: RFC 3339 / ISO 8601 date-times with `Z` or an offset
//! (`1999-03-15T12:00:00+02:00`), date-times without offset (taken as UTC, `T` or a space,
//! seconds and fractions optional), dates (`1999-03-15`, midnight UTC), months (`1999-03`, the
//! first day) and years (`1999`). Output is RFC 3339 with `Z`, e.g. `1999-03-15T00:00:00Z`.

use chrono::{DateTime, NaiveDate, NaiveDateTime, SecondsFormat, Utc};
use serde::{Deserialize, Serialize};

use super::FieldError;
use super::field::FieldKind;

/// Parses an ISO 8601 time stamp (see the module docs for the accepted forms) as UTC.
pub fn parse_time(text: &str) -> Result<DateTime<Utc>, FieldError> {
    let s = text.trim();
    let err = |reason: &str| FieldError::Time { text: text.to_string(), reason: reason.to_string() };
    if s.is_empty() {
        return Err(err("empty time stamp"));
    }
    if let Ok(t) = DateTime::parse_from_rfc3339(s) {
        return Ok(t.with_timezone(&Utc));
    }
    // Offsets in other ISO 8601 spellings (`+0200`, `+02`) and `T` or space separators.
    for fmt in ["%Y-%m-%dT%H:%M:%S%.f%z", "%Y-%m-%d %H:%M:%S%.f%z", "%Y-%m-%dT%H:%M%z", "%Y-%m-%dT%H:%M:%S%.f%#z"] {
        if let Ok(t) = DateTime::parse_from_str(s, fmt) {
            return Ok(t.with_timezone(&Utc));
        }
    }
    let naive = s.strip_suffix('Z').unwrap_or(s);
    for fmt in ["%Y-%m-%dT%H:%M:%S%.f", "%Y-%m-%d %H:%M:%S%.f", "%Y-%m-%dT%H:%M", "%Y-%m-%d %H:%M"] {
        if let Ok(t) = NaiveDateTime::parse_from_str(naive, fmt) {
            return Ok(t.and_utc());
        }
    }
    let date = |y: &str, m: &str, d: &str| -> Option<NaiveDate> {
        let year: i32 = y.parse().ok()?;
        (y.len() == 4 && m.len() == 2 && d.len() == 2).then_some(())?;
        NaiveDate::from_ymd_opt(year, m.parse().ok()?, d.parse().ok()?)
    };
    let parts: Vec<&str> = naive.split('-').collect();
    let day = match parts.as_slice() {
        [y, m, d] => date(y, m, d),
        [y, m] => date(y, m, "01"),
        [y] => date(y, "01", "01"),
        _ => None,
    };
    day.and_then(|d| d.and_hms_opt(0, 0, 0)).map(|t| t.and_utc()).ok_or_else(|| {
        err("not an ISO 8601 time stamp (e.g. 1999-03-15, 1999-03-15T12:00:00Z or 1999-03-15T12:00+02:00)")
    })
}

/// Formats a time as RFC 3339 in UTC with whole seconds (fractions when present), e.g.
/// `1999-01-31T00:00:00Z`.
pub fn format_time(t: &DateTime<Utc>) -> String {
    t.to_rfc3339_opts(SecondsFormat::AutoSi, true)
}

/// On which side a requested time fell outside the series.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Clamp {
    /// Before the first step: the first step is shown.
    Before,
    /// After the last step: the last step is shown.
    After,
}

/// Where a time falls in a series: the two steps to blend and the weight of the upper one.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimeSample {
    /// Index of step tᵢ.
    pub lower: usize,
    /// Index of step tᵢ₊₁ (equal to `lower` when a single step is used).
    pub upper: usize,
    /// uₜ of eq. 9.4 in [0, 1]: the weight of `upper` (always 0 or 1 for labels).
    pub weight: f64,
    /// Set when the time was outside the series and was clamped.
    pub clamped: Option<Clamp>,
}

impl TimeSample {
    /// The sample of step `i` alone.
    pub fn single(i: usize) -> TimeSample {
        TimeSample { lower: i, upper: i, weight: 0.0, clamped: None }
    }

    /// Locates `t` in the sorted step times `times`: for scalars the bracketing steps and uₜ
    /// (eq. 9.4), for labels the nearest step (ties go to the later one). `None` when `times`
    /// is empty.
    pub fn locate(times: &[DateTime<Utc>], t: DateTime<Utc>, kind: FieldKind) -> Option<TimeSample> {
        let last = times.len().checked_sub(1)?;
        if t < times[0] {
            return Some(TimeSample { clamped: Some(Clamp::Before), ..TimeSample::single(0) });
        }
        if t > times[last] {
            return Some(TimeSample { clamped: Some(Clamp::After), ..TimeSample::single(last) });
        }
        // times[i] <= t; i < last unless t == times[last].
        let i = times.partition_point(|&s| s <= t) - 1;
        if i == last {
            return Some(TimeSample::single(last));
        }
        let span = (times[i + 1] - times[i]).num_milliseconds() as f64;
        let u = ((t - times[i]).num_milliseconds() as f64 / span).clamp(0.0, 1.0);
        Some(match kind {
            FieldKind::Scalar if u == 0.0 => TimeSample::single(i),
            FieldKind::Scalar => TimeSample { lower: i, upper: i + 1, weight: u, clamped: None },
            FieldKind::Label => TimeSample::single(if u >= 0.5 { i + 1 } else { i }),
        })
    }

    /// Eq. 9.4 on two grids of the same size: `(1 − u)·lower + u·upper`. A cell is nodata (NaN)
    /// where a step with non-zero weight is nodata.
    pub fn blend(&self, lower: &[f32], upper: &[f32]) -> Vec<f32> {
        let u = self.weight as f32;
        if self.lower == self.upper || u == 0.0 {
            return lower.to_vec();
        }
        if u == 1.0 {
            return upper.to_vec();
        }
        lower.iter().zip(upper).map(|(&a, &b)| (1.0 - u) * a + u * b).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_iso_forms() {
        let z = |s: &str| format_time(&parse_time(s).unwrap());
        assert_eq!(z("1999-03-15"), "1999-03-15T00:00:00Z");
        assert_eq!(z("1999-03"), "1999-03-01T00:00:00Z");
        assert_eq!(z("1999"), "1999-01-01T00:00:00Z");
        assert_eq!(z("1999-03-15T12:30:00Z"), "1999-03-15T12:30:00Z");
        assert_eq!(z("1999-03-15T12:30:00+02:00"), "1999-03-15T10:30:00Z");
        assert_eq!(z("1999-03-15T12:30+0200"), "1999-03-15T10:30:00Z");
        assert_eq!(z("1999-03-15 12:30:15"), "1999-03-15T12:30:15Z");
        assert_eq!(z("1999-03-15T12:30"), "1999-03-15T12:30:00Z");
        assert_eq!(z("1999-03-15T12:30:00.5Z"), "1999-03-15T12:30:00.500Z");
        for bad in ["", "yesterday", "1999-13-01", "1999-02-30", "99-01-01", "1999-3-1", "1999-03-15T25:00"] {
            assert!(matches!(parse_time(bad), Err(FieldError::Time { .. })), "{bad}");
        }
    }

    #[test]
    fn locate_scalar_label_and_clamp() {
        let times: Vec<_> = ["2000-01-01", "2000-01-11", "2000-01-31"].iter().map(|s| parse_time(s).unwrap()).collect();
        let at = |s: &str, k| TimeSample::locate(&times, parse_time(s).unwrap(), k).unwrap();
        let s = at("2000-01-04", FieldKind::Scalar);
        assert_eq!((s.lower, s.upper, s.clamped), (0, 1, None));
        assert!((s.weight - 0.3).abs() < 1e-12);
        assert_eq!(at("2000-01-11", FieldKind::Scalar), TimeSample::single(1));
        assert_eq!(at("2000-01-31", FieldKind::Scalar), TimeSample::single(2));
        assert_eq!(at("1999-12-31", FieldKind::Scalar).clamped, Some(Clamp::Before));
        assert_eq!(
            at("2000-02-01", FieldKind::Label),
            TimeSample { clamped: Some(Clamp::After), ..TimeSample::single(2) }
        );
        assert_eq!(at("2000-01-05", FieldKind::Label), TimeSample::single(0));
        assert_eq!(at("2000-01-06", FieldKind::Label), TimeSample::single(1), "midpoint switches");
        assert_eq!(at("2000-01-21", FieldKind::Label), TimeSample::single(2));
        assert_eq!(TimeSample::locate(&[], times[0], FieldKind::Scalar), None);
    }

    #[test]
    fn blend_is_eq_9_4() {
        let s = TimeSample { lower: 0, upper: 1, weight: 0.25, clamped: None };
        let out = s.blend(&[0.0, 10.0, f32::NAN], &[4.0, 20.0, 1.0]);
        assert_eq!(&out[..2], &[1.0, 12.5]);
        assert!(out[2].is_nan());
        assert_eq!(TimeSample::single(0).blend(&[1.0], &[2.0]), vec![1.0]);
    }
}
