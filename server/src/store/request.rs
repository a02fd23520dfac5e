//! Data layers in rendered views (D3–D5): the mappings and time of a request checked against
//! the layer store and Table 9.1 ([`DataRequest::resolve`]), and their fields loaded for the
//! renderer on the render thread ([`LayerCache`]).

use super::{LayerMeta, Store};
use crate::fields::{Clamp, FieldError, Mapping, TimeSample, format_time, parse_time, validate_mappings};
use crate::render::RenderError;
use crate::render::projection::{DataLayer, DataMapping, DataView};
use serde::Serialize;
use std::collections::HashMap;
use std::sync::Arc;

/// Mappings and a time that a view cannot show.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A mapping names a layer the store does not have.
    #[error("unknown layer {:?}", crate::echo::echo(.0))]
    UnknownLayer(String),
    /// The mappings are unusable: too many, a feature used twice, a bad range, opacity or
    /// hatch colour, a target the layer's kind cannot show.
    #[error("{0}")]
    Mappings(FieldError),
    /// The time is no ISO 8601 time.
    #[error("{0}")]
    Time(FieldError),
}

/// The version of a stored layer a view shows: a re-uploaded or extended layer is another
/// version (another ETag, other GPU textures).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct LayerVersion {
    /// Layer id.
    pub id: String,
    /// Creation time of the layer.
    pub created: String,
    /// Number of time steps.
    pub steps: usize,
}

impl LayerVersion {
    fn of(meta: &LayerMeta) -> LayerVersion {
        LayerVersion { id: meta.id.clone(), created: meta.created.clone(), steps: meta.steps.len() }
    }

    /// The renderer's cache key of this version.
    pub fn key(&self) -> String {
        format!("{}@{}#{}", self.id, self.created, self.steps)
    }
}

/// The validated data part of a view: mappings, normalized time and the layer versions, plus
/// the warnings to answer with (Table 9.1, clamped times), which are not part of the view's
/// identity.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct DataRequest {
    /// The mappings as requested (layer ids).
    pub mappings: Vec<Mapping>,
    /// The time as RFC 3339, if given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
    /// The version of each mapping's layer.
    pub layers: Vec<LayerVersion>,
    /// Warnings for the response: unsuitable or limited mappings (Table 9.1), times outside a
    /// series.
    #[serde(skip)]
    pub warnings: Vec<String>,
}

impl DataRequest {
    /// Whether the view shows no data layers.
    pub fn is_empty(&self) -> bool {
        self.mappings.is_empty() && self.time.is_none()
    }

    /// Checks `mappings` and `time` against `store`: unknown layers, too many mappings, a
    /// feature other than colour and hatch colour used twice, bad ranges, opacities or hatch
    /// colours and bad times are errors; Table 9.1 and clamped times become warnings.
    pub fn resolve(mappings: &[Mapping], time: Option<&str>, store: &Store) -> Result<DataRequest, DataError> {
        let metas = mappings
            .iter()
            .map(|m| store.get(&m.layer).map_err(|_| DataError::UnknownLayer(m.layer.clone())))
            .collect::<Result<Vec<_>, _>>()?;
        let find = |id: &str| metas.iter().find(|m| m.id == id).map(|m| (m.kind, m.classes.len()));
        let mut warnings: Vec<String> =
            validate_mappings(mappings, find).map_err(DataError::Mappings)?.into_iter().map(|w| w.message).collect();
        let time = time.map(parse_time).transpose().map_err(DataError::Time)?;
        if let Some(t) = time {
            for meta in &metas {
                let times = meta.times().into_iter().filter_map(|s| parse_time(s).ok()).collect::<Vec<_>>();
                let clamped = TimeSample::locate(&times, t, meta.kind).and_then(|s| s.clamped);
                let (side, shown) = match clamped {
                    Some(Clamp::Before) => ("before the first", times.first()),
                    Some(Clamp::After) => ("after the last", times.last()),
                    None => continue,
                };
                let shown = shown.map(format_time).unwrap_or_default();
                warnings.push(format!(
                    "time {} is {side} step of layer {}; showing {shown} (clamped)",
                    format_time(&t),
                    meta.id
                ));
            }
        }
        Ok(DataRequest {
            mappings: mappings.to_vec(),
            time: time.as_ref().map(format_time),
            layers: metas.iter().map(LayerVersion::of).collect(),
            warnings,
        })
    }
}

/// Most layers the render thread keeps loaded.
const MAX_LOADED_LAYERS: usize = 8;

/// Fields of stored layers loaded on the render thread, by version.
#[derive(Default)]
pub struct LayerCache {
    layers: HashMap<String, Arc<DataLayer>>,
}

impl LayerCache {
    /// The renderer's [`DataView`] of `request`, loading layers from `store` on first use.
    pub fn view(&mut self, request: &DataRequest, store: &Store) -> Result<DataView, RenderError> {
        let mut mappings = Vec::with_capacity(request.mappings.len());
        for (mapping, version) in request.mappings.iter().zip(&request.layers) {
            let key = version.key();
            let layer = match self.layers.get(&key) {
                Some(layer) => layer.clone(),
                None => {
                    let field = store.field(&version.id).map_err(|e| RenderError::Data(e.to_string()))?;
                    if self.layers.len() >= MAX_LOADED_LAYERS {
                        self.layers.clear();
                    }
                    let layer = Arc::new(DataLayer { key: key.clone(), field });
                    self.layers.insert(key, layer.clone());
                    layer
                }
            };
            mappings.push(DataMapping { layer, mapping: mapping.clone() });
        }
        let time = request.time.as_deref().map(parse_time).transpose().map_err(|e| RenderError::Data(e.to_string()))?;
        Ok(DataView { mappings, time })
    }
}
