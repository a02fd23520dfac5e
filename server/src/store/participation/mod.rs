//! The participation store (issue #14): comments pinned in the landscape, their likes and
//! reports, viewpoints defined over the admin API, and meetings — behind one trait,
//! [`ParticipationStore`], so that one embedded SQLite file serves a single server and one
//! PostgreSQL database can serve several replicas.
//!
//! [`SqlStore`] implements it with sqlx's `Any` driver: the same portable SQL (numbered `$n`
//! parameters, BIGINT ids assigned by the server, times as milliseconds since the epoch, JSON
//! as TEXT) runs on both, and the migrations in `migrations/` create the tables.

mod sql;

pub(crate) use sql::redacted;
pub use sql::{SqlStore, sqlite_url};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::future::Future;
use std::pin::Pin;
use utoipa::ToSchema;

/// The future a [`ParticipationStore`] method returns (boxed, so the trait is usable as
/// `dyn ParticipationStore`).
pub type StoreFuture<'a, T> = Pin<Box<dyn Future<Output = Result<T, ParticipationError>> + Send + 'a>>;

/// Why a participation-store operation failed.
#[derive(Debug, thiserror::Error)]
pub enum ParticipationError {
    /// The database cannot be opened (a bad `--database-url`, an unwritable data directory).
    #[error("cannot open the participation database {url}: {message}")]
    Open {
        /// The database URL without credentials.
        url: String,
        /// What the driver said.
        message: String,
    },
    /// The migrations failed.
    #[error("cannot migrate the participation database: {0}")]
    Migrate(String),
    /// A query failed.
    #[error("participation database error: {0}")]
    Database(String),
    /// A stored row cannot be read back (a JSON column that is no JSON).
    #[error("participation database holds an unreadable row: {0}")]
    Corrupt(String),
}

impl From<sqlx::Error> for ParticipationError {
    fn from(error: sqlx::Error) -> ParticipationError {
        ParticipationError::Database(error.to_string())
    }
}

/// Whether a comment is shown to the public.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum CommentStatus {
    /// Shown to everyone.
    Visible,
    /// Waiting for a moderator (pre-moderation).
    Pending,
    /// Hidden by a moderator or by reports.
    Hidden,
}

impl CommentStatus {
    /// Every status, in the order above.
    pub const ALL: [CommentStatus; 3] = [CommentStatus::Visible, CommentStatus::Pending, CommentStatus::Hidden];

    /// The name stored in the database and used in the API.
    pub fn name(self) -> &'static str {
        match self {
            CommentStatus::Visible => "visible",
            CommentStatus::Pending => "pending",
            CommentStatus::Hidden => "hidden",
        }
    }

    /// The status of a name; `None` for other text.
    pub fn parse(name: &str) -> Option<CommentStatus> {
        CommentStatus::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// What a comment's pixel showed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Hit {
    /// The terrain.
    Terrain,
    /// A plant of a vegetation layer.
    Plant {
        /// The layer's name.
        layer: String,
        /// The plant's index within the layer.
        index: u32,
    },
}

/// A comment as stored: where it is pinned, what it says and its moderation state.
#[derive(Debug, Clone, PartialEq)]
pub struct Comment {
    /// Identifier (random, unique across replicas).
    pub id: i64,
    /// The number drawn on its pin: 1, 2, … in order of creation.
    pub number: i64,
    /// Position in scene metres (x east, y north, z up).
    pub position: [f64; 3],
    /// WGS 84 longitude and latitude in degrees.
    pub lon_lat: [f64; 2],
    /// What the pixel showed.
    pub hit: Hit,
    /// The camera the comment was made from, as JSON (a [`crate::scene::camera::Camera`]).
    pub camera: serde_json::Value,
    /// Plain text.
    pub text: String,
    /// One of the scene's categories, if given.
    pub category: Option<String>,
    /// Creation time, milliseconds since the Unix epoch.
    pub created_ms: i64,
    /// SHA-256 of the author token ([`author_hash`]); the token itself is never stored.
    pub author: String,
    /// Moderation state.
    pub status: CommentStatus,
    /// Reports received.
    pub reports: i64,
    /// Likes received.
    pub likes: i64,
}

/// A comment to store; the store assigns id and number.
#[derive(Debug, Clone, PartialEq)]
pub struct NewComment {
    /// Position in scene metres.
    pub position: [f64; 3],
    /// WGS 84 longitude and latitude.
    pub lon_lat: [f64; 2],
    /// What the pixel showed.
    pub hit: Hit,
    /// The camera, as JSON.
    pub camera: serde_json::Value,
    /// Plain text (validated by the caller).
    pub text: String,
    /// Category, if any.
    pub category: Option<String>,
    /// Creation time in milliseconds since the epoch.
    pub created_ms: i64,
    /// [`author_hash`] of the author token.
    pub author: String,
    /// Initial status (visible under post-moderation, pending under pre-moderation).
    pub status: CommentStatus,
}

/// Which comments to list; every condition left out matches all.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CommentFilter {
    /// Only these statuses (empty: all).
    pub statuses: Vec<CommentStatus>,
    /// Only this category.
    pub category: Option<String>,
    /// Created at or after (ms since the epoch).
    pub since_ms: Option<i64>,
    /// Created at or before (ms since the epoch).
    pub until_ms: Option<i64>,
}

