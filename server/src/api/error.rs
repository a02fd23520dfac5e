//! Typed API errors and their JSON form: `{"error": {"code", "message", "parameter"}}`.

use crate::echo::{bound_message, echo};
use crate::render::RenderError;
use crate::render::view_style::{StyleError, StyleTarget};
use crate::scene::camera_params::CameraError;
use crate::store::request::DataError;
use axum::http::{HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde::Serialize;
use utoipa::ToSchema;

/// An error answered to a client; each variant has one HTTP status and one `code`.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// The request is malformed: not JSON, an unknown query parameter, a number that is no number.
    #[error("{message}")]
    BadRequest { parameter: Option<String>, message: String },
    /// A value is well-formed but out of range or otherwise unusable.
    #[error("{message}")]
    Invalid { parameter: Option<String>, message: String },
    /// The image or the request body is larger than the server allows.
    #[error("{message}")]
    TooLarge { parameter: Option<String>, message: String },
    /// No such route or resource.
    #[error("{0}")]
    NotFound(String),
    /// The request conflicts with stored data (e.g. a layer name taken by an incompatible layer).
    #[error("{0}")]
    Conflict(String),
    /// The route exists but not for this method.
    #[error("method not allowed")]
    MethodNotAllowed,
    /// A write endpoint was called without the admin token.
    #[error("this endpoint needs `Authorization: Bearer <token>`")]
    Unauthorized,
    /// A write was refused whatever the token: without an admin token, from a client not on
    /// loopback, naming a foreign `Host` or sent from a foreign `Origin`; with one, from a
    /// foreign `Origin` (cross-site request forgery). The message says why.
    #[error("{0}")]
    Forbidden(String),
    /// The request body did not arrive within `--body-timeout-s`.
    #[error("{0}")]
    RequestTimeout(String),
    /// Too many writes from one author token or client address (rate limits of
    /// `[participation]`); try again after `retry_after` seconds.
    #[error("{message}")]
    TooManyRequests { message: String, retry_after: u32 },
    /// The render queue or the session limit is full; try again after `retry_after` seconds.
    #[error("{message}")]
    Busy { message: String, retry_after: u32 },
    /// The scene is still loading.
    #[error("the scene is still loading")]
    NotReady,
    /// The server is shutting down.
    #[error("the server is shutting down")]
    ShuttingDown,
    /// Rendering or encoding failed on the server's side.
    #[error("rendering failed: {0}")]
    Internal(String),
    /// The layer store or the participation store failed on the server's side (details go
    /// to the log only).
    #[error("the server's store failed; see the server log")]
    Storage(String),
}

/// The JSON body of every error response.
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorBody {
    /// The error.
    pub error: ErrorDetail,
}

/// What went wrong, for programs (`code`, `parameter`) and for people (`message`).
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorDetail {
    /// Stable machine-readable code, e.g. `invalid_parameter`.
    pub code: &'static str,
    /// Human-readable explanation.
    pub message: String,
    /// The offending request parameter (`width`, `camera.pitch`, `style.hatch_tiles`, …).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parameter: Option<String>,
}

impl ApiError {
    /// A 400 naming `parameter`.
    pub fn bad(parameter: impl Into<String>, message: impl Into<String>) -> ApiError {
        ApiError::BadRequest { parameter: Some(parameter.into()), message: message.into() }
    }

    /// A 422 naming `parameter`.
    pub fn invalid(parameter: impl Into<String>, message: impl Into<String>) -> ApiError {
        ApiError::Invalid { parameter: Some(parameter.into()), message: message.into() }
    }

    /// A 413 naming `parameter`.
    pub fn too_large(parameter: impl Into<String>, message: impl Into<String>) -> ApiError {
        ApiError::TooLarge { parameter: Some(parameter.into()), message: message.into() }
    }

