//! The one description of a rendered view shared by `GET /api/render` (query parameters),
//! `POST /api/render` (JSON body) and the WebSocket: [`ViewParams`] is what a client sends,
//! [`ViewRequest`] the validated, normalized view that is rendered, hashed and cached. A view
//! link round-trips: [`ViewParams::to_query`] and [`ViewParams::from_query`] convert between
//! the two encodings.

use super::error::ApiError;
use crate::render::{RenderError, Style};
use crate::scene::Scene;
use crate::scene::camera::Camera;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use sha2::{Digest, Sha256};
use utoipa::{IntoParams, ToSchema};

/// Image width when a request gives none.
pub const DEFAULT_WIDTH: u32 = 1024;
/// Image height when a request gives none.
pub const DEFAULT_HEIGHT: u32 = 768;
/// JPEG quality when a request gives none.
pub const DEFAULT_JPEG_QUALITY: u8 = 90;
/// Eye height above the terrain when a position has no z.
pub const DEFAULT_EYE_HEIGHT: f32 = 1.7;
/// Largest absolute camera coordinate in scene metres.
const MAX_COORDINATE: f32 = 1.0e7;

/// Encoded image formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum ImageFormat {
    /// Lossless PNG (RGBA, 8 bit).
    Png,
    /// JPEG with a quality of 1–100.
    Jpeg,
}

impl ImageFormat {
    /// Parses a format name (`png`, `jpeg` or `jpg`); anything else is a 422 naming `parameter`
    /// and the supported formats.
    pub fn parse(name: &str, parameter: &str) -> Result<ImageFormat, ApiError> {
        match name.to_ascii_lowercase().as_str() {
            "png" => Ok(ImageFormat::Png),
            "jpeg" | "jpg" => Ok(ImageFormat::Jpeg),
            _ => {
                Err(ApiError::invalid(parameter, format!("unsupported format {name:?}; supported formats: png, jpeg")))
            }
        }
    }

    /// The canonical name (`png`, `jpeg`).
    pub fn name(self) -> &'static str {
        match self {
            ImageFormat::Png => "png",
            ImageFormat::Jpeg => "jpeg",
        }
    }

    /// The MIME type.
    pub fn mime(self) -> &'static str {
        match self {
            ImageFormat::Png => "image/png",
            ImageFormat::Jpeg => "image/jpeg",
        }
    }

    /// Encodes `image`; `quality` (1–100) applies to JPEG. Deterministic: the same image gives
    /// the same bytes.
    pub fn encode(self, image: &image::RgbaImage, quality: Option<u8>) -> Result<Vec<u8>, image::ImageError> {
        let mut out = std::io::Cursor::new(Vec::new());
        match self {
            ImageFormat::Png => image.write_to(&mut out, image::ImageFormat::Png)?,
            ImageFormat::Jpeg => {
                let rgb = image::DynamicImage::ImageRgba8(image.clone()).into_rgb8();
                let quality = quality.unwrap_or(DEFAULT_JPEG_QUALITY);
                image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality).encode_image(&rgb)?;
            }
        }
        Ok(out.into_inner())
    }
}

/// Where parameters came from, so that errors name them as the client wrote them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// Query parameters of `GET /api/render` (`x`, `yaw`, …).
    Query,
    /// The JSON body of `POST /api/render` (`camera.position`, `camera.yaw`, …).
    Body,
    /// A WebSocket control message (`position`, `yaw`, …).
    Message,
}

impl Source {
    fn camera_field(self, field: &str) -> String {
        match (self, field) {
            (Source::Body, _) => format!("camera.{field}"),
            (Source::Query, "position") => "x".into(),
            _ => field.into(),
        }
    }
}

/// Camera parameters of a request; each one left out keeps the scene's default camera (or,
/// on the WebSocket, the session's current camera).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct CameraParams {
    /// `[x, y]` (the eye `eye_height` above the terrain) or `[x, y, z]`, scene metres.
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<f32>>, min_items = 2, max_items = 3)]
    pub position: Option<Vec<f32>>,
    /// Eye height above the terrain in metres when the position has no z (default 1.7).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub eye_height: Option<f32>,
    /// Compass heading in degrees: 0 north, 90 east.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub yaw: Option<f32>,
    /// Degrees above (+) or below (−) the horizon, −90…90.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pitch: Option<f32>,
    /// Vertical field of view in degrees, 1…170.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fov: Option<f32>,
    /// Rotation about the view direction in degrees, −180…180; positive turns the picture
    /// counter-clockwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub roll: Option<f32>,
}

