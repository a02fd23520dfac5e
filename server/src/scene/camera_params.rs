//! Camera parameters of a view as clients give them (the `camera` of `POST /api/render`, the
//! query parameters of `GET /api/render`, WebSocket `camera` messages, the CLI's flags) and
//! their resolution against the terrain into a [`Camera`].

use super::Scene;
use super::camera::{Camera, Projection};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

/// Eye height above the terrain when a position has no z.
pub const DEFAULT_EYE_HEIGHT: f32 = 1.7;
/// Largest absolute camera coordinate in scene metres.
const MAX_COORDINATE: f32 = 1.0e7;
/// Height of a plan view's eye above the highest terrain point, in metres (above every plant).
pub const PLAN_EYE_CLEARANCE: f32 = 200.0;

/// How a camera projects: `perspective` (default) or `plan` (orthographic, top-down).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "lowercase")]
pub enum CameraMode {
    /// A perspective view from the eye position.
    Perspective,
    /// A map-like plan view: `center` and `width` in scene metres, `yaw` up in the image.
    Plan,
}

/// A camera parameter that cannot be used: the parameter as the client wrote it and why.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{message}")]
pub struct CameraError {
    /// The parameter (`camera.pitch` in a JSON body, `pitch` in a query, `--pitch` on the
    /// command line, …).
    pub parameter: String,
    /// What is wrong with it.
    pub message: String,
}