    /// The HTTP status of this error.
    pub fn status(&self) -> StatusCode {
        match self {
            ApiError::BadRequest { .. } => StatusCode::BAD_REQUEST,
            ApiError::Invalid { .. } => StatusCode::UNPROCESSABLE_ENTITY,
            ApiError::TooLarge { .. } => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::NotFound(_) => StatusCode::NOT_FOUND,
            ApiError::Conflict(_) => StatusCode::CONFLICT,
            ApiError::MethodNotAllowed => StatusCode::METHOD_NOT_ALLOWED,
            ApiError::Unauthorized => StatusCode::UNAUTHORIZED,
            ApiError::Forbidden(_) => StatusCode::FORBIDDEN,
            ApiError::RequestTimeout(_) => StatusCode::REQUEST_TIMEOUT,
            ApiError::TooManyRequests { .. } => StatusCode::TOO_MANY_REQUESTS,
            ApiError::Busy { .. } | ApiError::NotReady | ApiError::ShuttingDown => StatusCode::SERVICE_UNAVAILABLE,
            ApiError::Internal(_) | ApiError::Storage(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The stable `code` of this error.
    pub fn code(&self) -> &'static str {
        match self {
            ApiError::BadRequest { .. } => "bad_request",
            ApiError::Invalid { .. } => "invalid_parameter",
            ApiError::TooLarge { .. } => "too_large",
            ApiError::NotFound(_) => "not_found",
            ApiError::Conflict(_) => "conflict",
            ApiError::MethodNotAllowed => "method_not_allowed",
            ApiError::Unauthorized => "unauthorized",
            ApiError::Forbidden(_) => "forbidden",
            ApiError::RequestTimeout(_) => "request_timeout",
            ApiError::TooManyRequests { .. } => "too_many_requests",
            ApiError::Busy { .. } => "busy",
            ApiError::NotReady => "not_ready",
            ApiError::ShuttingDown => "shutting_down",
            ApiError::Internal(_) | ApiError::Storage(_) => "internal",
        }
    }

    /// The JSON body of this error (also sent as a WebSocket error message).
    pub fn detail(&self) -> ErrorDetail {
        let parameter = match self {
            ApiError::BadRequest { parameter, .. }
            | ApiError::Invalid { parameter, .. }
            | ApiError::TooLarge { parameter, .. } => parameter.clone(),
            _ => None,
        };
        // Messages and parameter names may repeat client input: bound them (a safety net
        // behind the bounded echoes where the messages are made).
        let parameter = parameter.map(|p| echo(&p).to_string());
        ErrorDetail { code: self.code(), message: bound_message(&self.to_string()), parameter }
    }

    fn retry_after(&self) -> Option<u32> {
        match self {
            ApiError::Busy { retry_after, .. } | ApiError::TooManyRequests { retry_after, .. } => Some(*retry_after),
            ApiError::NotReady | ApiError::ShuttingDown => Some(1),
            _ => None,
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = self.status();
        let retry_after = self.retry_after();
        if let ApiError::Internal(message) | ApiError::Storage(message) = &self {
            tracing::error!(%message, "request failed");
        }
        let mut response = (status, axum::Json(ErrorBody { error: self.detail() })).into_response();
        let headers = response.headers_mut();
        if let Some(seconds) = retry_after {
            headers.insert(header::RETRY_AFTER, HeaderValue::from(seconds));
        }
        if status == StatusCode::UNAUTHORIZED {
            headers.insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        response
    }
}

/// A camera parameter out of range or unusable: a 422 naming it.
impl From<CameraError> for ApiError {
    fn from(error: CameraError) -> ApiError {
        ApiError::Invalid { parameter: Some(error.parameter), message: error.message }
    }
}

/// A style that cannot be resolved: an unknown preset is a 404 naming it and the known ones;
/// an unknown layer or a value out of range a 422 naming it as `style.<field>`,
/// `layer_styles.<layer>` or `layer_styles.<layer>.<field>`.
impl From<StyleError> for ApiError {
    fn from(error: StyleError) -> ApiError {
        let parameter = match &error.target {
            StyleTarget::View => "style".to_owned(),
            StyleTarget::Layer(name) => format!("layer_styles.{}", echo(name)),
        };
        // The render errors bound the names they repeat.
        let cause = bound_message(&error.error.to_string());
        let message = format!("{parameter}: {cause}");
        match &error.error {
            RenderError::UnknownPreset { .. } => ApiError::NotFound(message),
            RenderError::Style { field, .. } => ApiError::invalid(format!("{parameter}.{field}"), message),
            _ => ApiError::invalid(parameter, message),
        }
    }
}

/// Data layers a view cannot show: an unknown layer is a 404, bad mappings or a bad time a
/// 422 naming `mappings` or `time`.
impl From<DataError> for ApiError {
    fn from(error: DataError) -> ApiError {
        match &error {
            DataError::UnknownLayer(_) => ApiError::NotFound(error.to_string()),
            DataError::Mappings(_) => ApiError::invalid("mappings", error.to_string()),
            DataError::Time(_) => ApiError::invalid("time", error.to_string()),
        }
    }
}
