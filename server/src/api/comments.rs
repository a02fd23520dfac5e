//! Comments pinned in the landscape (`/api/comments`, issue #14): their JSON form.

use crate::fields::format_time;
use crate::store::participation::{Comment, CommentStatus, Hit};
use serde::Serialize;
use utoipa::ToSchema;

/// A comment as the API answers it. The public form leaves out the report count.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct CommentJson {
    /// Identifier (below 2⁵³).
    pub id: i64,
    /// The number drawn on its pin.
    pub number: i64,
    /// Position in scene metres `[x, y, z]` (x east, y north, z up).
    pub position: [f64; 3],
    /// WGS 84 longitude in degrees.
    pub lon: f64,
    /// WGS 84 latitude in degrees.
    pub lat: f64,
    /// What the pixel showed: `{"kind": "terrain"}` or `{"kind": "plant", "layer", "index"}`.
    pub hit: Hit,
    /// The camera the comment was made from (as in `GET /api/scene`'s `default_camera`, plus
    /// `roll` and `projection`).
    #[schema(value_type = Object)]
    pub camera: serde_json::Value,
    /// Plain text.
    pub text: String,
    /// Category (one of the scene's), if given.
    pub category: Option<String>,
    /// Creation time, RFC 3339 (UTC).
    pub created: String,
    /// Likes.
    pub likes: i64,
    /// `visible`, `pending` or `hidden` (always `visible` publicly).
    pub status: CommentStatus,
    /// Reports received (admin lists only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reports: Option<i64>,
}

/// RFC 3339 of a time in milliseconds since the epoch.
pub fn rfc3339_ms(ms: i64) -> String {
    chrono::DateTime::from_timestamp_millis(ms).map(|t| format_time(&t)).unwrap_or_default()
}

impl CommentJson {
    /// The public form.
    pub fn public(comment: &Comment) -> CommentJson {
        CommentJson {
            id: comment.id,
            number: comment.number,
            position: comment.position,
            lon: comment.lon_lat[0],
            lat: comment.lon_lat[1],
            hit: comment.hit.clone(),
            camera: comment.camera.clone(),
            text: comment.text.clone(),
            category: comment.category.clone(),
            created: rfc3339_ms(comment.created_ms),
            likes: comment.likes,
            status: comment.status,
            reports: None,
        }
    }

    /// The moderators' form, with the report count.
    pub fn admin(comment: &Comment) -> CommentJson {
        CommentJson { reports: Some(comment.reports), ..CommentJson::public(comment) }
    }
}