impl CameraError {
    fn new(parameter: impl Into<String>, message: impl Into<String>) -> CameraError {
        CameraError { parameter: parameter.into(), message: message.into() }
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
    /// The flags of `landsketch render` (`--pos`, `--yaw`, `--plan`, …).
    CommandLine,
}

impl Source {
    /// The name of the camera parameter `field` (a [`CameraParams`] field) in this source.
    fn camera_field(self, field: &str) -> String {
        match (self, field) {
            (Source::Body, _) => format!("camera.{field}"),
            (Source::Query, "position") => "x".into(),
            (Source::Query, "width") => "plan_width".into(),
            (Source::CommandLine, "position") => "--pos".into(),
            (Source::CommandLine, "center") => "--plan CX,CY".into(),
            (Source::CommandLine, "width") => "--plan WIDTH".into(),
            (Source::CommandLine, _) => format!("--{}", field.replace('_', "-")),
            _ => field.into(),
        }
    }
}

/// Camera parameters of a request; each one left out keeps the scene's default camera (or,
/// on the WebSocket, the session's current camera).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(default, deny_unknown_fields)]
pub struct CameraParams {
    /// `perspective` (default) or `plan`: an orthographic top-down view of `width` metres
    /// centred on `center`, heading `yaw` up (0: north up).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mode: Option<CameraMode>,
    /// Plan view: `[x, y]` of the image centre in scene metres (default: the current camera's
    /// x and y).
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<Vec<f32>>, min_items = 2, max_items = 2)]
    pub center: Option<Vec<f32>>,
    /// Plan view: scene metres across the image (default: the current plan width, else the
    /// terrain's larger side).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width: Option<f32>,
    /// `[x, y]` (the eye `eye_height` above the terrain) or `[x, y, z]` (z an elevation, not
    /// below the terrain there), scene metres.
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
    /// puts the eye above the terrain. Out-of-range or unusable values are errors naming the
    /// parameter as `source` writes it.
    pub fn resolve(&self, base: &Camera, scene: &Scene, source: Source) -> Result<ResolvedCamera, CameraError> {
        let name = |field: &str| source.camera_field(field);
        let plan = match self.mode {
            Some(mode) => mode == CameraMode::Plan,
            None => !base.projection.is_perspective(),
        };
        if plan {
            return self.resolve_plan(base, scene, source);
        }
        if let Some(field) = [("center", self.center.is_some()), ("width", self.width.is_some())]
            .into_iter()
            .find_map(|(field, given)| given.then_some(field))
        {
            return Err(CameraError::new(name(field), format!("{field} applies to plan views only (mode plan)")));
        }
        let base = &Camera { projection: Projection::Perspective, ..*base };
        if let Some(eye) = self.eye_height
            && !(0.0..=10_000.0).contains(&eye)
        {
            return Err(CameraError::new(name("eye_height"), format!("eye_height {eye} is outside 0..=10000 metres")));
        }
        let ground_eye = |x: f32, y: f32| -> Result<ResolvedCamera, CameraError> {
            let eye = self.eye_height.unwrap_or(DEFAULT_EYE_HEIGHT);
            let ground = scene.terrain.height_at(f64::from(x), f64::from(y)).ok_or_else(|| {
                let ([x0, y0], [x1, y1]) = scene.terrain.bounds();
                CameraError::new(
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
                    return Err(CameraError::new(
                        name("position"),
                        format!("coordinate {bad} is not a number within ±{MAX_COORDINATE} metres"),
                    ));
                }
                match *position {
                    [x, y] => ground_eye(x, y)?,
                    [x, y, z] if self.eye_height.is_none() => {
                        // An eye under the ground sees nothing but paper: a z read as a height
                        // above the terrain instead of an elevation is the usual cause.
                        if let Some(ground) = scene.terrain.buries([x, y, z]) {
                            let (parameter, given) = match source {
                                Source::Query => ("z".to_owned(), format!("z {z}")),
                                _ => (name("position"), format!("{} {x},{y},{z}", name("position"))),
                            };
                            return Err(CameraError::new(
                                parameter,
                                format!(
                                    "{given}: the eye is below the terrain (ground {ground:.1} m); z is an elevation: leave it out to stand eye_height above the ground"
                                ),
                            ));
                        }
                        ResolvedCamera { camera: Camera { position: [x, y, z], ..*base }, eye_height: None }
                    }
                    [_, _, _] => {
                        return Err(CameraError::new(name("eye_height"), "give either z or eye_height, not both"));
                    }
                    _ => {
                        return Err(CameraError::new(
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

    /// A plan view: centre and width from these parameters or `base`, the eye
    /// [`PLAN_EYE_CLEARANCE`] above the highest terrain, looking straight down.
    fn resolve_plan(&self, base: &Camera, scene: &Scene, source: Source) -> Result<ResolvedCamera, CameraError> {
        let name = |field: &str| source.camera_field(field);
        let perspective_only = [
            ("position", self.position.is_some()),
            ("eye_height", self.eye_height.is_some()),
            ("pitch", self.pitch.is_some()),
            ("fov", self.fov.is_some()),
        ];
        if let Some((field, _)) = perspective_only.into_iter().find(|(_, given)| *given) {
            return Err(CameraError::new(
                name(field),
                format!("{field} does not apply to a plan view; give center and width"),
            ));
        }
        let ([x0, y0], [x1, y1]) = scene.terrain.bounds();
        let [cx, cy] = match self.center.as_deref() {
            None => [base.position[0], base.position[1]],
            Some(&[x, y]) if [x, y].iter().all(|v| v.is_finite() && v.abs() <= MAX_COORDINATE) => [x, y],
            Some(other) => {
                return Err(CameraError::new(
                    name("center"),
                    format!("expected [x, y] within ±{MAX_COORDINATE} metres, got {other:?}"),
                ));
            }
        };
        let default_width = match base.projection {
            Projection::Plan { width } => width,
            Projection::Perspective => (x1 - x0).max(y1 - y0) as f32,
        };
        let width = checked(self.width, default_width, &name("width"), 0.01, 1.0e6)?;
        let top = scene.terrain.dem.data.iter().copied().filter(|h| h.is_finite()).fold(f64::MIN, f64::max);
        let z = if top == f64::MIN { 0.0 } else { top as f32 } + PLAN_EYE_CLEARANCE;
        let mut camera = Camera { roll: base.roll, yaw: base.yaw, ..Camera::plan(cx, cy, z, width) };
        camera.yaw = checked(self.yaw, camera.yaw, &name("yaw"), -3600.0, 3600.0)?;
        camera.roll = checked(self.roll, camera.roll, &name("roll"), -180.0, 180.0)?;
        Ok(ResolvedCamera { camera, eye_height: None })
    }
}

fn checked(value: Option<f32>, default: f32, parameter: &str, lo: f32, hi: f32) -> Result<f32, CameraError> {
    match value {
        None => Ok(default),
        Some(v) if (lo..=hi).contains(&v) => Ok(v),
        Some(v) => Err(CameraError::new(parameter, format!("{parameter} {v} is outside {lo}..={hi}"))),
    }
}
