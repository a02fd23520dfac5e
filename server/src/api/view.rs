//! The one description of a rendered view shared by `GET /api/render` (query parameters),
//! `POST /api/render` (JSON body) and the WebSocket: [`ViewParams`] is what a client sends,
//! [`ViewRequest`] the validated, normalized view that is rendered, hashed and cached. A view
//! link round-trips: [`ViewParams::to_query`] and [`ViewParams::from_query`] convert between
//! the two encodings.

use super::error::ApiError;
use crate::fields::Mapping;
use crate::render::compare::Compare;
use crate::render::marks::Pin;
use crate::render::style::{FrameStyle, LayerStyle, PartialStyle};
use crate::render::view_style::ViewStyle;
use crate::render::{RenderError, Style};
use crate::scene::Scene;
use crate::scene::camera::{Camera, Projection};
use crate::store::Store;
use crate::store::request::DataRequest;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use utoipa::{IntoParams, ToSchema};

pub use crate::render::image_format::{DEFAULT_JPEG_QUALITY, ImageFormat};
pub use crate::scene::camera_params::{CameraMode, CameraParams, Source};

/// Image width when a request gives none.
pub const DEFAULT_WIDTH: u32 = 1024;
/// Image height when a request gives none.
pub const DEFAULT_HEIGHT: u32 = 768;

/// A view as a client asks for it, in the JSON body of `POST /api/render`; `GET /api/render`
/// takes the same as flat query parameters (see [`RenderQuery`]).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ViewParams {
    /// The camera; the scene's default camera where left out.
    pub camera: CameraParams,
    /// Image width in pixels (default 1024).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    /// Image height in pixels (default 768).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
    /// `png` (default) or `jpeg`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub format: Option<String>,
    /// JPEG quality 1–100 (default 90); ignored for PNG.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<u32>,
    /// A named style preset (`GET /api/scene` lists them); `style` merges over it. An
    /// unknown name is a 404.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Style overrides: a JSON object with any subset of the style fields (README, "Style").
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub style: Option<PartialStyle>,
    /// Styles of single layers (thesis 8.2.8): layer name (`terrain` or a vegetation layer)
    /// → a partial style merged over the view's style, or over `"preset"` when it names one,
    /// e.g. `{"existing": {"preset": "photorealism"}}`.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub layer_styles: Option<BTreeMap<String, LayerStyle>>,
    /// Data layers shown in the view (D3/D4): up to 3 `{"layer": id, "target": "color" |
    /// "hatch_tone" | "hatch_color" | "hatch_pattern" | "silhouette_style" |
    /// "silhouette_density", "range": [lo, hi], "colormap": name, "opacity": 0..1, "reverse":
    /// bool, "color": [r, g, b]}` (`color`: the sRGB ink of a `hatch_color` mapping).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mappings: Option<Vec<Mapping>>,
    /// ISO 8601 time of the data layers (D5; default: each layer's first step).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
    /// Before / after: `{"layer": "planned"}` shows the view without the vegetation layer
    /// `planned`; with `"split": 0.5` the left half of the image without it, the right half
    /// with it (the split 0…1 of the width from the left).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compare: Option<Compare>,
    /// Draws the visible comments as numbered pins in the view (default false).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub comments: Option<bool>,
}

/// The query parameters of `GET /api/render`: [`ViewParams`] flattened (`x`, `y`, `z` for
/// the position, `style` as JSON text).
#[derive(Debug, Default, Serialize, Deserialize, IntoParams)]
#[serde(default, deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct RenderQuery {
    /// Camera x, scene metres (east); give x and y together.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub x: Option<f32>,
    /// Camera y, scene metres (north).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub y: Option<f32>,
    /// Eye elevation in scene metres (not below the terrain there); without it the eye is
    /// `eye_height` above the terrain.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z: Option<f32>,
    /// Eye height above the terrain when z is left out (default 1.7).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub eye_height: Option<f32>,
    /// Compass heading in degrees (0 north, 90 east).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub yaw: Option<f32>,
    /// Degrees above or below the horizon, −90…90.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pitch: Option<f32>,
    /// Vertical field of view in degrees, 1…170.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fov: Option<f32>,
    /// Rotation about the view direction in degrees, −180…180.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roll: Option<f32>,
    /// `perspective` (default) or `plan` (orthographic top-down).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mode: Option<CameraMode>,
    /// Plan view centre `x,y` in scene metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub center: Option<String>,
    /// Plan view: scene metres across the image.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plan_width: Option<f32>,
    /// Image width in pixels (default 1024).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width: Option<u32>,
    /// Image height in pixels (default 768).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub height: Option<u32>,
    /// `png` (default) or `jpeg`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub format: Option<String>,
    /// JPEG quality 1–100 (default 90).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<u32>,
    /// Style preset name (`GET /api/scene` lists them).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Style overrides as a URL-encoded JSON object, e.g. `{"hatch_map":2}`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub style: Option<String>,
    /// Per-layer styles as a URL-encoded JSON object, e.g. `{"existing":{"photorealism":1}}`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub layer_styles: Option<String>,
    /// Data-layer mappings as a URL-encoded JSON array (see the JSON body's `mappings`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mappings: Option<String>,
    /// ISO 8601 time of the data layers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<String>,
    /// Before / after: the vegetation layer (the plan) the view is shown without.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compare_layer: Option<String>,
    /// With `compare_layer`: the split 0…1 of the image width, left of it without the layer,
    /// right of it with it (left out: without the layer everywhere).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub split: Option<f32>,
    /// `true`: the visible comments drawn as numbered pins.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub comments: Option<bool>,
}