/// A camera resolved against the terrain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedCamera {
    /// The camera with an absolute eye position.
    pub camera: Camera,
    /// The eye height above the terrain when the position was given without z.
    pub eye_height: Option<f32>,
}

impl CameraParams {
    /// Applies these parameters to `base`; a position without z (or an `eye_height` alone)
    /// puts the eye above the terrain. Out-of-range values are 422s naming the parameter.
    pub fn resolve(&self, base: &Camera, scene: &Scene, source: Source) -> Result<ResolvedCamera, ApiError> {
        let name = |field: &str| source.camera_field(field);
        if let Some(eye) = self.eye_height
            && !(0.0..=10_000.0).contains(&eye)
        {
            return Err(ApiError::invalid(name("eye_height"), format!("eye_height {eye} is outside 0..=10000 metres")));
        }
        let ground_eye = |x: f32, y: f32| -> Result<ResolvedCamera, ApiError> {
            let eye = self.eye_height.unwrap_or(DEFAULT_EYE_HEIGHT);
            let ground = scene.terrain.height_at(f64::from(x), f64::from(y)).ok_or_else(|| {
                let ([x0, y0], [x1, y1]) = scene.terrain.bounds();
                ApiError::invalid(
                    name("position"),
                    format!(
                        "position {x},{y} is outside the terrain (x {x0:.0}..{x1:.0}, y {y0:.0}..{y1:.0} m); give z to place the eye freely"
                    ),
                )
            })?;
            Ok(ResolvedCamera {
                camera: Camera { position: [x, y, ground as f32 + eye], ..*base },
                eye_height: Some(eye),
            })
        };
        let mut resolved = match self.position.as_deref() {
            None if self.eye_height.is_some() => ground_eye(base.position[0], base.position[1])?,
            None => ResolvedCamera { camera: *base, eye_height: None },
            Some(position) => {
                if let Some(bad) = position.iter().find(|v| !(v.is_finite() && v.abs() <= MAX_COORDINATE)) {
                    return Err(ApiError::invalid(
                        name("position"),
                        format!("coordinate {bad} is not a number within ±{MAX_COORDINATE} metres"),
                    ));
                }
                match *position {
                    [x, y] => ground_eye(x, y)?,
                    [x, y, z] if self.eye_height.is_none() => {
                        ResolvedCamera { camera: Camera { position: [x, y, z], ..*base }, eye_height: None }
                    }
                    [_, _, _] => {
                        return Err(ApiError::invalid(name("eye_height"), "give either z or eye_height, not both"));
                    }
                    _ => {
                        return Err(ApiError::invalid(
                            name("position"),
                            format!("expected [x, y] or [x, y, z], got {} values", position.len()),
                        ));
                    }
                }
            }
        };
        let camera = &mut resolved.camera;
        camera.yaw = checked(self.yaw, camera.yaw, &name("yaw"), -3600.0, 3600.0)?;
        camera.pitch = checked(self.pitch, camera.pitch, &name("pitch"), -90.0, 90.0)?;
        camera.fov = checked(self.fov, camera.fov, &name("fov"), 1.0, 170.0)?;
        camera.roll = checked(self.roll, camera.roll, &name("roll"), -180.0, 180.0)?;
        Ok(resolved)
    }
}