impl CommentFilter {
    /// The comments the public sees: visible ones only.
    pub fn public() -> CommentFilter {
        CommentFilter { statuses: vec![CommentStatus::Visible], ..CommentFilter::default() }
    }

    /// Whether `comment` passes the filter (the store's SQL applies the same conditions).
    pub fn matches(&self, comment: &Comment) -> bool {
        (self.statuses.is_empty() || self.statuses.contains(&comment.status))
            && self.category.as_ref().is_none_or(|c| comment.category.as_ref() == Some(c))
            && self.since_ms.is_none_or(|t| comment.created_ms >= t)
            && self.until_ms.is_none_or(|t| comment.created_ms <= t)
    }
}

/// What a like or unlike did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LikeOutcome {
    /// The like was added (or removed).
    Done,
    /// Nothing changed: the author liked it already (or had not liked it).
    Unchanged,
    /// The author wrote the comment.
    OwnComment,
    /// No such comment.
    NoComment,
}

/// What a report did.
#[derive(Debug, Clone, PartialEq)]
pub enum ReportOutcome {
    /// Counted; the comment after it (hidden when it reached the threshold).
    Counted(Comment),
    /// The author had reported it already; the comment unchanged.
    Repeated(Comment),
    /// No such comment.
    NoComment,
}

/// A viewpoint kept in the store (defined over the admin API): its name, its definition as
/// JSON and its place in the list.
#[derive(Debug, Clone, PartialEq)]
pub struct StoredViewpoint {
    /// Unique name.
    pub name: String,
    /// The definition (an [`crate::api::viewpoints::Viewpoint`] without its name), as JSON.
    pub body: serde_json::Value,
    /// Place in the list (ascending).
    pub ordinal: i64,
    /// Last change, ms since the epoch.
    pub updated_ms: i64,
}

/// A meeting (presenter mode): its join code, who presents, when it opened and closed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Meeting {
    /// The short join code.
    pub code: String,
    /// Who presents (a session or author token hash; the meeting code decides).
    pub presenter: String,
    /// Opened, ms since the epoch.
    pub created_ms: i64,
    /// Closed, ms since the epoch; `None` while open.
    pub closed_ms: Option<i64>,
}

/// The participation store: comments, likes, reports, viewpoints and meetings. Every method
/// is one transaction; implementations are shared between tasks (`Send + Sync`).
pub trait ParticipationStore: Send + Sync {
    /// Stores a new comment, assigning its id and the next pin number.
    fn add_comment(&self, comment: NewComment) -> StoreFuture<'_, Comment>;
    /// One comment by id.
    fn comment(&self, id: i64) -> StoreFuture<'_, Option<Comment>>;
    /// The comments passing `filter`, by pin number.
    fn comments(&self, filter: CommentFilter) -> StoreFuture<'_, Vec<Comment>>;
    /// Sets a comment's status; the comment after it, `None` when there is none.
    fn set_status(&self, id: i64, status: CommentStatus) -> StoreFuture<'_, Option<Comment>>;
    /// Deletes a comment with its likes and reports; the deleted comment.
    fn delete_comment(&self, id: i64) -> StoreFuture<'_, Option<Comment>>;
    /// Adds the like of `author` (an [`author_hash`]) — one per author, never on one's own.
    fn like(&self, id: i64, author: &str, now_ms: i64) -> StoreFuture<'_, LikeOutcome>;
    /// Removes the like of `author`.
    fn unlike(&self, id: i64, author: &str) -> StoreFuture<'_, LikeOutcome>;
    /// Counts the report of `author` (once per author) and hides the comment when it has
    /// `hide_threshold` reports.
    fn report(&self, id: i64, author: &str, now_ms: i64, hide_threshold: u32) -> StoreFuture<'_, ReportOutcome>;
    /// The stored viewpoints, by ordinal.
    fn viewpoints(&self) -> StoreFuture<'_, Vec<StoredViewpoint>>;
    /// Creates or replaces a viewpoint (a new one goes last); `true` when it was created.
    fn put_viewpoint(&self, name: &str, body: serde_json::Value, now_ms: i64) -> StoreFuture<'_, bool>;
    /// Deletes a viewpoint; `true` when there was one.
    fn delete_viewpoint(&self, name: &str) -> StoreFuture<'_, bool>;
    /// Stores a new meeting; `false` when the code is taken.
    fn add_meeting(&self, meeting: Meeting) -> StoreFuture<'_, bool>;
    /// One meeting by code.
    fn meeting(&self, code: &str) -> StoreFuture<'_, Option<Meeting>>;
    /// Marks a meeting closed; `true` when it was open.
    fn close_meeting(&self, code: &str, now_ms: i64) -> StoreFuture<'_, bool>;
}

/// The stored form of an author token: hex SHA-256, so the database never holds a token that
/// could be replayed.
pub fn author_hash(token: &str) -> String {
    crate::api::view::hex(&Sha256::digest(token.as_bytes()))
}

/// Milliseconds since the Unix epoch now.
pub fn now_ms() -> i64 {
    let since = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    i64::try_from(since.as_millis()).unwrap_or(i64::MAX)
}