/// Limits a server puts on views.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest image width in pixels.
    pub max_width: u32,
    /// Largest image height in pixels.
    pub max_height: u32,
}

impl ViewParams {
    /// Parses the query string of `GET /api/render`. Unknown, repeated or malformed
    /// parameters are 400s naming the parameter.
    pub fn from_query(query: &str) -> Result<ViewParams, ApiError> {
        let parser = serde_urlencoded::Deserializer::new(form_urlencoded::parse(query.as_bytes()));
        let q: RenderQuery = serde_path_to_error::deserialize(parser).map_err(|e| {
            let path = e.path().to_string();
            let message = format!("malformed query: {}", e.inner());
            ApiError::BadRequest { parameter: (path != ".").then_some(path), message }
        })?;
        let position = match (q.x, q.y, q.z) {
            (None, None, None) => None,
            (Some(x), Some(y), None) => Some(vec![x, y]),
            (Some(x), Some(y), Some(z)) => Some(vec![x, y, z]),
            (None, _, _) => return Err(ApiError::invalid("x", "x is missing: give x and y together (z optionally)")),
            (_, None, _) => return Err(ApiError::invalid("y", "y is missing: give x and y together (z optionally)")),
        };
        let style = q.style.as_deref().map(|text| query_json("style", text, "valid JSON")).transpose()?;
        let layer_styles = q
            .layer_styles
            .as_deref()
            .map(|text| query_json("layer_styles", text, "a valid JSON object"))
            .transpose()?;
        let mappings = match &q.mappings {
            Some(text) => Some(serde_json::from_str(text).map_err(|e| {
                ApiError::bad("mappings", format!("mappings is not a valid JSON array of mappings: {e}"))
            })?),
            None => None,
        };
        let center = match &q.center {
            Some(text) => Some(
                text.split(',')
                    .map(|v| v.trim().parse::<f32>())
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|_| ApiError::bad("center", format!("center {:?} is not x,y", crate::echo::echo(text))))?,
            ),
            None => None,
        };
        let compare = match (q.compare_layer, q.split) {
            (Some(layer), split) => Some(Compare { layer, split }),
            (None, None) => None,
            (None, Some(_)) => return Err(ApiError::bad("split", "split needs compare_layer: the layer to compare")),
        };
        Ok(ViewParams {
            camera: CameraParams {
                mode: q.mode,
                center,
                width: q.plan_width,
                position,
                eye_height: q.eye_height,
                yaw: q.yaw,
                pitch: q.pitch,
                fov: q.fov,
                roll: q.roll,
            },
            width: q.width,
            height: q.height,
            format: q.format,
            quality: q.quality,
            preset: q.preset,
            style,
            layer_styles,
            mappings,
            time: q.time,
            compare,
            comments: q.comments,
        })
    }

    /// The query string of `GET /api/render` for these parameters (without the leading `?`).
    /// A position of other than 2 or 3 values has no query form; its first three values are
    /// written.
    pub fn to_query(&self) -> String {
        let position = self.camera.position.as_deref().unwrap_or_default();
        let query = RenderQuery {
            x: position.first().copied(),
            y: position.get(1).copied(),
            z: position.get(2).copied(),
            eye_height: self.camera.eye_height,
            yaw: self.camera.yaw,
            pitch: self.camera.pitch,
            fov: self.camera.fov,
            roll: self.camera.roll,
            mode: self.camera.mode,
            center: self.camera.center.as_ref().map(|c| c.iter().map(f32::to_string).collect::<Vec<_>>().join(",")),
            plan_width: self.camera.width,
            width: self.width,
            height: self.height,
            format: self.format.clone(),
            quality: self.quality,
            preset: self.preset.clone(),
            style: self.style.as_ref().and_then(|s| serde_json::to_string(s).ok()),
            layer_styles: self.layer_styles.as_ref().and_then(|m| serde_json::to_string(m).ok()),
            mappings: self.mappings.as_ref().and_then(|m| serde_json::to_string(m).ok()),
            time: self.time.clone(),
            compare_layer: self.compare.as_ref().map(|c| c.layer.clone()),
            split: self.compare.as_ref().and_then(|c| c.split),
            comments: self.comments.filter(|&on| on),
        };
        serde_urlencoded::to_string(&query).expect("flat query parameters always URL-encode")
    }

    /// Validates and normalizes these parameters into the view to render: defaults filled
    /// in, the eye placed on the terrain, the style parsed, data layers looked up in `store`
    /// and checked against Table 9.1. 413 for images above `limits`, 422 for out-of-range
    /// values, 404 for an unknown preset or layer.
    pub fn normalize(
        &self,
        scene: &Scene,
        store: &Store,
        limits: Limits,
        source: Source,
    ) -> Result<ViewRequest, ApiError> {
        let camera = self.camera.resolve(&scene.default_camera, scene, source)?.camera;
        let width = image_side("width", self.width.unwrap_or(DEFAULT_WIDTH), limits.max_width)?;
        let height = image_side("height", self.height.unwrap_or(DEFAULT_HEIGHT), limits.max_height)?;
        let format = match &self.format {
            Some(name) => image_format(name, "format")?,
            None => ImageFormat::Png,
        };
        let quality = jpeg_quality(self.quality, "quality")?;
        let quality = (format == ImageFormat::Jpeg).then_some(quality);
        let styles = self.view_style().resolve(&scene.layer_names())?;
        let data = DataRequest::resolve(self.mappings.as_deref().unwrap_or_default(), self.time.as_deref(), store)?;
        if let Some(compare) = &self.compare {
            check_compare(compare, &scene.layer_names())?;
        }
        Ok(ViewRequest {
            camera,
            width,
            height,
            format,
            quality,
            style: styles.base,
            layer_styles: styles.layers,
            data,
            compare: self.compare.clone(),
            comments: self.comments.unwrap_or(false).then(Vec::new),
        })
    }

    /// The style part of these parameters: preset, fields and layer styles.
    pub fn view_style(&self) -> ViewStyle {
        ViewStyle {
            preset: self.preset.clone(),
            style: self.style.clone().unwrap_or_default(),
            layer_styles: self.layer_styles.clone().unwrap_or_default(),
        }
    }
}