fn checked(value: Option<f32>, default: f32, parameter: &str, lo: f32, hi: f32) -> Result<f32, ApiError> {
    match value {
        None => Ok(default),
        Some(v) if (lo..=hi).contains(&v) => Ok(v),
        Some(v) => Err(ApiError::invalid(parameter, format!("{parameter} {v} is outside {lo}..={hi}"))),
    }
}

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
    /// A named style preset (none are defined yet: any name is a 404).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Style overrides: a JSON object with any subset of the style fields (README, "Style").
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Object>)]
    pub style: Option<Value>,
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
    /// Absolute eye height; without it the eye is `eye_height` above the terrain.
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
    /// Style preset name (none defined yet).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// Style overrides as a URL-encoded JSON object, e.g. `{"hatch_map":2}`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub style: Option<String>,
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
        let style = match &q.style {
            Some(text) => Some(
                serde_json::from_str(text)
                    .map_err(|e| ApiError::bad("style", format!("style is not valid JSON: {e}")))?,
            ),
            None => None,
        };
        Ok(ViewParams {
            camera: CameraParams {
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
            width: self.width,
            height: self.height,
            format: self.format.clone(),
            quality: self.quality,
            preset: self.preset.clone(),
            style: self.style.as_ref().map(Value::to_string),
        };
        serde_urlencoded::to_string(&query).expect("flat query parameters always URL-encode")
    }

    /// Validates and normalizes these parameters into the view to render: defaults filled
    /// in, the eye placed on the terrain, the style parsed. 413 for images above `limits`,
    /// 422 for out-of-range values, 404 for an unknown preset.
    pub fn normalize(&self, scene: &Scene, limits: Limits, source: Source) -> Result<ViewRequest, ApiError> {
        if let Some(preset) = &self.preset {
            return Err(ApiError::NotFound(format!("unknown preset {preset:?}; this server has no presets yet")));
        }
        let camera = self.camera.resolve(&scene.default_camera, scene, source)?.camera;
        let width = image_side("width", self.width.unwrap_or(DEFAULT_WIDTH), limits.max_width)?;
        let height = image_side("height", self.height.unwrap_or(DEFAULT_HEIGHT), limits.max_height)?;
        let format = match &self.format {
            Some(name) => ImageFormat::parse(name, "format")?,
            None => ImageFormat::Png,
        };
        let quality = jpeg_quality(self.quality, "quality")?;
        let quality = (format == ImageFormat::Jpeg).then_some(quality);
        let style = parse_style(self.style.as_ref(), "style")?;
        Ok(ViewRequest { camera, width, height, format, quality, style })
    }
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

/// Builds a [`Style`] from a JSON object of overrides on the defaults; errors are 422s naming
/// the field as `<parameter>.<field>`.
pub fn parse_style(overrides: Option<&Value>, parameter: &str) -> Result<Style, ApiError> {
    let Some(overrides) = overrides else { return Ok(Style::default()) };
    if !overrides.is_object() {
        return Err(ApiError::invalid(parameter, format!("{parameter} must be a JSON object of style fields")));
    }
    let style: Style = serde_path_to_error::deserialize(overrides).map_err(|e| {
        let path = e.path().to_string();
        let name = if path == "." { parameter.to_owned() } else { format!("{parameter}.{path}") };
        ApiError::invalid(name, format!("{parameter}: {}", e.inner()))
    })?;
    style.validate().map_err(|e| match e {
        RenderError::Style { field, .. } => ApiError::invalid(format!("{parameter}.{field}"), e.to_string()),
        other => ApiError::invalid(parameter, other.to_string()),
    })?;
    Ok(style)
}

/// `style` as a JSON object. Goes through JSON text so that `f32` fields keep their short
/// decimal form (0.98, not 0.9800000190734863).
pub fn style_json(style: &Style) -> Map<String, Value> {
    match serde_json::to_string(style).and_then(|text| serde_json::from_str(&text)) {
        Ok(Value::Object(map)) => map,
        _ => Map::new(),
    }
}

/// The fields of `style` that differ from the default style: the short form of a style in
/// links.
pub fn style_overrides(style: &Style) -> Map<String, Value> {
    let (actual, default) = (style_json(style), style_json(&Style::default()));
    actual.into_iter().filter(|(k, v)| default.get(k) != Some(v)).collect()
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
}

impl ViewRequest {
    /// The parameters that normalize back to this view: the body of a `POST /api/render`,
    /// or with [`ViewParams::to_query`] a `GET /api/render` link.
    pub fn to_params(&self) -> ViewParams {
        let c = &self.camera;
        ViewParams {
            camera: CameraParams {
                position: Some(c.position.to_vec()),
                eye_height: None,
                yaw: Some(c.yaw),
                pitch: Some(c.pitch),
                fov: Some(c.fov),
                roll: Some(c.roll),
            },
            width: Some(self.width),
            height: Some(self.height),
            format: Some(self.format.name().into()),
            quality: self.quality.map(u32::from),
            preset: None,
            style: Some(style_overrides(&self.style)).filter(|m| !m.is_empty()).map(Value::Object),
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