/// Checks a before/after comparison against the scene's vegetation layers `layers`: an
/// unknown layer is a 422 naming it and the scene's layers (`compare.layer`), a split outside
/// 0…1 a 422 naming `compare.split`.
pub fn check_compare(compare: &Compare, layers: &[String]) -> Result<(), ApiError> {
    compare.check(layers).map(|_| ()).map_err(|e| {
        let parameter = match e {
            RenderError::Compare(_) if compare.split.is_some() => "compare.split",
            _ => "compare.layer",
        };
        ApiError::invalid(parameter, e.to_string())
    })
}

/// Parses the JSON text of the query parameter `parameter`: malformed JSON is a 400 saying
/// it is not `what`; a value of the wrong shape a 422 naming the field (`style.ambient`).
fn query_json<T: DeserializeOwned>(parameter: &str, text: &str, what: &str) -> Result<T, ApiError> {
    let mut deserializer = serde_json::Deserializer::from_str(text);
    let value = serde_path_to_error::deserialize(&mut deserializer).map_err(|e| {
        let path = e.path().to_string();
        let inner = e.into_inner();
        if inner.is_data() {
            let field = if path == "." { parameter.to_owned() } else { format!("{parameter}.{path}") };
            ApiError::invalid(field, format!("{parameter}: {inner}"))
        } else {
            ApiError::bad(parameter, format!("{parameter} is not {what}: {inner}"))
        }
    })?;
    deserializer.end().map_err(|e| ApiError::bad(parameter, format!("{parameter} is not {what}: {e}")))?;
    Ok(value)
}

/// Parses an image format name; an unknown one is a 422 naming `parameter` and the supported
/// formats.
pub fn image_format(name: &str, parameter: &str) -> Result<ImageFormat, ApiError> {
    name.parse::<ImageFormat>().map_err(|e| ApiError::invalid(parameter, e.to_string()))
}

/// Checks a JPEG quality (1–100; default 90).
pub fn jpeg_quality(quality: Option<u32>, parameter: &str) -> Result<u8, ApiError> {
    match quality {
        None => Ok(DEFAULT_JPEG_QUALITY),
        Some(q) => u8::try_from(q)
            .ok()
            .filter(|q| (1..=100).contains(q))
            .ok_or_else(|| ApiError::invalid(parameter, format!("quality {q} is outside 1..=100"))),
    }
}

/// Checks one image side against the server's limit: 0 is a 422, too large a 413.
pub fn image_side(parameter: &str, value: u32, max: u32) -> Result<u32, ApiError> {
    if value == 0 {
        Err(ApiError::invalid(parameter, format!("{parameter} must be at least 1 pixel")))
    } else if value > max {
        Err(ApiError::too_large(parameter, format!("{parameter} {value} exceeds this server's limit of {max} pixels")))
    } else {
        Ok(value)
    }
}

/// A validated, normalized view: what is rendered, hashed for the ETag and cached. Equal
/// requests render byte-identical images.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ViewRequest {
    /// The camera with an absolute eye position.
    pub camera: Camera,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Output format.
    pub format: ImageFormat,
    /// JPEG quality; `None` for PNG.
    pub quality: Option<u8>,
    /// The complete style.
    pub style: Style,
    /// Complete styles of single layers (absent from the JSON, so the ETag, when there are
    /// none).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub layer_styles: BTreeMap<String, Style>,
    /// Data layers and time (absent from the JSON, so the ETag, when there are none).
    #[serde(skip_serializing_if = "DataRequest::is_empty")]
    pub data: DataRequest,
    /// Before / after (absent from the JSON, so the ETag, when there is none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub compare: Option<Compare>,
    /// The comment pins drawn in the view when it asks for them (`comments`), filled in from
    /// the participation store by [`super::comments::with_pins`]; part of the ETag, so a new
    /// or hidden comment changes it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub comments: Option<Vec<Pin>>,
}

impl ViewRequest {
    /// The styles to render: the view's style and its layers' styles.
    pub fn frame_style(&self) -> FrameStyle {
        FrameStyle { base: self.style.clone(), layers: self.layer_styles.clone() }
    }

    /// The parameters that normalize back to this view: the body of a `POST /api/render`,
    /// or with [`ViewParams::to_query`] a `GET /api/render` link.
    pub fn to_params(&self) -> ViewParams {
        let c = &self.camera;
        let styles = ViewStyle::of_frame(&self.frame_style());
        let camera = match c.projection {
            Projection::Perspective => CameraParams {
                position: Some(c.position.to_vec()),
                yaw: Some(c.yaw),
                pitch: Some(c.pitch),
                fov: Some(c.fov),
                roll: Some(c.roll),
                ..CameraParams::default()
            },
            Projection::Plan { width } => CameraParams {
                mode: Some(CameraMode::Plan),
                center: Some(vec![c.position[0], c.position[1]]),
                width: Some(width),
                yaw: Some(c.yaw),
                roll: Some(c.roll),
                ..CameraParams::default()
            },
        };
        ViewParams {
            camera,
            width: Some(self.width),
            height: Some(self.height),
            format: Some(self.format.name().into()),
            quality: self.quality.map(u32::from),
            preset: None,
            style: Some(styles.style).filter(|s| !s.is_empty()),
            layer_styles: Some(styles.layer_styles).filter(|m| !m.is_empty()),
            mappings: Some(self.data.mappings.clone()).filter(|m| !m.is_empty()),
            time: self.data.time.clone(),
            compare: self.compare.clone(),
            comments: self.comments.is_some().then_some(true),
        }
    }

    /// A strong ETag (quoted hex digest) of this view in the scene identified by `scene_id`.
    pub fn etag(&self, scene_id: &str) -> String {
        let json = serde_json::to_vec(self).expect("a view always serializes to JSON");
        let digest = Sha256::new().chain_update(scene_id.as_bytes()).chain_update([0]).chain_update(&json).finalize();
        format!("\"{}\"", hex(&digest[..16]))
    }
}

/// Lower-case hexadecimal digits of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_comparison_round_trips_through_a_link() {
        let params = ViewParams::from_query("compare_layer=planned&split=0.25&width=64").expect("query");
        assert_eq!(params.compare, Some(Compare { layer: "planned".into(), split: Some(0.25) }));
        assert_eq!(ViewParams::from_query(&params.to_query()).expect("link"), params);
        let hidden = ViewParams::from_query("compare_layer=planned").expect("query");
        assert_eq!(hidden.compare, Some(Compare { layer: "planned".into(), split: None }));
        let err = ViewParams::from_query("split=0.5").unwrap_err().to_string();
        assert!(err.contains("compare_layer"), "{err}");
        let layers = vec!["existing".to_owned(), "planned".to_owned()];
        let unknown = check_compare(&Compare { layer: "meadow".into(), split: None }, &layers).unwrap_err();
        assert!(unknown.to_string().contains("meadow") && unknown.to_string().contains("existing, planned"));
    }
}
